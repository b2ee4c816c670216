#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/as_tuple.hpp>
#include <boost/asio/awaitable.hpp>
#include <boost/asio/experimental/channel.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <chrono>
#include <utility>

#include "drivers/protocol_family.hpp"
#include "gateway/bus/bus.hpp"

namespace fieldgate {

// A command queued on a bus (Bus::submit) until the bus carries it and answers its submitter.
struct PendingCommand {
  explicit PendingCommand(asio::any_io_executor executor) : done(executor, 1) {}

  // The submitter's wait: the bus's answer, or link_down when the bus stopped without one.
  asio::awaitable<Reply> reply() {
    auto [ec, reply] = co_await done.async_receive(asio::as_tuple(asio::use_awaitable));
    if (ec) co_return Reply::of(Reply::Status::link_down, "gateway stopping");
    co_return reply;
  }
  void answer(Reply reply) { done.try_send(boost::system::error_code{}, std::move(reply)); }
  // The bus stops with the command still queued.
  void abandon() { done.try_send(asio::error::operation_aborted, Reply{}); }

  int node = 0;  // the node's position on its bus, where one queue serves every node
  std::chrono::steady_clock::time_point queued_at = std::chrono::steady_clock::now();
  Request request;
  CommandOptions options;
  asio::experimental::channel<void(boost::system::error_code, Reply)> done;
};

}  // namespace fieldgate
