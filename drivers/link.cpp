#include "drivers/link.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/experimental/awaitable_operators.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

namespace fieldgate {

using namespace boost::asio::experimental::awaitable_operators;

Link::Link(ByteTransport& transport, std::size_t max_frame)
    : transport_(transport), max_frame_(max_frame) {}

asio::awaitable<std::error_code> Link::send(std::string_view bytes) {
  auto ec = co_await transport_.write(bytes);
  if (!ec) stats_.bytes_sent += bytes.size();
  co_return ec;
}

void Link::discard_input() {
  stats_.bytes_discarded += buffer_.size();
  buffer_.clear();
  transport_.discard_input();
}

asio::awaitable<void> Link::pause(std::chrono::microseconds duration) {
  if (duration.count() <= 0) co_return;
  asio::steady_timer timer(co_await asio::this_coro::executor, duration);
  co_await timer.async_wait(asio::as_tuple(asio::use_awaitable));
}

asio::awaitable<LinkRead> Link::read_frame(const FrameSplitter& splitter,
                                           const LinkTiming& timing) {
  LinkRead result;
  asio::steady_timer timer(co_await asio::this_coro::executor);
  bool first = buffer_.empty();
  char chunk[512];
  for (;;) {
    if (const auto n = splitter(buffer_); n > 0) {
      result.status = LinkRead::Status::frame;
      result.frame = buffer_.substr(0, n);
      buffer_.erase(0, n);
      co_return result;
    }
    if (buffer_.size() > max_frame_) {
      result.status = LinkRead::Status::overflow;
      result.partial = std::move(buffer_);
      buffer_.clear();
      co_return result;
    }
    timer.expires_after(first ? timing.reply_timeout : timing.byte_timeout);
    auto outcome = co_await (transport_.read_some(asio::buffer(chunk)) ||
                             timer.async_wait(asio::as_tuple(asio::use_awaitable)));
    if (outcome.index() == 1) {
      // The timer and the data can become ready together (a stalled process): bytes already
      // buffered by the OS are not a timeout.
      if (const auto late = transport_.read_available(asio::buffer(chunk)); late > 0) {
        stats_.bytes_received += late;
        buffer_.append(chunk, late);
        first = false;
        continue;
      }
      result.status = LinkRead::Status::timeout;
      result.partial = std::move(buffer_);
      buffer_.clear();
      co_return result;
    }
    auto [ec, n] = std::get<0>(outcome);
    if (ec) {
      result.status = LinkRead::Status::error;
      result.error = ec;
      result.partial = std::move(buffer_);
      buffer_.clear();
      co_return result;
    }
    stats_.bytes_received += n;
    buffer_.append(chunk, n);
    first = false;
  }
}

}  // namespace fieldgate
