#include "gateway/gateway.hpp"

#include <algorithm>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/execution.hpp>
#include <boost/asio/ip/address.hpp>

#include "gateway/console/fleet_watch.hpp"
#include "gateway/console/plant_view.hpp"
#include "gateway/lifecycle/log.hpp"
#include "gateway/metrics/metrics.hpp"
#include "gateway/sparkplug/edge_node.hpp"

namespace fieldgate {

namespace {

using namespace std::chrono_literals;

// How often a reload's replaced configuration is looked at again while something still runs on it.
constexpr auto kSweepInterval = 1s;

// The io_context's executor, counting the work tracked through it in `work`. An ActionRunner
// given it counts its own coroutines: co_spawn tracks work for each coroutine until it ends (its
// steps in the background, its completion watch), and every wait of its timers is tracked too.
//
// Stand-in for a count of its own (ActionRunner::in_flight(), asked of the register map's
// owner): this sees the coroutines it spawns, not an action run inline in a caller's coroutine
// (a Modbus request, which holds its generation through its handler, or a profile axis's
// follow-up, see Gateway::idle).
class WorkCountingExecutor {
 public:
  WorkCountingExecutor(asio::any_io_executor inner, std::shared_ptr<std::size_t> work) noexcept
      : inner_(std::move(inner)), work_(std::move(work)) {}
  WorkCountingExecutor(const WorkCountingExecutor& other) noexcept
      : inner_(other.inner_), work_(other.work_), tracked_(other.tracked_) {
    if (tracked_) ++*work_;
  }
  WorkCountingExecutor& operator=(const WorkCountingExecutor& other) noexcept {
    if (this == &other) return *this;
    release();
    inner_ = other.inner_;
    work_ = other.work_;
    tracked_ = other.tracked_;
    if (tracked_) ++*work_;
    return *this;
  }
  ~WorkCountingExecutor() { release(); }

  asio::execution_context& query(asio::execution::context_t) const noexcept {
    return asio::query(inner_, asio::execution::context_as<asio::execution_context&>);
  }
  asio::execution::outstanding_work_t query(asio::execution::outstanding_work_t) const noexcept {
    if (tracked_) return asio::execution::outstanding_work.tracked;
    return asio::execution::outstanding_work.untracked;
  }
  WorkCountingExecutor require(asio::execution::blocking_t::never_t p) const {
    return with(asio::require(inner_, p), tracked_);
  }
  WorkCountingExecutor require(asio::execution::blocking_t::possibly_t p) const {
    return with(asio::prefer(inner_, p), tracked_);
  }
  WorkCountingExecutor require(asio::execution::outstanding_work_t::tracked_t p) const {
    return with(asio::prefer(inner_, p), true);
  }
  WorkCountingExecutor require(asio::execution::outstanding_work_t::untracked_t p) const {
    return with(asio::prefer(inner_, p), false);
  }
  template <typename F>
  void execute(F&& f) const {
    inner_.execute(std::forward<F>(f));
  }
  friend bool operator==(const WorkCountingExecutor& a, const WorkCountingExecutor& b) noexcept {
    return a.inner_ == b.inner_ && a.work_ == b.work_ && a.tracked_ == b.tracked_;
  }

 private:
  WorkCountingExecutor with(asio::any_io_executor inner, bool tracked) const {
    WorkCountingExecutor e(std::move(inner), work_);
    e.tracked_ = tracked;
    if (tracked) ++*work_;
    return e;
  }
  void release() {
    if (tracked_) --*work_;
    tracked_ = false;
  }

  asio::any_io_executor inner_;
  std::shared_ptr<std::size_t> work_;
  bool tracked_ = false;
};

static_assert(asio::execution::is_executor<WorkCountingExecutor>::value);

template <typename Stats>
HttpServerCounts plus(HttpServerCounts counts, const Stats& stats) {
  counts.refused += stats.refused;
  counts.evicted += stats.evicted;
  counts.denied += stats.denied;
  counts.bad_requests += stats.bad_requests;
  return counts;
}

}  // namespace

Gateway::Gateway(asio::io_context& io, std::shared_ptr<const LoadedConfig> config) : io_(io) {
  current_ = build(std::move(config), nullptr, pending_start_);
}

Gateway::~Gateway() {
  stop();
}

std::shared_ptr<Gateway::Generation> Gateway::build(std::shared_ptr<const LoadedConfig> config,
                                                    Generation* previous,
                                                    std::vector<std::shared_ptr<Bus>>& fresh) {
  auto g = std::make_shared<Generation>();
  g->config = config;
  Generation* raw = g.get();
  // A bus a reload stopped may still finish a poll after its generation was freed.
  const auto on_update = [weak = std::weak_ptr<Generation>(g)](int node_index) {
    if (const auto live = weak.lock()) live->actions->node_updated(node_index);
  };
  std::vector<std::shared_ptr<NodeImage>> images;
  PreviousNodes previous_nodes;  // node names are unique in a configuration
  if (previous) {
    int index = 0;
    for (const auto& old_bus : previous->config->gateway.buses)
      for (const auto& old : old_bus.nodes)
        previous_nodes.emplace(old.name, std::pair{index++, &old});
  }
  int first = 0;
  for (const auto& bus_config : config->gateway.buses) {
    std::shared_ptr<Bus> bus;
    if (previous) {
      for (const auto& old : previous->buses) {
        if (old->config().name != bus_config.name) continue;
        if (old->config().signature == bus_config.signature) {
          old->rebind(first, on_update);
          bus = old;
        } else if (old->reconfigure(config, bus_config, first, on_update)) {
          ++g->reconfigured;
          bus = old;
        }
      }
    }
    if (!bus) {
      bus = make_bus(io_.get_executor(), config, bus_config, first, on_update);
      if (previous) carry_over(*previous, previous_nodes, bus_config, *bus);
      fresh.push_back(bus);
    }
    for (auto& image : bus->node_images()) images.push_back(std::move(image));
    for (std::size_t i = 0; i < bus_config.nodes.size(); ++i)
      g->bus_of_node.push_back(static_cast<int>(g->buses.size()));
    g->buses.push_back(bus);
    first += static_cast<int>(bus_config.nodes.size());
  }
  g->image = ProcessImage(std::move(images));
  const auto bus_of = [raw](int n) -> Bus& {
    return *raw->buses.at(
        static_cast<std::size_t>(raw->bus_of_node.at(static_cast<std::size_t>(n))));
  };
  g->actions = std::make_unique<ActionRunner>(
      WorkCountingExecutor(io_.get_executor(), g->action_work), g->image, bus_of);
  g->control = std::make_shared<ControlService>(config, g->image, *g->actions, bus_of);
  for (std::size_t l = 0; l < config->gateway.listener_count(); ++l)
    g->handlers.push_back(make_handler(*g, l));
  return g;
}

// A bus a reload rebuilds (its timing or one of its nodes changed) reopens its link and starts
// every node afresh. A node that is itself unchanged keeps serving what the replaced bus last
// read, with its age, until the new bus has been in touch with it; and it keeps the setpoints the
// PLC wrote unless its configured ones changed.
void Gateway::carry_over(const Generation& previous, const PreviousNodes& previous_nodes,
                         const BusConfig& bus_config, const Bus& bus) {
  const auto images = bus.node_images();
  for (std::size_t i = 0; i < bus_config.nodes.size() && i < images.size(); ++i) {
    const NodeConfig& node = bus_config.nodes[i];
    const auto found = previous_nodes.find(node.name);
    if (found == previous_nodes.end()) continue;
    const auto [index, old] = found->second;
    if (old->identity != node.identity) continue;
    const NodeImage& from = previous.image.node(index);
    NodeImage& to = *images[i];
    if (from.points.size() != to.points.size()) continue;
    to.points = from.points;
    to.counters.last_good = from.counters.last_good;
    to.counters.ever_good = from.counters.ever_good;
    if (old->setpoints == node.setpoints && from.setpoints.size() == to.setpoints.size())
      to.setpoints = from.setpoints;
    to.carried_over = std::any_of(to.points.begin(), to.points.end(),
                                  [](const PointValue& v) { return v.valid; });
  }
}

std::shared_ptr<RegisterMapHandler> Gateway::make_handler(Generation& g, std::size_t listener) {
  return std::make_shared<RegisterMapHandler>(g.config, listener, g.image, *g.actions, *g.control);
}

std::vector<WritePolicy> Gateway::node_policies(const Generation& g) {
  std::vector<WritePolicy> policies;
  for (const auto& bus : g.config->gateway.buses)
    for (const auto& node : bus.nodes) {
      const ModbusConfig& m = g.config->gateway.listener_modbus(node.listener);
      const bool read_only = m.read_only_holding || m.unit_read_only(node.unit_id);
      policies.push_back({!read_only, !read_only && m.writes_enabled});
    }
  return policies;
}

std::shared_ptr<RegisterMapHandler> Gateway::handler_of(const std::shared_ptr<Generation>& g,
                                                        std::size_t listener) {
  return {g, g->handlers.at(listener).get()};
}

std::shared_ptr<ControlService> Gateway::control_of(const std::shared_ptr<Generation>& g) {
  return {g, g->control.get()};
}

std::shared_ptr<modbus::RequestHandler> Gateway::handler(std::string_view listener) const {
  const auto index = current_->config->gateway.find_listener(std::string(listener));
  if (!index) return nullptr;
  return handler_of(current_, *index);
}

modbus::ModbusTcpServerOptions Gateway::server_options(const GatewayConfig& config,
                                                       std::size_t listener) {
  const auto& m = config.listener_modbus(listener);
  modbus::ModbusTcpServerOptions options;
  options.endpoint = asio::ip::tcp::endpoint(asio::ip::make_address(m.address), m.port);
  options.max_clients = m.max_clients;
  options.when_full = m.evict_when_full ? modbus::WhenFull::evict_idle : modbus::WhenFull::refuse;
  options.max_clients_per_address = m.max_clients_per_address;
  options.max_connects_per_second_per_address = m.max_connects_per_second_per_address;
  options.max_connects_per_second = m.max_connects_per_second;
  options.idle_timeout = m.idle_timeout;
  options.request_timeout = m.request_timeout;
  if (!m.allow.empty()) {
    options.allow_client = [allow = m.allow,
                            name = config.listener_name(listener)](const asio::ip::address& peer) {
      const bool allowed = allow.allows(peer);
      if (!allowed)
        log::warning("modbus {}: refused client {} (not in the allow list)", name,
                     peer.to_string());
      return allowed;
    };
  }
  return options;
}

std::shared_ptr<modbus::RequestHandler> Gateway::rtu_handler(const std::shared_ptr<Generation>& g) {
  const auto& rtu = g->config->gateway.modbus_rtu;
  if (!rtu) return nullptr;
  return handler_of(g, rtu->listener);
}

void Gateway::spawn(const std::shared_ptr<Bus>& bus) {
  // The coroutine holds the bus, so a bus dropped by a reload lives until its loop has ended.
  asio::co_spawn(
      io_, [bus]() -> asio::awaitable<void> { co_await bus->run(); }, asio::detached);
}

std::unique_ptr<modbus::ModbusTcpServer> Gateway::open_listener(
    const std::shared_ptr<Generation>& g, std::size_t listener) {
  const auto& config = g->config->gateway;
  auto server = std::make_unique<modbus::ModbusTcpServer>(
      io_.get_executor(), server_options(config, listener), handler_of(g, listener));
  server->start();
  const auto ep = server->local_endpoint();
  if (listener == 0)  // as with a single listener, which scripts and tests look for
    log::notice("modbus: listening on {}:{}", ep.address().to_string(), ep.port());
  else
    log::notice("modbus {}: listening on {}:{} ({} unit(s))", config.listener_name(listener),
                ep.address().to_string(), ep.port(), g->config->map_of(listener).units().size());
  return server;
}

void Gateway::start() {
  for (std::size_t l = 0; l < current_->config->gateway.listener_count(); ++l)
    listeners_.push_back({current_->config->gateway.listener_name(l), open_listener(current_, l)});
  rtu_.apply(*current_->config, rtu_handler(current_));
  start_metrics();
  start_console();
  start_sparkplug();
  for (auto& bus : pending_start_) spawn(bus);
  pending_start_.clear();
}

void Gateway::start_sparkplug() {
  if (sparkplug_) sparkplug_->stop();
  sparkplug_.reset();
  const auto& s = current_->config->gateway.sparkplug;
  if (!s.enabled) return;
  sparkplug_ = std::make_unique<sparkplug::EdgeNode>(io_.get_executor(), s);
  sparkplug_->bind(current_->config, current_->image, control_of(current_),
                   node_policies(*current_));
  sparkplug_->start();
}

const sparkplug::SessionStats* Gateway::sparkplug_stats() const {
  return sparkplug_ ? &sparkplug_->stats() : nullptr;
}

HttpServerCounts Gateway::metrics_http_counts() const {
  return metrics_ ? plus(metrics_before_, metrics_->stats()) : metrics_before_;
}

HttpServerCounts Gateway::console_http_counts() const {
  return console_ ? plus(console_before_, console_->stats()) : console_before_;
}

void Gateway::start_metrics() {
  const auto& m = current_->config->gateway.metrics;
  metrics_before_ = metrics_http_counts();
  if (metrics_) metrics_->stop();
  metrics_.reset();
  if (!m.enabled) return;
  try {
    metrics_ = std::make_unique<MetricsServer>(
        io_.get_executor(), asio::ip::tcp::endpoint(asio::ip::make_address(m.address), m.port),
        [this] { return render_metrics(*this); }, m.allow);
    metrics_->start();
    const auto ep = metrics_->local_endpoint();
    log::notice("metrics: http://{}:{}/metrics", ep.address().to_string(), ep.port());
  } catch (const boost::system::system_error& e) {
    // Metrics are secondary: the gateway keeps serving Modbus without them.
    log::error("metrics: cannot listen on {}:{}: {}", m.address, m.port, e.code().message());
  }
}

void Gateway::start_console() {
  const auto& c = current_->config->gateway.console;
  console_before_ = console_http_counts();
  if (console_) console_->stop();
  console_.reset();
  if (fleet_) fleet_->stop();
  fleet_.reset();
  if (!c.enabled) return;
  try {
    const auto& s = current_->config->gateway.sparkplug;
    // Where the gateway is an edge node, the console shows the whole group it belongs to.
    if (s.enabled) {
      fleet_ = std::make_unique<FleetWatch>(io_.get_executor(), s);
      fleet_->start();
    }
    console_ = std::make_unique<ConsoleServer>(io_.get_executor(), c, [this] {
      return plant_json(*this, std::chrono::steady_clock::now(), std::chrono::system_clock::now(),
                        fleet_.get());
    });
    console_->start();
    const auto ep = console_->local_endpoint();
    const bool v6 = ep.address().is_v6();
    log::notice("console: http://{}{}{}:{}/{}", v6 ? "[" : "", ep.address().to_string(),
                v6 ? "]" : "", ep.port(),
                c.token_sha256.empty() ? "" : " (open it with ?token=... )");
  } catch (const boost::system::system_error& e) {
    // The console is secondary: the gateway keeps serving Modbus without it.
    log::error("console: cannot listen on {}:{}: {}", c.address, c.port, e.code().message());
  }
}

std::string Gateway::apply(std::shared_ptr<const LoadedConfig> config) {
  std::vector<std::shared_ptr<Bus>> fresh;
  auto next = build(std::move(config), current_.get(), fresh);
  std::size_t kept = 0, stopped = 0;
  for (const auto& old : current_->buses) {
    bool still_used = false;
    for (const auto& b : next->buses) still_used = still_used || b == old;
    if (still_used) {
      ++kept;
    } else {
      old->stop();
      ++stopped;
    }
  }
  const std::string listener_summary = apply_listeners(next);
  rtu_.apply(*next->config, rtu_handler(next));
  const auto& old_metrics = current_->config->gateway.metrics;
  const auto& new_metrics = next->config->gateway.metrics;
  const bool metrics_changed = old_metrics.enabled != new_metrics.enabled ||
                               old_metrics.address != new_metrics.address ||
                               old_metrics.port != new_metrics.port;
  retired_.push_back(std::move(current_));
  current_ = next;
  if (metrics_changed) start_metrics();
  // Its allow list or token may have changed; open pages reconnect on their own.
  start_console();
  if (!sparkplug_ || sparkplug_->config() != current_->config->gateway.sparkplug)
    start_sparkplug();
  else
    sparkplug_->bind(current_->config, current_->image, control_of(current_),
                     node_policies(*current_));
  for (auto& bus : fresh) spawn(bus);
  sweep_retired();
  const std::string in_place =
      next->reconfigured == 0
          ? ""
          : fmt::format(" ({} of them with node changes applied in place)", next->reconfigured);
  return fmt::format("{} bus(es) kept running, {} started, {} stopped{}{}", kept, fresh.size(),
                     stopped, in_place, listener_summary);
}

// A listener of the same name keeps its socket and clients (new requests get the new handler);
// one whose address changed is reopened; a new one is opened, a removed one closed.
std::string Gateway::apply_listeners(const std::shared_ptr<Generation>& next) {
  if (listeners_.empty()) return "";  // not started
  const auto& config = next->config->gateway;
  std::vector<Listener> kept;
  std::size_t opened = 0, closed = 0;
  for (std::size_t l = 0; l < config.listener_count(); ++l) {
    const std::string name = config.listener_name(l);
    auto old = std::find_if(listeners_.begin(), listeners_.end(),
                            [&](const Listener& x) { return x.name == name && x.server; });
    if (old != listeners_.end()) {
      old->server->set_handler(handler_of(next, l));
      if (old->server->reconfigure(server_options(config, l))) {
        kept.push_back(std::move(*old));
        continue;
      }
      log::warning(
          "modbus {}: the listen address changed; reopening the listener (clients "
          "reconnect)",
          name);
      old->server->stop();
      old->server.reset();
    }
    try {
      kept.push_back({name, open_listener(next, l)});
      ++opened;
    } catch (const boost::system::system_error& e) {
      const auto& m = config.listener_modbus(l);
      log::error("modbus {}: cannot listen on {}:{}: {}", name, m.address, m.port,
                 e.code().message());
    }
  }
  for (auto& old : listeners_)
    if (old.server) {
      log::notice("modbus {}: listener removed; closing it", old.name);
      old.server->stop();
      ++closed;
    }
  listeners_ = std::move(kept);
  if (opened == 0 && closed == 0) return "";
  return fmt::format("; {} listener(s) opened, {} closed", opened, closed);
}

void Gateway::stop() {
  for (auto& l : listeners_)
    if (l.server) l.server->stop();
  rtu_.stop();
  if (metrics_) metrics_->stop();
  if (console_) console_->stop();
  if (fleet_) fleet_->stop();
  if (sparkplug_) sparkplug_->stop();
  if (current_) {
    for (auto& bus : current_->buses) bus->stop();
    current_->actions->stop();
  }
  for (auto& g : retired_) g->actions->stop();
  sweep_timer_.cancel();
}

bool Gateway::idle(const Generation& g) {
  if (*g.action_work != 0) return false;
  // A profile axis's follow-up runs on the handler that accepted its command and ends, its
  // command left busy, when that handler is freed. Stand-in for a query of the handler
  // (RegisterMapHandler::idle()): no command of the generation's nodes is busy.
  for (std::size_t n = 0; n < g.image.size(); ++n)
    for (const auto& axis : g.image.node(static_cast<int>(n)).profile_axes)
      if (axis.status == CommandStatus::busy) return false;
  return true;
}

void Gateway::sweep_retired() {
  std::erase_if(retired_, [](const std::shared_ptr<Generation>& g) {
    // Ours is the only reference: no request, command or server holds any part of it.
    return g.use_count() == 1 && idle(*g);
  });
  if (retired_.empty()) return;
  sweep_timer_.expires_after(kSweepInterval);
  sweep_timer_.async_wait([this](const boost::system::error_code& ec) {
    if (!ec) sweep_retired();
  });
}

std::string Gateway::status_line() const {
  std::size_t up = 0, online = 0;
  for (const auto& b : current_->buses) up += b->counters().link_up ? 1 : 0;
  const auto& image = current_->image;
  for (std::size_t i = 0; i < image.size(); ++i)
    online += image.node(static_cast<int>(i)).state == NodeState::online ? 1 : 0;
  std::size_t clients = 0;
  for (const auto& l : listeners_)
    if (l.server) clients += l.server->stats().clients_connected;
  return fmt::format("buses up {}/{}, nodes online {}/{}, clients {}", up, current_->buses.size(),
                     online, image.size(), clients);
}

bool Gateway::all_buses_attempted() const {
  for (const auto& b : current_->buses)
    if (!b->counters().open_attempted) return false;
  return true;
}

}  // namespace fieldgate
