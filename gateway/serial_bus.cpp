#include "gateway/serial_bus.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>

#include "drivers/transport/serial_transport.hpp"
#include "drivers/transport/tcp_transport.hpp"
#include "gateway/log.hpp"
#include "gateway/reply_accounting.hpp"

namespace fieldgate {

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
using Clock = std::chrono::steady_clock;

std::unique_ptr<ByteTransport> make_transport(asio::any_io_executor ex, const TransportConfig& t) {
  if (t.kind == TransportConfig::Kind::tcp)
    return std::make_unique<TcpTransport>(ex, t.host, t.port, serial_char_time_us(t.serial));
  return std::make_unique<SerialTransport>(ex, t.serial);
}
}  // namespace

struct SerialBus::PendingCommand {
  PendingCommand(asio::any_io_executor ex) : done(ex, 1) {}
  int node = 0;
  Request request;
  CommandOptions options;
  asio::experimental::channel<void(boost::system::error_code, Reply)> done;
};

SerialBus::SerialBus(asio::any_io_executor executor, std::shared_ptr<const void> config_owner,
                     const BusConfig& config, int first_node_index, NodeUpdated on_update)
    : executor_(executor),
      config_owner_(std::move(config_owner)),
      config_(config),
      first_node_index_(first_node_index),
      on_update_(std::move(on_update)),
      transport_(make_transport(executor, config.transport)),
      link_(*transport_),
      wake_(executor) {
  int index = 0;  // local: position on this bus; the gateway's number is first_node_index_ + index
  for (const auto& n : config.nodes) {
    NodeRuntime rt;
    rt.index = index;
    rt.config = &n;
    rt.image = std::make_shared<NodeImage>();
    nodes_.push_back(rt);
    auto& img = *rt.image;
    img.points.assign(n.model->points.size(), {});
    img.setpoints.clear();
    for (const auto& s : n.model->setpoints) {
      const auto it = n.setpoints.find(s.name);
      img.setpoints.push_back(it != n.setpoints.end() ? it->second : s.default_value);
    }
    // One poll item per distinct request: points that share a reply share a transaction.
    std::vector<PollItem> items;
    for (std::size_t p = 0; p < n.model->points.size(); ++p) {
      const auto& point = n.model->points[p];
      if (!point.read || point.poll_class.empty()) continue;
      const std::string command = point.read->request.source();
      const auto period = n.period_of(point.poll_class);
      auto existing = std::find_if(items.begin(), items.end(), [&](const PollItem& it) {
        return it.request.command == command && it.period == period;
      });
      if (existing == items.end()) {
        PollItem item;
        item.node = index;
        item.request = Request{command, Request::Expect::values, point.read->format};
        item.period = period;
        items.push_back(std::move(item));
        existing = std::prev(items.end());
      }
      existing->targets.push_back({static_cast<int>(p), point.read->field});
    }
    for (auto& it : items) plan_.add(std::move(it));
    ++index;
  }
}

SerialBus::~SerialBus() = default;

bool SerialBus::owns_node(int node_index) const {
  return node_index >= first_node_index_ &&
         node_index < first_node_index_ + static_cast<int>(nodes_.size());
}

const NodeConfig& SerialBus::node_config(int node_index) const {
  return *nodes_.at(static_cast<std::size_t>(node_index - first_node_index_)).config;
}

SerialBus::NodeRuntime& SerialBus::node(int node_index) {
  return nodes_.at(static_cast<std::size_t>(node_index - first_node_index_));
}

std::vector<std::shared_ptr<NodeImage>> SerialBus::node_images() const {
  std::vector<std::shared_ptr<NodeImage>> images;
  for (const auto& n : nodes_) images.push_back(n.image);
  return images;
}

void SerialBus::rebind(int first_node_index, NodeUpdated on_update) {
  first_node_index_ = first_node_index;
  on_update_ = std::move(on_update);
}

void SerialBus::stop() {
  stopping_ = true;
  wake_.cancel();
  transport_->close();
}

std::shared_ptr<Bus> make_bus(asio::any_io_executor executor,
                              std::shared_ptr<const void> config_owner, const BusConfig& config,
                              int first_node_index, Bus::NodeUpdated on_update) {
  if (config.transport.kind == TransportConfig::Kind::can)
    return make_can_bus(executor, std::move(config_owner), config, first_node_index,
                        std::move(on_update));
  return std::make_shared<SerialBus>(executor, std::move(config_owner), config, first_node_index,
                                     std::move(on_update));
}

asio::awaitable<Reply> SerialBus::submit(int node_index, Request request, CommandOptions options) {
  auto& n = node(node_index);
  if (options.urgent) {
    // Not queued: the line may be held by a transaction that only ends when this gets through.
    ++counters_.commands;
    co_return co_await config_.family->send_urgent(link_, n.config->address, request);
  }
  // A bus-wide command (a global stop) concerns every node: only the link must be up.
  const bool node_gone = (*n.image).state == NodeState::offline && !request.bus_wide;
  if (node_gone || !transport_->is_open()) {
    Reply r;
    r.status = Reply::Status::unreachable;
    r.text = transport_->is_open() ? "node is offline" : "bus link is down";
    co_return r;
  }
  auto cmd = std::make_shared<PendingCommand>(executor_);
  cmd->node = n.index;  // local, so a reload that renumbers the gateway's nodes cannot misroute it
  cmd->request = std::move(request);
  cmd->options = options;
  commands_.push_back(cmd);
  wake_.cancel();
  auto [ec, reply] = co_await cmd->done.async_receive(use_tuple);
  if (ec) {
    Reply r;
    r.status = Reply::Status::link_down;
    r.text = "gateway stopping";
    co_return r;
  }
  co_return reply;
}

void SerialBus::set_state(NodeRuntime& n, NodeState state, std::string_view why) {
  auto& img = (*n.image);
  if (img.state == state) return;
  const auto old = img.state;
  img.state = state;
  if (state == NodeState::online) {
    log::notice("bus {}: node {} ({}) online{}", config_.name, n.config->name,
                n.config->address.text, old == NodeState::offline ? " again" : "");
    plan_.restart_node(n.index, Clock::now());
  } else if (state == NodeState::offline) {
    log::warning("bus {}: node {} ({}) offline: {}", config_.name, n.config->name,
                 n.config->address.text, why);
    n.next_probe = Clock::now() + config_.timing.probe_interval;
  }
}

bool SerialBus::all_nodes_offline_now() const {
  for (const auto& n : nodes_)
    if (n.image->state != NodeState::offline) return false;
  return true;
}

void SerialBus::all_nodes_offline(std::string_view why) {
  for (auto& n : nodes_) set_state(n, NodeState::offline, why);
}

void SerialBus::record(NodeRuntime& n, const Reply& reply) {
  auto& c = (*n.image).counters;
  switch (count_reply(c, counters_, reply, Clock::now())) {
    case ReplyOutcome::answered:
      set_state(n, NodeState::online, {});
      break;
    case ReplyOutcome::garbled:
      break;
    case ReplyOutcome::failed:
      if (c.consecutive_timeouts >= static_cast<uint32_t>(config_.timing.offline_after) ||
          (*n.image).state == NodeState::offline)
        set_state(n, NodeState::offline,
                  reply.status == Reply::Status::unreachable ? reply.text : "no reply");
      break;
  }
}

asio::awaitable<Reply> SerialBus::transact(NodeRuntime& n, const Request& request, int retries,
                                           bool accept_no_reply) {
  Reply reply;
  for (int attempt = 0; attempt <= retries; ++attempt) {
    if (attempt > 0) {
      ++counters_.retries;
      ++(*n.image).counters.retries;
    }
    const auto started = Clock::now();
    reply =
        co_await config_.family->transact(link_, n.config->address, request, config_.timing.link);
    record_latency(std::chrono::duration<double>(Clock::now() - started).count());
    for (const auto& note : link_.take_notes()) log::notice("bus {}: {}", config_.name, note);
    ++counters_.transactions;
    ++(*n.image).counters.transactions;
    if (accept_no_reply && reply.status == Reply::Status::timeout) {
      reply.status = Reply::Status::ok;
      break;
    }
    if (reply.status == Reply::Status::link_down) break;
    if (reply.status != Reply::Status::timeout && reply.status != Reply::Status::garbled) break;
    if (attempt < retries) record(n, reply);
  }
  record(n, reply);
  if (reply.status == Reply::Status::link_down) {
    log::error("bus {}: link failed: {}", config_.name, reply.text);
    transport_->close();
  }
  co_await link_.pause(config_.timing.inter_frame_gap);
  co_return reply;
}

void SerialBus::record_latency(double seconds) {
  std::size_t bucket = 0;
  while (bucket < std::size(kLatencyBuckets) && seconds > kLatencyBuckets[bucket]) ++bucket;
  ++counters_.latency_counts[bucket];
  counters_.latency_sum += seconds;
  counters_.bytes_sent = link_.stats().bytes_sent;
  counters_.bytes_received = link_.stats().bytes_received;
}

asio::awaitable<void> SerialBus::run_poll(std::size_t item_index) {
  auto& item = plan_.item(item_index);
  auto& n = nodes_[static_cast<std::size_t>(item.node)];
  const bool probing = (*n.image).state == NodeState::offline;
  const Request request = item.request;
  const auto targets = item.targets;
  Reply reply = co_await transact(n, request, probing ? 0 : config_.timing.retries, false);
  const auto now = Clock::now();
  if (probing) {
    n.next_probe = now + config_.timing.probe_interval;
  } else {
    plan_.completed(item_index, now);
  }
  if (reply.status != Reply::Status::ok) co_return;
  auto& img = (*n.image);
  for (const auto& t : targets) {
    if (t.field >= static_cast<int>(reply.values.size())) {
      ++img.counters.errors;
      img.counters.last_error_text = "reply has fewer values than the model expects";
      continue;
    }
    img.points[static_cast<std::size_t>(t.point)] = {
        reply.values[static_cast<std::size_t>(t.field)], now, true};
  }
  if (on_update_) on_update_(first_node_index_ + n.index);
}

asio::awaitable<void> SerialBus::open_link() {
  auto delay = config_.timing.reconnect_min;
  while (!stopping_) {
    const auto ec = co_await transport_->open();
    counters_.open_attempted = true;
    if (!ec) {
      counters_.link_up = true;
      opened_at_ = Clock::now();
      ++counters_.reconnects;
      log::notice("bus {}: opened {}", config_.name, transport_->describe());
      link_error_logged_ = false;
      co_await config_.family->on_link_open(link_, config_.timing.link);
      for (const auto& note : link_.take_notes()) log::notice("bus {}: {}", config_.name, note);
      for (auto& n : nodes_)
        if ((*n.image).state == NodeState::offline) n.next_probe = Clock::now();
      co_return;
    }
    counters_.link_up = false;
    if (!link_error_logged_) {
      log::error(
          "bus {}: cannot open {}: {} (retrying with back-off up to {} s)", config_.name,
          transport_->describe(), ec.message(),
          std::chrono::duration_cast<std::chrono::seconds>(config_.timing.reconnect_max).count());
      link_error_logged_ = true;
    }
    all_nodes_offline("bus link is down");
    while (!commands_.empty()) {
      Reply r;
      r.status = Reply::Status::unreachable;
      r.text = "bus link is down";
      commands_.front()->done.try_send(boost::system::error_code{}, r);
      commands_.pop_front();
    }
    wake_.expires_after(delay);
    co_await wake_.async_wait(use_tuple);
    delay = std::min(delay * 2, config_.timing.reconnect_max);
  }
}

asio::awaitable<void> SerialBus::run() {
  plan_.start(Clock::now());
  while (!stopping_) {
    if (!transport_->is_open()) {
      counters_.link_up = false;
      co_await open_link();
      continue;
    }
    if (!commands_.empty()) {
      auto cmd = commands_.front();
      commands_.pop_front();
      ++counters_.commands;
      auto& n = nodes_[static_cast<std::size_t>(cmd->node)];
      Reply reply;
      if ((*n.image).state == NodeState::offline && !cmd->request.bus_wide) {
        reply.status = Reply::Status::unreachable;
        reply.text = "node is offline";
      } else {
        // Commands are not retried: a lost reply may hide a command the device already ran.
        reply = co_await transact(n, cmd->request, 0, cmd->options.accept_no_reply);
      }
      cmd->done.try_send(boost::system::error_code{}, std::move(reply));
      continue;
    }
    const auto now = Clock::now();
    auto due = plan_.next([&](int local) {
      return nodes_[static_cast<std::size_t>(local)].image->state != NodeState::offline;
    });
    std::optional<std::size_t> probe;
    SteadyTime probe_when = SteadyTime::max();
    for (auto& n : nodes_) {
      if ((*n.image).state != NodeState::offline) continue;
      if (n.next_probe < probe_when) {
        if (auto item = plan_.probe_item(n.index)) {
          probe = item;
          probe_when = n.next_probe;
        }
      }
    }
    std::optional<std::size_t> chosen;
    SteadyTime when = SteadyTime::max();
    if (due) {
      chosen = due->item;
      when = due->when;
    }
    if (probe && probe_when < when) {
      chosen = probe;
      when = probe_when;
    }
    if (chosen && when <= now) {
      // Nothing on the link answers (a power-cycled controller back at its power-up rate, a
      // re-plugged adapter): reopen it, so the family's link-open procedure runs again.
      if (chosen == probe && all_nodes_offline_now() &&
          now - opened_at_ >= config_.timing.probe_interval) {
        transport_->close();
        continue;
      }
      co_await run_poll(*chosen);
      continue;
    }
    wake_.expires_at(when);
    co_await wake_.async_wait(use_tuple);
  }
  while (!commands_.empty()) {
    commands_.front()->done.try_send(asio::error::operation_aborted, Reply{});
    commands_.pop_front();
  }
}

}  // namespace fieldgate
