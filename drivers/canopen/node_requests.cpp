#include "drivers/canopen/node_requests.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace fieldgate::canopen {

namespace {

// Syslog level of NodeHost::log.
constexpr int kNotice = 5;
// Pause between the uploads of a `wait` step.
constexpr auto kWaitInterval = std::chrono::milliseconds(10);

}  // namespace

NodeRequests::NodeRequests(uint8_t id, SdoChannel& sdo, NodeSupervision& nmt,
                           const NodePoints& points, RequestHost& host)
    : id_(id), sdo_(sdo), nmt_(nmt), points_(points), host_(host) {}

void NodeRequests::note_abort(const SdoResult& result) {
  if (result.status != SdoResult::Status::server_abort) return;
  nmt_.status().last_abort = result.abort_code;
  host_.refresh_local_points(Clock::now());
}

void NodeRequests::store_object(uint16_t index, uint8_t sub, std::span<const uint8_t> bytes,
                                TimePoint at) {
  host_.store(points_.from_object(index, sub, bytes), at);
  if (index == kErrorRegisterObject.index && sub == 0 && !bytes.empty())
    nmt_.error_register_seen(bytes[0]);
}

asio::awaitable<Reply> NodeRequests::upload(const ObjectAddress& object, int retries,
                                            TimePoint now) {
  co_return co_await upload(object, retries, now, false);
}

asio::awaitable<Reply> NodeRequests::poll(const ObjectAddress& object, int retries, TimePoint now) {
  finished_at = now;
  if (absent_.contains(object.index, object.sub)) co_return Reply::of(Reply::Status::ok);
  co_return co_await upload(object, retries, now, true);
}

Reply NodeRequests::object_absent(const ObjectAddress& object, uint32_t code, TimePoint at) {
  if (absent_.add(object.index, object.sub))
    host_.log(kNotice, fmt::format("node {}: no object 0x{:04X}:{} (SDO abort 0x{:08X}: {}): "
                                   "not polled any more, its points read {}",
                                   id_, object.index, object.sub, code, abort_text(code),
                                   object.type == DataType::visible_string ||
                                           object.type == DataType::octet_string
                                       ? "as an empty string (0)"
                                       : "0"));
  host_.object_absent(points_.absent_values(object.index, object.sub), at);
  // A definite answer from a node that is there; not a device error of a command.
  return Reply::of(Reply::Status::ok);
}

asio::awaitable<Reply> NodeRequests::upload(const ObjectAddress& object, int retries, TimePoint now,
                                            bool polled) {
  Reply reply;
  auto started = now;
  for (int attempt = 0; attempt <= retries; ++attempt) {
    if (attempt > 0) {
      host_.retrying();
      started = finished_at;
    }
    finished_at = started;
    // A named step, not a temporary: GCC 12 destroys prvalue arguments of a coroutine twice.
    const SdoStep first = sdo_.client().upload(object.index, object.sub, started);
    auto result = co_await sdo_.run(first, host_.port(), finished_at);
    if (!result) co_return Reply::of(Reply::Status::link_down, "bus link is down");
    host_.transfer_done(std::chrono::duration<double>(finished_at - started).count());
    if (polled && result->status == SdoResult::Status::server_abort &&
        says_absent(result->abort_code)) {
      reply = object_absent(object, result->abort_code, finished_at);
      break;
    }
    note_abort(*result);
    reply = upload_reply(object, *result);
    if (reply.status == Reply::Status::ok)
      store_object(object.index, object.sub, result->data, finished_at);
    if (reply.status != Reply::Status::timeout && reply.status != Reply::Status::garbled) break;
    if (attempt < retries) host_.record(reply, started, finished_at);
  }
  host_.record(reply, started, finished_at);
  co_return reply;
}

asio::awaitable<Reply> NodeRequests::download(const Operation& op, TimePoint now) {
  co_return co_await download(op, now, true);
}

asio::awaitable<Reply> NodeRequests::download(const Operation& op, TimePoint now, bool by_command) {
  std::vector<uint8_t> data;
  if (op.text)
    data.assign(op.text->begin(), op.text->end());
  else
    data = encode_integer(op.object.type, op.value);
  finished_at = now;
  const std::vector<uint8_t> written = data;
  const SdoStep first =
      sdo_.client().download(op.object.index, op.object.sub, std::move(data), now);
  auto result = co_await sdo_.run(first, host_.port(), finished_at);
  if (!result) co_return Reply::of(Reply::Status::link_down, "bus link is down");
  host_.transfer_done(std::chrono::duration<double>(finished_at - now).count());
  note_abort(*result);
  Reply reply = reply_of(*result);
  host_.record(reply, now, finished_at);
  // Confirmed: the points of this object hold the written value until their next poll.
  if (reply.status == Reply::Status::ok) {
    store_object(op.object.index, op.object.sub, written, finished_at);
    if (nmt_.on_downloaded(op.object, op.value, finished_at, by_command)) host_.heartbeat_rearmed();
  }
  co_return reply;
}

asio::awaitable<Reply> NodeRequests::wait_for(const Operation& op) {
  const auto deadline = Clock::now() + op.within;
  const auto masked = [&](int64_t v) { return static_cast<uint64_t>(v) & op.mask; };
  for (;;) {
    Reply r = co_await upload(op.object, 0, Clock::now());
    if (r.status != Reply::Status::ok) co_return r;
    const int64_t v = r.values.empty() ? 0 : r.values[0];
    if (masked(v) == masked(op.value)) co_return r;
    if (host_.urgent_pending())
      co_return Reply::of(Reply::Status::device_error,
                          fmt::format("wait for 0x{:04X}:{} interrupted by an urgent command",
                                      op.object.index, op.object.sub),
                          v);
    if (Clock::now() >= deadline)
      co_return Reply::of(
          Reply::Status::device_error,
          fmt::format("0x{:04X}:{} is 0x{:X}; waited {} ms for & 0x{:X} == 0x{:X}", op.object.index,
                      op.object.sub, static_cast<uint64_t>(v),
                      std::chrono::duration_cast<std::chrono::milliseconds>(op.within).count(),
                      op.mask, masked(op.value)),
          v);
    co_await host_.pause_until(std::min(Clock::now() + kWaitInterval, deadline));
    if (!host_.port().up()) co_return Reply::of(Reply::Status::link_down, "bus link is down");
  }
}

asio::awaitable<bool> NodeRequests::run_supervision_duty(bool reachable, int retries) {
  // The clock is read only where a duty is due (a system call on User-Mode Linux, and the
  // node's worker asks before every transfer).
  using Duty = NodeSupervision::Duty;
  switch (nmt_.duty(reachable)) {
    case Duty::configure:
      co_await configure_heartbeat(host_.now());
      co_return true;
    case Duty::start: {
      const CanFrame start = nmt_.start(host_.now());
      co_await host_.port().send(start);
      co_return true;
    }
    case Duty::report_pre_operational:
      co_await report_pre_operational(retries, host_.now());
      co_return true;
    case Duty::guard: {
      const auto now = host_.now();
      if (nmt_.next_guard() > now) co_return false;
      if (auto rtr = nmt_.guard(now)) co_await host_.port().send(*rtr);
      co_return true;
    }
    case Duty::none:
      break;
  }
  co_return false;
}

asio::awaitable<void> NodeRequests::configure_heartbeat(TimePoint now) {
  Operation op;
  op.kind = Operation::Kind::write;
  op.object = kHeartbeatObject;
  op.value = nmt_.producer_ms();
  const Reply r = co_await download(op, now, false);
  nmt_.configured(r, op.value, finished_at);
}

asio::awaitable<void> NodeRequests::report_pre_operational(int retries, TimePoint now) {
  nmt_.begin_pre_operational_report();
  // upload() puts it into the error register point, so the map shows it with the NMT state.
  const Reply r = co_await upload(kErrorRegisterObject, retries, now);
  nmt_.report_pre_operational(r);
}

asio::awaitable<void> NodeRequests::probe(TimePoint now) {
  co_await upload(kDeviceTypeObject, 0, now);
}

std::optional<Operation> NodeRequests::operation_of(const Request& request, std::string& error) {
  const auto* compiled = dynamic_cast<const CompiledOperation*>(request.compiled.get());
  if (!compiled) {
    error = "not compiled when the configuration loaded";
    return std::nullopt;
  }
  return compiled->with(request.arguments, error);
}

std::optional<CanFrame> NodeRequests::immediate_frame(const Request& request) const {
  const auto* compiled = dynamic_cast<const CompiledOperation*>(request.compiled.get());
  if (!compiled || compiled->operation().kind != Operation::Kind::nmt) return std::nullopt;
  return nmt_frame(compiled->operation().nmt, request.bus_wide ? 0 : id_);
}

asio::awaitable<Reply> NodeRequests::execute(const Request& request, bool accept_no_reply,
                                             TimePoint now) {
  std::string error;
  const auto op = operation_of(request, error);
  if (!op)
    co_return Reply::of(Reply::Status::device_error,
                        fmt::format("'{}' not sent: {}", request.command, error),
                        sdo_abort::value_range);
  switch (op->kind) {
    case Operation::Kind::read: {
      Reply r = co_await upload(op->object, 0, now);
      co_return r;
    }
    case Operation::Kind::write: {
      Reply r = co_await download(*op, now);
      if (accept_no_reply && r.status == Reply::Status::timeout) r.status = Reply::Status::ok;
      co_return r;
    }
    case Operation::Kind::wait: {
      Reply r = co_await wait_for(*op);
      co_return r;
    }
    case Operation::Kind::nmt: {
      const uint8_t target = request.bus_wide ? 0 : id_;
      const CanFrame frame = nmt_frame(op->nmt, target);
      const bool sent = co_await host_.port().send(frame);
      if (!sent) co_return Reply::of(Reply::Status::link_down, "cannot send NMT: bus link is down");
      if (op->nmt == NmtCommand::start) nmt_.started_by_command(Clock::now());
      co_return Reply::of(Reply::Status::ok);
    }
  }
  co_return Reply::of(Reply::Status::garbled, "unknown operation");
}

}  // namespace fieldgate::canopen
