#include "gateway/bus/can_bus.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>
#include <stdexcept>

#include "gateway/bus/node_image_setup.hpp"
#include "gateway/bus/pending_command.hpp"
#include "gateway/bus/reply_accounting.hpp"
#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

using namespace canopen;

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
using BusClock = std::chrono::steady_clock;
// Error frames can flood (a bus without termination): one log line per this interval at most.
constexpr auto kErrorLogInterval = std::chrono::seconds(10);
// A CAN bus runs a frame family; the configuration loader pairs `can:` with them.
const FrameFamily& frame_family(const BusConfig& config) {
  const auto* family = dynamic_cast<const FrameFamily*>(config.family.get());
  if (!family)
    throw std::invalid_argument(fmt::format(
        "bus {}: protocol {} runs on a byte stream, not on a CAN bus (can:)", config.name,
        config.family ? config.family->name() : std::string_view("(none)")));
  return *family;
}
}  // namespace

struct CanBus::NodeRuntime final : RequestHost {
  NodeRuntime(CanBus& bus, asio::any_io_executor ex, const NodeConfig& nc,
              const SupervisionTiming& timing)
      : bus(bus),
        id(static_cast<uint8_t>(nc.address.number)),
        config(&nc),
        points(id, *nc.model,
               [&](const PointDef& point, const std::string& error) {
                 log::error("bus {}: node {}: point {}: {}", bus.config_->name, nc.name, point.name,
                            error);
               }),
        wake(ex),
        sdo(id, bus.config_->timing.link.reply_timeout, wake),
        nmt(id, nc.name, timing, *this),
        requests(id, sdo, nmt, points, *this),
        tpdos(points.tpdo_cobs()) {}

  Presence presence() const override {
    switch (image->state) {
      case NodeState::starting:
        return Presence::starting;
      case NodeState::online:
        return Presence::online;
      case NodeState::offline:
        return Presence::offline;
      case NodeState::faulted:
        break;
    }
    return Presence::faulted;
  }
  void go_online() override { bus.set_state(*this, NodeState::online, {}); }
  void go_offline(std::string why) override { bus.set_state(*this, NodeState::offline, why); }
  void probe_by(SteadyTime when) override { next_probe = std::min(next_probe, when); }
  void refresh_local_points(SteadyTime now) override { bus.refresh_local_points(*this, now); }
  void nmt_state_forgotten() override {
    for (const int p : points.nmt_state_points())
      image->points[static_cast<std::size_t>(p)].valid = false;
    bus.notify(*this);
  }
  void device_error(uint16_t code, std::string text) override {
    image->counters.last_device_error = code;
    image->counters.last_error_text = std::move(text);
  }
  void error_text(std::string text) override {
    image->counters.last_error_text = std::move(text);
    bus.notify(*this);
  }
  void wake_worker() override { wake.cancel(); }
  void log(int level, std::string text) override {
    log::write(static_cast<log::Level>(std::clamp(level, 3, 7)),
               fmt::format("bus {}: {}", bus.config_->name, text));
  }
  SteadyTime now() const override { return BusClock::now(); }

  FramePort& port() override { return bus; }
  void transfer_done(double seconds) override {
    count_latency(bus.counters_, seconds);
    ++bus.counters_.transactions;
    ++image->counters.transactions;
  }
  void retrying() override {
    ++bus.counters_.retries;
    ++image->counters.retries;
  }
  void record(const Reply& reply, SteadyTime sent, SteadyTime at) override {
    bus.record(*this, reply, sent, at);
  }
  void store(const std::vector<PointUpdate>& updates, SteadyTime at) override {
    for (const auto& u : updates)
      image->points[static_cast<std::size_t>(u.point)] = {u.value, at, true};
    if (!updates.empty()) bus.notify(*this);
  }
  void heartbeat_rearmed() override { bus.supervisor_wake_.cancel(); }
  void object_absent(const std::vector<PointUpdate>& updates, SteadyTime at) override {
    for (const auto& u : updates) {
      const auto p = static_cast<std::size_t>(u.point);
      image->points[p] = {u.value, at, true};
      if (p < image->polled.size()) image->polled[p] = false;
    }
    if (!updates.empty()) bus.notify(*this);
  }
  bool urgent_pending() const override { return urgent_waiting; }
  asio::awaitable<void> pause_until(SteadyTime when) override {
    co_await bus.sleep_until(wake, when);
  }

  CanBus& bus;
  int index = 0;  // position on this bus
  uint8_t id = 0;
  const NodeConfig* config = nullptr;
  std::shared_ptr<NodeImage> image;
  NodePoints points;

  asio::steady_timer wake;
  SdoChannel sdo;
  NodeSupervision nmt;    // heartbeat, NMT, EMCY
  NodeRequests requests;  // commands, polls, probes and bring-up as transfers
  TpdoFreshness tpdos;    // the TPDOs that spare polls their transfer
  std::deque<std::shared_ptr<PendingCommand>> commands;
  std::vector<bool> polled;  // by model point: a poll item reads it (objects absent or not)
  bool urgent_waiting = false;
  SteadyTime next_probe{};
};

CanBus::CanBus(asio::any_io_executor executor, std::shared_ptr<const void> config_owner,
               const BusConfig& config, int first_node_index, NodeUpdated on_update,
               std::unique_ptr<CanChannel> channel)
    : executor_(executor),
      config_owners_(config_owner),
      config_(&config),
      family_(frame_family(config)),
      first_node_index_(first_node_index),
      on_update_(std::move(on_update)),
      channel_(std::move(channel)),
      wake_(executor),
      supervisor_wake_(executor),
      trace_(config.name, config.trace) {
  if (!channel_)
    channel_ = std::make_unique<SocketCanTransport>(executor, config.transport.can_interface);
  SupervisionTiming timing;
  timing.heartbeat_timeout =
      std::chrono::duration_cast<std::chrono::microseconds>(config.timing.heartbeat_timeout);
  timing.reply_timeout = config.timing.link.reply_timeout;
  timing.start_nodes = config.timing.start_nodes;
  timing.offline_after = config.timing.offline_after;
  int index = 0;
  for (const auto& nc : config.nodes) {
    auto rt = std::make_unique<NodeRuntime>(*this, executor, nc, timing);
    auto& n = *rt;
    n.index = index;
    n.image = make_node_image(nc);
    const Model& model = *nc.model;
    for (const uint32_t cob : family_.receive_ids(nc.address, model)) by_cob_[cob] = &n;

    nodes_.push_back(std::move(rt));
    ++index;
  }
  plan_polls();
}

void CanBus::plan_polls() {
  plan_ = PollPlan{};
  jobs_.clear();
  for (auto& rt : nodes_) {
    auto& n = *rt;
    const NodeConfig& nc = *n.config;
    const Model& model = *nc.model;
    const auto add_target = [&](const PollJob& job, int point, SteadyTime::duration period) {
      const auto us = std::chrono::duration_cast<std::chrono::microseconds>(period);
      for (std::size_t i = 0; i < jobs_.size(); ++i) {
        auto& item = plan_.item(i);
        if (item.node == n.index && item.period == us && jobs_[i] == job) {
          item.targets.push_back({point, 0});
          return;
        }
      }
      PollItem item;
      item.node = n.index;
      item.period = us;
      item.request = poll_request(job);
      item.targets.push_back({point, 0});
      plan_.add(std::move(item));
      jobs_.push_back(job);
    };
    for (std::size_t p = 0; p < model.points.size(); ++p) {
      const auto& point = model.points[p];
      if (!point.read || point.poll_class.empty()) continue;
      const auto period = nc.period_of(point.poll_class);
      if (period.count() <= 0) continue;
      if (const auto job = n.points.poll_job(p)) add_target(*job, static_cast<int>(p), period);
    }
    // The data age covers the polled points only (a write-only point is never read).
    n.polled.assign(model.points.size(), false);
    for (const auto& item : plan_.items())
      if (item.node == n.index)
        for (const auto& t : item.targets) n.polled[static_cast<std::size_t>(t.point)] = true;
    n.image->polled = n.polled;
  }
}

bool CanBus::reconfigure(std::shared_ptr<const void> config_owner, const BusConfig& config,
                         int first_node_index, NodeUpdated on_update) {
  if (config.name != config_->name || config.link_signature != config_->link_signature ||
      config.nodes.size() != nodes_.size())
    return false;
  for (std::size_t i = 0; i < nodes_.size(); ++i)
    if (nodes_[i]->config->name != config.nodes[i].name ||
        nodes_[i]->config->identity != config.nodes[i].identity)
      return false;
  config_owners_.push(config_owner);
  config_ = &config;
  for (std::size_t i = 0; i < nodes_.size(); ++i) {
    auto& n = *nodes_[i];
    const NodeConfig& nc = config.nodes[i];
    apply_setpoint_changes(*n.image, *n.config, nc);
    n.config = &nc;
  }
  // Points of objects a device was found to lack stay out of its data age.
  std::vector<std::vector<std::size_t>> absent(nodes_.size());
  for (std::size_t i = 0; i < nodes_.size(); ++i)
    for (std::size_t p = 0; p < nodes_[i]->polled.size(); ++p)
      if (nodes_[i]->polled[p] && !nodes_[i]->image->polled[p]) absent[i].push_back(p);
  const PollPlan previous = std::move(plan_);
  plan_polls();
  for (std::size_t i = 0; i < nodes_.size(); ++i)
    for (const auto p : absent[i]) nodes_[i]->image->polled[p] = false;
  std::vector<int> same(nodes_.size());
  for (std::size_t i = 0; i < same.size(); ++i) same[i] = static_cast<int>(i);
  plan_.start_after(previous, same, BusClock::now());
  ++numbering_;
  first_node_index_ = first_node_index;
  on_update_ = std::move(on_update);
  for (auto& n : nodes_) n->wake.cancel();  // each worker picks its next poll from the new plan
  return true;
}

CanBus::~CanBus() = default;

std::shared_ptr<Bus> make_can_bus(asio::any_io_executor executor,
                                  std::shared_ptr<const void> config_owner, const BusConfig& config,
                                  int first_node_index, Bus::NodeUpdated on_update) {
  return std::make_shared<CanBus>(executor, std::move(config_owner), config, first_node_index,
                                  std::move(on_update));
}

const NodeConfig& CanBus::node_config(int node_index) const {
  return *node(node_index).config;
}

CanBus::NodeRuntime& CanBus::node(int node_index) {
  return *nodes_.at(static_cast<std::size_t>(node_index - first_node_index_));
}

const CanBus::NodeRuntime& CanBus::node(int node_index) const {
  return *nodes_.at(static_cast<std::size_t>(node_index - first_node_index_));
}

CanBus::NodeStatus CanBus::node_status(int node_index) const {
  return node(node_index).nmt.status();
}

std::vector<std::shared_ptr<NodeImage>> CanBus::node_images() const {
  std::vector<std::shared_ptr<NodeImage>> images;
  for (const auto& n : nodes_) images.push_back(n->image);
  return images;
}

void CanBus::rebind(int first_node_index, NodeUpdated on_update) {
  ++numbering_;
  first_node_index_ = first_node_index;
  on_update_ = std::move(on_update);
}

std::vector<uint32_t> CanBus::receive_ids() const {
  std::vector<uint32_t> ids;
  for (const auto& [cob, n] : by_cob_) ids.push_back(cob);
  return ids;
}

void CanBus::wake_all() {
  for (auto& n : nodes_) n->wake.cancel();
  wake_.cancel();
  supervisor_wake_.cancel();
}

void CanBus::stop() {
  stopping_ = true;
  channel_->close();
  wake_all();
}

void CanBus::notify(NodeRuntime& n) {
  if (on_update_) on_update_(first_node_index_ + n.index);
}

asio::awaitable<bool> CanBus::sleep_until(asio::steady_timer& timer, SteadyTime when) {
  timer.expires_at(when);
  auto [ec] = co_await timer.async_wait(use_tuple);
  co_return !ec;
}

// --- link ------------------------------------------------------------------------------------

asio::awaitable<void> CanBus::run() {
  auto self = shared_from_this();
  plan_.start(BusClock::now());
  for (auto& n : nodes_) {
    ++workers_running_;
    asio::co_spawn(
        executor_, [self, &n = *n]() -> asio::awaitable<void> { co_await self->node_worker(n); },
        asio::detached);
  }
  if (heartbeat_consumer()) {
    ++workers_running_;
    asio::co_spawn(
        executor_, [self]() -> asio::awaitable<void> { co_await self->heartbeat_supervisor(); },
        asio::detached);
  }
  auto delay = config_->timing.reconnect_min;
  while (!stopping_) {
    const auto ec = channel_->open(receive_ids());
    counters_.open_attempted = true;
    if (ec) {
      counters_.link_up = false;
      if (!link_error_logged_) {
        log::error(
            "bus {}: cannot open {}: {} (retrying with back-off up to {} ms; its nodes are "
            "offline meanwhile)",
            config_->name, channel_->describe(), ec.message(),
            std::chrono::duration_cast<std::chrono::milliseconds>(config_->timing.reconnect_max)
                .count());
        link_error_logged_ = true;
      }
      for (auto& n : nodes_) {
        n->nmt.link_lost();
        set_state(*n, NodeState::offline, "bus link is down");
      }
      fail_commands("bus link is down");
      co_await sleep_until(wake_, BusClock::now() + delay);
      delay = std::min(delay * 2, config_->timing.reconnect_max);
      continue;
    }
    delay = config_->timing.reconnect_min;
    link_error_logged_ = false;
    link_up_ = true;
    counters_.link_up = true;
    ++counters_.reconnects;
    log::notice("bus {}: opened {} ({} nodes{}{})", config_->name, channel_->describe(),
                nodes_.size(), heartbeat_consumer() ? ", heartbeat consumer" : "",
                config_->timing.start_nodes ? ", NMT start" : "");
    const auto now = BusClock::now();
    for (auto& n : nodes_) {
      n->nmt.bring_up(true);
      n->tpdos.restart(now);
      n->next_probe = now;
    }
    wake_all();
    co_await read_loop();
    link_up_ = false;
    counters_.link_up = false;
    channel_->close();
    if (stopping_) break;
    for (auto& n : nodes_) {
      n->nmt.link_lost();
      set_state(*n, NodeState::offline, "bus link is down");
    }
    fail_commands("bus link is down");
    wake_all();
    co_await sleep_until(wake_, BusClock::now() + delay);
  }
  stopping_ = true;
  wake_all();
  fail_commands("gateway stopping");
  while (workers_running_ > 0) {
    wake_.expires_at(SteadyTime::max());
    co_await wake_.async_wait(use_tuple);
  }
}

void CanBus::link_failed(std::error_code ec) {
  if (!link_up_) return;
  log::error("bus {}: {} failed: {}; reopening", config_->name, channel_->describe(), ec.message());
  link_up_ = false;
  counters_.link_up = false;
  channel_->close();  // ends read_loop
  wake_all();
}

void CanBus::fail_commands(std::string_view why) {
  for (auto& n : nodes_) {
    while (!n->commands.empty()) {
      n->commands.front()->answer(Reply::of(Reply::Status::unreachable, std::string(why)));
      n->commands.pop_front();
    }
    n->urgent_waiting = false;
  }
}

asio::awaitable<void> CanBus::read_loop() {
  std::vector<CanFrame> frames;
  while (!stopping_ && link_up_) {
    frames.clear();
    const auto ec = co_await channel_->receive(frames);
    const auto now = BusClock::now();
    for (const auto& f : frames) dispatch(f, now);
    can_counters_.rx_dropped = channel_->stats().rx_dropped;
    can_counters_.tx_dropped = channel_->stats().tx_dropped;
    if (ec) {
      if (!stopping_) link_failed(ec);
      break;
    }
  }
}

void CanBus::trace_frame(const CanFrame& frame, TraceDirection direction, SteadyTime at,
                         std::string_view outcome) {
  if (!trace_.active()) return;
  const int id = family_.frame_node(frame);
  std::string node = id == FrameFamily::kNoNode      ? "-"
                     : id == FrameFamily::kEveryNode ? "*"
                                                     : std::to_string(id);
  for (const auto& n : nodes_)
    if (n->id == id) node = n->config->name;
  trace_.emit(at, node, direction, outcome, to_string(frame));
}

asio::awaitable<bool> CanBus::send(const CanFrame& frame, std::string_view outcome) {
  if (!link_up_) co_return false;
  const auto ec = co_await channel_->send(frame, config_->timing.link.reply_timeout);
  if (!ec) {
    trace_frame(frame, TraceDirection::tx, BusClock::now(), outcome);
    ++can_counters_.frames_sent;
    counters_.bytes_sent += frame.len;
    co_return true;
  }
  if (ec == std::errc::timed_out) {
    // The transmit queue stayed full (a bus-off controller, no other node acknowledging): the
    // frame is dropped and counted, and the transfer times out like one without an answer.
    co_return false;
  }
  link_failed(ec);
  co_return false;
}

// --- received frames -------------------------------------------------------------------------

void CanBus::dispatch(const CanFrame& frame, SteadyTime now) {
  if (frame.error) {
    trace_frame(frame, TraceDirection::rx, now, "error_frame");
    on_error_frame(frame, now);
    return;
  }
  ++can_counters_.frames_received;
  counters_.bytes_received += frame.len;
  const auto it = by_cob_.find(frame.id);
  if (it == by_cob_.end()) {
    trace_frame(frame, TraceDirection::rx, now, {});
    return;
  }
  NodeRuntime& n = *it->second;
  switch (family_.classify(n.config->address, frame)) {
    case FrameRole::transfer_response:
      trace_frame(frame, TraceDirection::rx, now, n.sdo.on_response(frame, now));
      break;
    case FrameRole::heartbeat:
      trace_frame(frame, TraceDirection::rx, now, {});
      if (auto hb = parse_heartbeat(frame)) {
        if (hb->state == nmt_state::boot_up) {
          ++n.image->controller_resets;
          // The SDO timeouts before it were the controller's before its restart.
          n.image->counters.consecutive_timeouts = 0;
          if (!n.requests.absent_objects().empty()) {
            // Restarted: perhaps with other firmware. Absent objects are polled again.
            n.requests.absent_objects().clear();
            n.image->polled = n.polled;
          }
        }
        n.nmt.on_heartbeat(hb->state, hb->toggle, now);
        if (hb->state == nmt_state::boot_up) notify(n);
      }
      break;
    case FrameRole::emergency:
      trace_frame(frame, TraceDirection::rx, now, {});
      if (auto e = parse_emergency(frame)) n.nmt.on_emergency(*e);
      break;
    case FrameRole::none:
      trace_frame(frame, TraceDirection::rx, now, {});
      return;
    case FrameRole::other:
      trace_frame(frame, TraceDirection::rx, now, {});
      break;
  }
  if (n.points.reads_tpdo(frame.id)) on_tpdo(n, frame, now);
}

void CanBus::on_error_frame(const CanFrame& frame, SteadyTime now) {
  const auto info = decode_error_frame(frame);
  ++can_counters_.error_frames;
  if (info.bus_off) {
    ++can_counters_.bus_off;
    // The controller stops until it restarts (restart-ms, or `ip link set ... type can restart`):
    // nodes time out or lose their heartbeat meanwhile and come back by themselves.
    log::error("bus {}: CAN controller bus-off ({})", config_->name, to_string(frame));
    error_frames_logged_ = now;
    return;
  }
  if (now - error_frames_logged_ < kErrorLogInterval) {
    ++error_frames_unlogged_;
    return;
  }
  if (error_frames_unlogged_ > 0)
    log::warning("bus {}: CAN error frame: {} ({}; {} more since the last report)", config_->name,
                 info.text, to_string(frame), error_frames_unlogged_);
  else
    log::warning("bus {}: CAN error frame: {} ({})", config_->name, info.text, to_string(frame));
  error_frames_logged_ = now;
  error_frames_unlogged_ = 0;
}

void CanBus::on_tpdo(NodeRuntime& n, const CanFrame& frame, SteadyTime now) {
  n.tpdos.received(frame.id, now);
  ++n.nmt.status().pdos;
  auto& img = *n.image;
  std::vector<std::string> errors;
  for (const auto& u : n.points.from_tpdo(frame, errors))
    img.points[static_cast<std::size_t>(u.point)] = {u.value, now, true};
  for (auto& error : errors) {
    ++img.counters.errors;
    img.counters.last_error_text = std::move(error);
  }
  notify(n);
}

void CanBus::refresh_local_points(NodeRuntime& n, SteadyTime now) {
  if (!n.points.has_local_points()) return;
  for (const auto& u : n.points.local_values(n.nmt.status()))
    n.image->points[static_cast<std::size_t>(u.point)] = {u.value, now, true};
  notify(n);
}

asio::awaitable<void> CanBus::heartbeat_supervisor() {
  // Woken well after its deadline, the process itself was held up (a loaded host): heartbeats
  // that came meanwhile wait in the socket, and are read before a missing one is concluded.
  constexpr auto kStalled = std::chrono::milliseconds(20);
  SteadyTime intended = SteadyTime::max();
  while (!stopping_) {
    const auto now = BusClock::now();
    if (intended != SteadyTime::max() && now - intended > kStalled) {
      intended = SteadyTime::max();
      co_await sleep_until(supervisor_wake_, now + std::chrono::milliseconds(1));
      continue;
    }
    SteadyTime next = SteadyTime::max();
    for (auto& n : nodes_) {
      if (!link_up_ || n->image->state == NodeState::offline) continue;
      next = std::min(next, n->nmt.check_heartbeat(now));
    }
    intended = next;
    co_await sleep_until(supervisor_wake_, next);
  }
  --workers_running_;
  wake_.cancel();
}

// --- node state ------------------------------------------------------------------------------

void CanBus::set_state(NodeRuntime& n, NodeState state, std::string_view why) {
  auto& img = *n.image;
  if (img.state == state) return;
  const auto old = img.state;
  img.state = state;
  const auto now = BusClock::now();
  if (state == NodeState::online) {
    log::notice("bus {}: node {} ({}) online{}", config_->name, n.config->name, n.id,
                old == NodeState::offline ? " again" : "");
    // Online by its heartbeat, the probes that timed out before do not count toward the next
    // offline.
    img.counters.consecutive_timeouts = 0;
    n.nmt.went_online(old == NodeState::offline);
    plan_.resume_node(n.index, now);
    n.tpdos.restart(now);
    refresh_local_points(n, now);
  } else if (state == NodeState::offline) {
    log::warning("bus {}: node {} ({}) offline: {}", config_->name, n.config->name, n.id, why);
    img.counters.last_error_text = std::string(why);
    n.next_probe = now + config_->timing.probe_interval;
    n.nmt.went_offline();
  }
  n.wake.cancel();
}

void CanBus::record(NodeRuntime& n, const Reply& reply, SteadyTime sent, SteadyTime at) {
  auto& c = n.image->counters;
  const auto consecutive_timeouts = c.consecutive_timeouts;
  switch (count_reply(c, counters_, reply, at)) {
    case ReplyOutcome::answered:
      set_state(n, NodeState::online, {});
      break;
    case ReplyOutcome::garbled:
      break;
    case ReplyOutcome::failed:
      if (reply.status == Reply::Status::timeout && n.nmt.restarted_since(sent)) {
        // Sent before the node's boot-up: its restart dropped the request. Counted as a timeout,
        // but the node that just booted is not silent.
        c.consecutive_timeouts = consecutive_timeouts;
        break;
      }
      if (reply.status == Reply::Status::timeout &&
          c.consecutive_timeouts >= static_cast<uint32_t>(config_->timing.offline_after)) {
        n.nmt.sdo_silent();  // its heartbeat may go on while SDO is dead
        set_state(n, NodeState::offline, "no SDO response");
      }
      break;
  }
}

// --- transfers -------------------------------------------------------------------------------

asio::awaitable<Reply> CanBus::submit(int node_index, Request request, CommandOptions options) {
  auto& n = node(node_index);
  if (options.urgent) {
    // NMT has no answer and no per-node transfer: it goes out at once.
    if (const auto frame = n.requests.immediate_frame(request)) {
      ++counters_.commands;
      if (options.on_sent) options.on_sent();
      const bool sent = co_await send(*frame);
      co_return sent ? Reply::of(Reply::Status::ok)
                     : Reply::of(Reply::Status::link_down, "bus link is down");
    }
  }
  // A bus-wide command (NMT to all nodes) concerns every node: only the link must be up.
  if ((n.image->state == NodeState::offline && !request.bus_wide) || !link_up_)
    co_return Reply::of(Reply::Status::unreachable,
                        link_up_ ? "node is offline" : "bus link is down");
  auto cmd = std::make_shared<PendingCommand>(executor_);
  cmd->request = std::move(request);
  cmd->options = options;
  if (options.urgent) {
    // Ahead of everything queued, and a running `wait` step gives way to it.
    n.commands.push_front(cmd);
    n.urgent_waiting = true;
  } else {
    n.commands.push_back(cmd);
  }
  n.wake.cancel();
  co_return co_await cmd->reply();
}

// --- node worker -----------------------------------------------------------------------------

asio::awaitable<void> CanBus::run_poll(NodeRuntime& n, std::size_t item_index, SteadyTime now) {
  const auto info = jobs_[item_index];
  const auto period = plan_.item(item_index).period;
  n.requests.finished_at = now;
  if (info.kind == PollJob::Kind::local) {
    refresh_local_points(n, now);
    plan_.completed(item_index, now);
    co_return;
  }
  if (n.tpdos.keeps_fresh(info, period, now)) {
    plan_.completed(item_index, now);  // no SDO traffic
    co_return;
  }
  // Due again a period after it was started, so a poll that is due sooner than its transfer
  // takes runs straight after it.
  plan_.completed(item_index, now);
  // poll() stores the value in every point of the object, the targets among them.
  co_await n.requests.poll(info.object, config_->timing.retries, now);
}

asio::awaitable<void> CanBus::node_worker(NodeRuntime& n) {
  // The time, when a transfer's end or a timer's expiry just told it: the clock is read only
  // when nothing did (a system call on User-Mode Linux, and this loop runs per transfer).
  std::optional<SteadyTime> known_now;
  while (!stopping_) {
    if (!link_up_) {
      co_await sleep_until(n.wake, SteadyTime::max());
      continue;
    }
    // Bring-up, a report and node guarding go before commands and polls.
    const bool reachable = n.image->state != NodeState::offline;
    if (co_await n.requests.run_supervision_duty(reachable, config_->timing.retries)) continue;
    if (!n.commands.empty()) {
      auto cmd = n.commands.front();
      n.commands.pop_front();
      ++counters_.commands;
      if (cmd->options.urgent)
        n.urgent_waiting = std::any_of(n.commands.begin(), n.commands.end(),
                                       [](const auto& c) { return c->options.urgent; });
      Reply reply;
      if (n.image->state == NodeState::offline && !cmd->request.bus_wide)
        reply = Reply::of(Reply::Status::unreachable, "node is offline");
      else {
        // Commands are not retried: a lost answer may hide a command the node carried out.
        if (cmd->options.on_sent) cmd->options.on_sent();
        reply = co_await n.requests.execute(cmd->request, cmd->options.accept_no_reply,
                                            BusClock::now());
      }
      cmd->answer(std::move(reply));
      continue;
    }
    const auto now = known_now ? *known_now : BusClock::now();
    known_now.reset();
    const bool offline = n.image->state == NodeState::offline;
    SteadyTime when = SteadyTime::max();
    std::optional<std::size_t> due;
    if (!offline) {
      if (auto d = plan_.next([&](int local) { return local == n.index; })) {
        due = d->item;
        when = d->when;
      }
      if (n.nmt.next_guard() < when) {
        const SteadyTime guard_at = n.nmt.next_guard();
        const bool expired = co_await sleep_until(n.wake, guard_at);
        if (expired) known_now = guard_at;
        continue;
      }
    } else {
      // Also after a heartbeat loss: a node whose producer time was reset unseen answers SDO.
      when = n.next_probe;
    }
    if (when <= now) {
      if (offline) {
        n.next_probe = now + config_->timing.probe_interval;
        co_await n.requests.probe(now);
      } else {
        co_await run_poll(n, *due, now);
      }
      known_now = n.requests.finished_at;
      continue;
    }
    const bool expired = co_await sleep_until(n.wake, when);
    if (expired) known_now = when;
  }
  while (!n.commands.empty()) {
    n.commands.front()->abandon();
    n.commands.pop_front();
  }
  --workers_running_;
  wake_.cancel();
}

}  // namespace fieldgate
