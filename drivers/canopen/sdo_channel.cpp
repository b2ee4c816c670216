#include "drivers/canopen/sdo_channel.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <fmt/format.h>

namespace fieldgate::canopen {

std::string_view trace_outcome(SdoResult::Status status) {
  switch (status) {
    case SdoResult::Status::ok:
      return "ok";
    case SdoResult::Status::server_abort:
      return "device_error";
    case SdoResult::Status::client_abort:
      return "garbled";
    case SdoResult::Status::timeout:
      return "timeout";
  }
  return "garbled";
}

Reply reply_of(const SdoResult& result) {
  Reply r;
  r.text = result.text;
  switch (result.status) {
    case SdoResult::Status::ok:
      r.status = Reply::Status::ok;
      r.text.clear();
      break;
    case SdoResult::Status::server_abort:
      r.status = Reply::Status::device_error;
      r.device_code = result.abort_code;
      break;
    case SdoResult::Status::client_abort:
      r.status = Reply::Status::garbled;
      r.device_code = result.abort_code;
      break;
    case SdoResult::Status::timeout:
      r.status = Reply::Status::timeout;
      break;
  }
  return r;
}

Reply upload_reply(const ObjectAddress& object, const SdoResult& result) {
  Reply reply = reply_of(result);
  if (reply.status != Reply::Status::ok) return reply;
  if (is_integer(object.type)) {
    PointSource src;
    src.type = object.type;
    std::string error;
    // Every point type holds the widest integer the model may use, so decode as int64.
    const auto v = decode_point_value(src, ValueType::int32, result.data, error);
    if (!v) {
      Reply garbled;
      garbled.status = Reply::Status::garbled;
      garbled.text = fmt::format("0x{:04X}:{}: {}", object.index, object.sub, error);
      return garbled;
    }
    reply.values = {*v};
  } else {
    reply.text.assign(result.data.begin(), result.data.end());
    reply.values.assign(result.data.begin(), result.data.end());
  }
  return reply;
}

SdoChannel::SdoChannel(uint8_t node, std::chrono::microseconds timeout, asio::steady_timer& wake)
    : client_(node, timeout), wake_(wake) {}

std::string_view SdoChannel::on_response(const CanFrame& frame, TimePoint now) {
  if (client_.idle()) {
    client_.on_frame(frame, now);  // counted as ignored: a late answer
    return "late";
  }
  auto step = client_.on_frame(frame, now);
  const std::string_view outcome = step.done ? trace_outcome(step.done->status) : "";
  if (step.send || step.done) {
    step_ = std::move(step);
    step_time_ = now;
    wake_.cancel();
  }
  return outcome;
}

asio::awaitable<std::optional<SdoResult>> SdoChannel::run(SdoStep step, FramePort& port,
                                                          TimePoint& finished_at) {
  for (;;) {
    if (step.send)
      co_await port.send(*step.send, step.done ? trace_outcome(step.done->status) : "");
    if (step.done) co_return std::move(*step.done);
    step_.reset();
    while (!step_) {
      if (!port.up()) {
        client_.abort(sdo_abort::general);  // forget it; there is no link to tell the node
        co_return std::nullopt;
      }
      const auto deadline = client_.deadline();
      if (!deadline) co_return std::nullopt;
      wake_.expires_at(*deadline);
      auto [ec] = co_await wake_.async_wait(asio::as_tuple(asio::use_awaitable));
      if (step_ || ec) continue;
      const auto now = Clock::now();
      auto timed = client_.on_time(now);
      if (timed.send || timed.done) {
        step_ = std::move(timed);
        step_time_ = now;
      }
    }
    step = std::move(*step_);
    step_.reset();
    finished_at = step_time_;
  }
}

}  // namespace fieldgate::canopen
