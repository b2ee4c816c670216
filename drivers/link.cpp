#include "drivers/link.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>

namespace fieldgate {

using Clock = std::chrono::steady_clock;

std::chrono::microseconds guard_time(const LinkTiming& timing, double char_time_us) {
  if (timing.guard_time.count() > 0) return timing.guard_time;
  const auto chars = std::chrono::microseconds(static_cast<int64_t>(16 * char_time_us + 0.5));
  return timing.reply_timeout + std::max(timing.byte_timeout, chars);
}

Link::Link(ByteTransport& transport, std::size_t max_frame)
    : transport_(transport), max_frame_(max_frame) {}

Clock::time_point Link::wire_free_at() const {
  return std::max(Clock::now(), tx_done_);
}

void Link::count_sent(std::size_t n) {
  // write() completes when the OS has the bytes, not when they have crossed a slow line: a
  // reply deadline counted from here would run out while the request is still on the wire.
  const auto wire =
      std::chrono::microseconds(static_cast<int64_t>(static_cast<double>(n) * char_time_us()));
  stats_.bytes_sent += n;
  tx_done_ = wire_free_at() + wire;
}

void Link::tap_sent_ahead(std::string_view bytes) {
  if (!tap_) return;
  tap_at_ = ahead_at_;
  tap_(true, bytes);
  tap_at_.reset();
}

bool Link::send_ahead(std::string_view bytes) {
  if (!ahead_.empty() || bytes.empty()) return false;
  const auto written = transport_.write_available(bytes);
  if (written == 0) return false;
  ahead_at_ = Clock::now();
  count_sent(written);
  ahead_.assign(bytes);
  ahead_written_ = written;
  return true;
}

void Link::drop_sent_ahead() {
  if (!ahead_.empty()) tap_sent_ahead(std::string_view(ahead_).substr(0, ahead_written_));
  ahead_.clear();
  ahead_written_ = 0;
  taking_over_ = false;
}

asio::awaitable<std::error_code> Link::send(std::string_view bytes) {
  std::string rest;  // of a request sent ahead, what the OS did not take then
  const bool taken_over = std::exchange(taking_over_, false);
  if (taken_over) {
    if (bytes != ahead_) {
      drop_sent_ahead();
      ahead_mismatch_ = true;
      co_return std::make_error_code(std::errc::protocol_error);
    }
    // The wire trace shows the request where its exchange begins, a moment after it left.
    rest = ahead_.substr(ahead_written_);
    tap_sent_ahead(ahead_);
    ahead_.clear();
    ahead_written_ = 0;
    if (rest.empty()) co_return std::error_code{};
    bytes = rest;
  }
  auto ec = co_await transport_.write(bytes);
  if (!ec) {
    count_sent(bytes.size());
    if (tap_ && !taken_over) tap_(true, bytes);
  }
  co_return ec;
}

asio::awaitable<LinkResync> Link::resync(std::chrono::microseconds guard,
                                         std::chrono::microseconds limit) {
  LinkResync result;
  ++stats_.resyncs;
  in_step_ = false;
  const auto started = Clock::now();
  const auto give_up = wire_free_at() + limit;
  result.drained = std::exchange(buffer_, {});
  char chunk[512];
  auto quiet_from = wire_free_at();
  for (;;) {
    if (take_available(result.drained) > 0) {
      quiet_from = Clock::now();
      continue;
    }
    const auto now = Clock::now();
    if (now >= quiet_from + guard) break;
    if (now >= give_up) {
      result.quiet = false;
      break;
    }
    const auto got = co_await transport_.read_some_until(asio::buffer(chunk),
                                                         std::min(quiet_from + guard, give_up));
    if (got.timed_out) continue;  // read_available() above decides
    if (got.error) break;         // the next transaction will see the failure
    stats_.bytes_received += got.size;
    result.drained.append(chunk, got.size);
    quiet_from = Clock::now();
  }
  stats_.resync_bytes += result.drained.size();
  stats_.bytes_discarded += result.drained.size();
  result.waited = std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - started);
  if (tap_ && !result.drained.empty()) tap_(false, result.drained);
  co_return result;
}

void Link::discard_input() {
  // A device that keeps talking is cut short by the transport's flush after this much.
  constexpr std::size_t kReadOffLimit = 4096;
  if (!ahead_.empty()) return;  // what comes is the reply to the request sent ahead
  std::string stray = std::exchange(buffer_, {});
  bool emptied = false;
  while (stray.size() < kReadOffLimit) {
    if (take_available(stray) == 0) {
      emptied = true;
      break;
    }
  }
  if (!stray.empty()) {
    stats_.bytes_discarded += stray.size();
    if (tap_) tap_(false, stray);
  }
  // A flush takes the tty's buffer lock, which the kernel's receive work holds while it hands
  // over a reply: right after one it can wait milliseconds for nothing (perf trace: p99 1.7 ms
  // on a PTY). Strays, a frame that left bytes behind or a failed read are when it pays.
  if (!in_step_ || !emptied || !stray.empty()) transport_.discard_input();
}

asio::awaitable<void> Link::pause(std::chrono::microseconds duration) {
  if (duration.count() <= 0) co_return;
  asio::steady_timer timer(co_await asio::this_coro::executor, duration);
  co_await timer.async_wait(asio::as_tuple(asio::use_awaitable));
}

std::size_t Link::take_available(std::string& into) {
  char chunk[512];
  const auto n = transport_.read_available(asio::buffer(chunk));
  stats_.bytes_received += n;
  into.append(chunk, n);
  return n;
}

LinkRead Link::end_read(LinkRead::Status status) {
  in_step_ = false;
  LinkRead result;
  result.status = status;
  result.partial = std::exchange(buffer_, {});
  if (tap_ && !result.partial.empty()) tap_(false, result.partial);
  return result;
}

asio::awaitable<LinkRead> Link::read_frame(const FrameSplitter& splitter,
                                           const LinkTiming& timing) {
  LinkRead result;
  bool first = buffer_.empty();
  // A read that may not wait is a flush: a frame it finds came out of turn, and finding none
  // says nothing about the line.
  const bool no_wait = timing.reply_timeout.count() <= 0 && timing.byte_timeout.count() <= 0;
  if (no_wait && !ahead_.empty()) co_return result;  // the input is the request sent ahead's
  char chunk[512];
  const auto take_waiting = [&] {
    if (take_available(buffer_) == 0) return false;
    first = false;
    return true;
  };
  for (;;) {
    if (const auto n = splitter(buffer_); n > 0) {
      result.status = LinkRead::Status::frame;
      result.frame = buffer_.substr(0, n);
      buffer_.erase(0, n);
      in_step_ = !no_wait;
      if (tap_) tap_(false, result.frame);
      co_return result;
    }
    if (buffer_.size() > max_frame_) co_return end_read(LinkRead::Status::overflow);
    const auto deadline =
        first ? wire_free_at() + timing.reply_timeout : Clock::now() + timing.byte_timeout;
    if (deadline <= Clock::now()) {
      // A read that may not wait (a flush before a request) takes what the OS holds: racing a
      // timer that has already expired costs the loop a timer and a turn for nothing.
      if (take_waiting()) continue;
      if (no_wait && first) {
        result.status = LinkRead::Status::timeout;  // nothing came, nothing was waited for
        co_return result;
      }
      co_return end_read(LinkRead::Status::timeout);
    }
    const auto got = co_await transport_.read_some_until(asio::buffer(chunk), deadline);
    if (got.timed_out) {
      // The timer and the data can become ready together (a stalled process): bytes already
      // buffered by the OS are not a timeout.
      if (take_waiting()) continue;
      co_return end_read(LinkRead::Status::timeout);
    }
    if (got.error) {
      auto failed = end_read(LinkRead::Status::error);
      failed.error = got.error;
      co_return failed;
    }
    stats_.bytes_received += got.size;
    buffer_.append(chunk, got.size);
    first = false;
  }
}

}  // namespace fieldgate
