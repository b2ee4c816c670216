#pragma once

// A bus for tests of what sits above the buses (the control service, the register map): it
// records each command and answers it at once with the next scripted reply.

#include <boost/asio/awaitable.hpp>

#include <string>
#include <vector>

#include "gateway/bus/bus.hpp"
#include "gateway/bus/wire_trace.hpp"

namespace fieldgate::test {

// Answers every command at once with the next scripted reply (ok when none is left).
class ScriptedBus : public Bus {
 public:
  std::vector<std::string> sent;
  std::vector<Reply> replies;

  boost::asio::awaitable<void> run() override { co_return; }
  void stop() override {}
  boost::asio::awaitable<Reply> submit(int, Request request, CommandOptions options) override {
    sent.push_back(request.command);
    if (options.on_sent) options.on_sent();
    Reply reply;
    reply.status = Reply::Status::ok;
    if (!replies.empty()) {
      reply = replies.front();
      replies.erase(replies.begin());
    }
    co_return reply;
  }
  const BusConfig& config() const override { return config_; }
  const BusCounters& counters() const override { return counters_; }
  WireTrace& trace() override { return trace_; }
  const NodeConfig& node_config(int) const override { return node_; }
  std::vector<std::shared_ptr<NodeImage>> node_images() const override { return {}; }
  void rebind(int, NodeUpdated) override {}
  int first_node_index() const override { return 0; }

 private:
  BusConfig config_;
  BusCounters counters_;
  WireTrace trace_{"test"};
  NodeConfig node_;
};

}  // namespace fieldgate::test
