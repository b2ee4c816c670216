#include "gateway/bus/serial_bus.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/use_awaitable.hpp>

#include <algorithm>
#include <stdexcept>

#include "drivers/printable_bytes.hpp"
#include "drivers/transport/serial_transport.hpp"
#include "drivers/transport/tcp_transport.hpp"
#include "gateway/bus/node_image_setup.hpp"
#include "gateway/bus/pending_command.hpp"
#include "gateway/bus/reply_accounting.hpp"
#include "gateway/lifecycle/log.hpp"

namespace fieldgate {

namespace {
constexpr auto use_tuple = asio::as_tuple(asio::use_awaitable);
using Clock = std::chrono::steady_clock;
// Rounds of proofs of alignment that failed in a row before the link is reopened.
constexpr int kReopenAfterFailedProofRounds = 5;
// A link that lived less than this (or two probe intervals) before it was reopened was reopened
// because nothing answered on it.
constexpr auto kBriefLink = std::chrono::seconds(60);
constexpr auto kReopenReminder = std::chrono::minutes(10);

std::unique_ptr<ByteTransport> make_transport(asio::any_io_executor ex, const TransportConfig& t) {
  if (t.kind == TransportConfig::Kind::tcp)
    return std::make_unique<TcpTransport>(ex, t.host, t.port, serial_char_time_us(t.serial));
  return std::make_unique<SerialTransport>(ex, t.serial);
}
// A serial bus runs a stream family; the configuration loader pairs `can:` with the frame ones.
ProtocolFamily& stream_family(const BusConfig& config) {
  auto* family = dynamic_cast<ProtocolFamily*>(config.family.get());
  if (!family)
    throw std::invalid_argument(fmt::format(
        "bus {}: protocol {} runs on a CAN bus (can: {{interface: ...}}), not on a byte stream",
        config.name, config.family ? config.family->name() : std::string_view("(none)")));
  return *family;
}

}  // namespace

SerialBus::SerialBus(asio::any_io_executor executor, std::shared_ptr<const void> config_owner,
                     const BusConfig& config, int first_node_index, NodeUpdated on_update)
    : SerialBus(executor, std::move(config_owner), config, first_node_index, std::move(on_update),
                make_transport(executor, config.transport)) {}

SerialBus::SerialBus(asio::any_io_executor executor, std::shared_ptr<const void> config_owner,
                     const BusConfig& config, int first_node_index, NodeUpdated on_update,
                     std::unique_ptr<ByteTransport> transport, TimeSource now)
    : executor_(executor),
      now_(now ? std::move(now) : TimeSource([] { return Clock::now(); })),
      config_owners_(config_owner),
      config_(&config),
      family_(stream_family(config)),
      first_node_index_(first_node_index),
      on_update_(std::move(on_update)),
      transport_(std::move(transport)),
      link_(*transport_),
      wake_(executor),
      trace_(config.name, config.trace) {
  link_.set_tap([this](bool tx, std::string_view bytes) {
    if (!trace_.active()) return;
    if (trace_collecting_) {
      traced_.push_back({link_.tap_time(), tx, std::string(bytes), {}});
      return;
    }
    // Outside a transaction: link-open procedures, urgent commands, discarded input.
    trace_.emit(link_.tap_time(), {}, tx ? TraceDirection::tx : TraceDirection::rx, {},
                printable_bytes(bytes));
  });
  link_.set_label_tap([this](std::string_view label) {
    if (trace_collecting_ && !traced_.empty()) traced_.back().label = label;
  });
  int index = 0;  // local: position on this bus; the gateway's number is first_node_index_ + index
  for (const auto& n : config.nodes) nodes_.push_back(bind(n, index++, config_owner));
  plan_polls();
}

std::shared_ptr<SerialBus::NodeRuntime> SerialBus::bind(const NodeConfig& node, int index,
                                                        std::shared_ptr<const void> owner) {
  auto rt = std::make_shared<NodeRuntime>();
  rt->bound_owner = std::move(owner);
  rt->index = index;
  rt->config = &node;
  rt->timing = node_link_timing(*config_, node);
  rt->family_context = family_.bind_node(node.address, *node.model);
  rt->image = make_node_image(node);
  return rt;
}

void SerialBus::plan_polls() {
  plan_ = PollPlan{};
  ++plan_number_;
  for (auto& rt : nodes_) {
    const NodeConfig& n = *rt->config;
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
        item.node = rt->index;
        item.request = Request{command, Request::Expect::values, point.read->format};
        item.request.compiled = point.read->request.compiled();  // where the family compiles reads
        item.period = period;
        items.push_back(std::move(item));
        existing = std::prev(items.end());
      }
      existing->targets.push_back({static_cast<int>(p), point.read->field});
    }
    rt->poll_items = static_cast<int>(items.size());
    // Before the items move into the plan: the data age covers the polled points.
    auto& polled = rt->image->polled;
    polled.assign(n.model->points.size(), false);
    for (const auto& it : items)
      for (const auto& t : it.targets) polled[static_cast<std::size_t>(t.point)] = true;
    for (auto& it : items) plan_.add(std::move(it));
    plan_.set_eligible(rt->index, rt->image->state != NodeState::offline);
  }
}

bool SerialBus::reconfigure(std::shared_ptr<const void> config_owner, const BusConfig& config,
                            int first_node_index, NodeUpdated on_update) {
  if (config.name != config_->name || config.link_signature != config_->link_signature)
    return false;
  std::vector<std::shared_ptr<NodeRuntime>> next;
  std::size_t kept = 0;
  for (const auto& n : config.nodes) {
    const auto same = std::find_if(nodes_.begin(), nodes_.end(),
                                   [&](const auto& rt) { return rt->config->name == n.name; });
    if (same != nodes_.end() && (*same)->config->identity != n.identity) return false;
    next.push_back(same != nodes_.end() ? *same : nullptr);
    kept += same != nodes_.end() ? 1 : 0;
  }
  if (kept != nodes_.size()) return false;  // a node was taken away

  config_owners_.push(config_owner);
  config_ = &config;
  std::vector<int> moved_to(nodes_.size());
  for (std::size_t i = 0; i < next.size(); ++i) {
    const NodeConfig& n = config.nodes[i];
    const int index = static_cast<int>(i);
    if (!next[i]) {
      next[i] = bind(n, index, config_owner);
      log::notice("bus {}: node {} ({}) added", config.name, n.name, n.address.text);
      continue;
    }
    auto& rt = *next[i];
    moved_to[static_cast<std::size_t>(rt.index)] = index;
    apply_setpoint_changes(*rt.image, *rt.config, n);
    rt.index = index;
    rt.config = &n;
    rt.timing = node_link_timing(config, n);
  }
  for (auto& cmd : commands_) cmd->node = moved_to[static_cast<std::size_t>(cmd->node)];
  last_command_node_ = -1;
  nodes_ = std::move(next);
  const PollPlan previous = std::move(plan_);
  plan_polls();
  plan_.start_after(previous, moved_to, now_());
  ++numbering_;
  first_node_index_ = first_node_index;
  on_update_ = std::move(on_update);
  return true;
}

SerialBus::~SerialBus() = default;

bool SerialBus::owns_node(int node_index) const {
  return node_index >= first_node_index_ &&
         node_index < first_node_index_ + static_cast<int>(nodes_.size());
}

const NodeConfig& SerialBus::node_config(int node_index) const {
  return *nodes_.at(static_cast<std::size_t>(node_index - first_node_index_))->config;
}

SerialBus::NodeRuntime& SerialBus::node(int node_index) {
  return *nodes_.at(static_cast<std::size_t>(node_index - first_node_index_));
}

std::vector<std::shared_ptr<NodeImage>> SerialBus::node_images() const {
  std::vector<std::shared_ptr<NodeImage>> images;
  for (const auto& n : nodes_) images.push_back(n->image);
  return images;
}

void SerialBus::rebind(int first_node_index, NodeUpdated on_update) {
  ++numbering_;
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
    if (options.on_sent) options.on_sent();
    co_return co_await family_.send_urgent(link_, n.config->address, request);
  }
  // A bus-wide command (a global stop) concerns every node: only the link must be up.
  const bool node_gone = (*n.image).state == NodeState::offline && !request.bus_wide;
  if (node_gone || !transport_->is_open())
    co_return Reply::of(Reply::Status::unreachable,
                        transport_->is_open() ? "node is offline" : "bus link is down");
  auto cmd = std::make_shared<PendingCommand>(executor_);
  cmd->node = n.index;  // local, so a reload that renumbers the gateway's nodes cannot misroute it
  cmd->request = std::move(request);
  cmd->options = options;
  cmd->queued_at = now_();
  commands_.push_back(cmd);
  wake_.cancel();
  co_return co_await cmd->reply();
}

std::shared_ptr<PendingCommand> SerialBus::take_command() {
  // A bus-wide command (a global stop) first; otherwise round-robin over nodes, in order of
  // arrival within a node, so one unit flooded with writes does not delay the others' commands.
  auto pick = commands_.begin();
  const auto bus_wide = std::find_if(commands_.begin(), commands_.end(),
                                     [](const auto& c) { return c->request.bus_wide; });
  if (bus_wide != commands_.end()) {
    pick = bus_wide;
  } else {
    const int count = static_cast<int>(nodes_.size());
    int best = count + 1;
    for (auto it = commands_.begin(); it != commands_.end(); ++it) {
      const int distance = ((*it)->node - last_command_node_ - 1 + count) % count;
      if (distance < best) {
        best = distance;
        pick = it;
      }
    }
  }
  auto cmd = *pick;
  commands_.erase(pick);
  last_command_node_ = cmd->node;
  return cmd;
}

void SerialBus::set_state(NodeRuntime& n, NodeState state, std::string_view why) {
  auto& img = (*n.image);
  if (img.state == state) return;
  const auto old = img.state;
  img.state = state;
  plan_.set_eligible(n.index, state != NodeState::offline);
  if (state == NodeState::online) {
    log::notice("bus {}: node {} ({}) online{}", config_->name, n.config->name,
                n.config->address.text, old == NodeState::offline ? " again" : "");
    // Back from offline, its items resume in their slots. A node starting (or faulted) was
    // polled on its schedule all along, and the poll answering now completes its own item: a
    // restart before that completion would move the item a period on twice.
    if (old == NodeState::offline) plan_.restart_node(n.index, now_());
  } else if (state == NodeState::offline) {
    log::warning("bus {}: node {} ({}) offline: {}", config_->name, n.config->name,
                 n.config->address.text, why);
    n.next_probe = now_() + config_->timing.probe_interval;
  } else if (state == NodeState::faulted) {
    log::warning("bus {}: node {} ({}) faulted: it answers but refuses every poll ({})",
                 config_->name, n.config->name, n.config->address.text, why);
  }
}

bool SerialBus::all_nodes_offline_now() const {
  for (const auto& n : nodes_)
    if (n->image->state != NodeState::offline) return false;
  return true;
}

void SerialBus::all_nodes_offline(std::string_view why) {
  for (auto& n : nodes_) set_state(*n, NodeState::offline, why);
}

void SerialBus::record(NodeRuntime& n, const Reply& reply, bool poll) {
  auto& c = (*n.image).counters;
  switch (count_reply(c, counters_, reply, now_())) {
    case ReplyOutcome::answered:
      if (reply.status == Reply::Status::ok) {
        if (poll) n.refused_polls = 0;
        if (poll || (*n.image).state != NodeState::faulted) set_state(n, NodeState::online, {});
      } else if (poll) {
        // The node answers but refuses this poll. Refusing every poll of a round (a wrong axis
        // letter, a model that does not fit) means none of its values is ever fresh: faulted.
        ++n.refused_polls;
        if (n.refused_polls >= n.poll_items || (*n.image).state == NodeState::offline)
          set_state(n, NodeState::faulted, reply.text);
      }
      break;
    case ReplyOutcome::garbled:
      break;
    case ReplyOutcome::failed:
      if (c.consecutive_timeouts >= static_cast<uint32_t>(config_->timing.offline_after) ||
          (*n.image).state == NodeState::offline)
        // Named apart: a forwarding device's "node unreachable" (Copley e 32) is not silence.
        set_state(n, NodeState::offline,
                  reply.status == Reply::Status::unreachable
                      ? fmt::format("unreachable ({})", reply.text)
                      : fmt::format("{}, no reply", to_string(reply.status)));
      break;
  }
}

asio::awaitable<Reply> SerialBus::transact(NodeRuntime& n, const Request& request, int retries,
                                           bool accept_no_reply, bool poll, bool sent_ahead) {
  Reply reply;
  if (sent_ahead && (!aligned_ || !link_.has_sent_ahead())) {
    abandon_sent_ahead();
    sent_ahead = false;
  }
  if (!aligned_) co_await prove_aligned(n, true);
  if (!aligned_ && transport_->is_open()) {
    // Nothing is sent while the line is out of step: its reply could not be told from a late one.
    // Not the node's failure (the failed proofs are counted against the nodes they went to):
    // its values just age.
    reply = Reply::of(Reply::Status::unreachable,
                      "line not in step (no proof of alignment passed), not sent");
    co_return reply;
  }
  for (int attempt = 0; attempt <= retries; ++attempt) {
    if (attempt > 0) {
      ++counters_.retries;
      ++(*n.image).counters.retries;
    }
    const bool taking_over = attempt == 0 && sent_ahead;
    const auto started = taking_over ? link_.sent_ahead_at() : Clock::now();
    const auto received_before = link_.stats().bytes_received;
    collect_trace(true);
    if (taking_over) link_.take_over_sent_ahead();
    reply = co_await family_.transact_node(link_, *n.family_context, request, n.timing);
    if (taking_over && (link_.take_ahead_mismatch() || link_.has_sent_ahead())) {
      // The family's exchange was not the one its request was sent ahead for: a family whose
      // pipelined_request() does not match its transact_node().
      log::error(
          "bus {}: node {} ({}): '{}' was sent ahead, but the exchange {}; its reply is "
          "owed and the line is proven in step again",
          config_->name, n.config->name, n.config->address.text, request.command,
          link_.has_sent_ahead() ? "did not take it over" : "sent other bytes");
      if (link_.has_sent_ahead()) link_.drop_sent_ahead();
      ++counters_.sent_ahead_lost;
      debt_.add();
      reply = Reply::of(Reply::Status::garbled, "request sent ahead was not the exchange's own");
    }
    if (armed_ && reply.status == Reply::Status::ok) send_armed_poll();
    collect_trace(false);
    // The trace's outcome names (docs/wire-trace.md), as CAN buses give them.
    trace_transaction(n,
                      reply.status == Reply::Status::garbled ? "garbled" : to_string(reply.status));
    record_latency(std::chrono::duration<double>(Clock::now() - started).count());
    log_notes(false);
    ++counters_.transactions;
    ++(*n.image).counters.transactions;
    if (reply.controller_reset) {
      // Every command that ran on the controller before is lost (ActionRunner, the profile).
      ++(*n.image).controller_resets;
      log::warning("bus {}: node {} ({}): the controller reset (found in its power-up state)",
                   config_->name, n.config->name, n.config->address.text);
    }
    if (link_.buffered() > 0 && reply.status != Reply::Status::timeout &&
        reply.status != Reply::Status::link_down) {
      // Bytes behind a reply: the line was in step before this exchange, so something else is
      // talking or the device answered twice, and the reply itself may be the stray one.
      reply = Reply::of(Reply::Status::garbled, fmt::format("stray bytes followed the reply ({})",
                                                            to_string(reply.status)));
    }
    if (reply.status == Reply::Status::ok || reply.status == Reply::Status::device_error)
      last_answered_ = &n;
    // A request that got no reply at all may still be answered.
    const bool heard = link_.stats().bytes_received != received_before;
    if (reply.status == Reply::Status::timeout && !heard) debt_.add();
    if (reply.status == Reply::Status::timeout || reply.status == Reply::Status::garbled)
      co_await resync(n, reply, heard);
    if (!aligned_ && !(accept_no_reply && reply.status == Reply::Status::timeout))
      break;  // no retry on a line out of step
    if (accept_no_reply && reply.status == Reply::Status::timeout) {
      reply.status = Reply::Status::ok;
      break;
    }
    if (reply.status == Reply::Status::link_down) break;
    if (reply.status != Reply::Status::timeout && reply.status != Reply::Status::garbled) break;
    if (attempt < retries) record(n, reply, poll);
  }
  record(n, reply, poll);
  if (reply.status == Reply::Status::link_down) {
    log::error("bus {}: link failed: {}", config_->name, reply.text);
    transport_->close();
  }
  co_await link_.pause(config_->timing.inter_frame_gap);
  co_return reply;
}

void SerialBus::log_notes(bool quiet) {
  for (auto& note : link_.take_notes()) {
    const int level = quiet && note.level >= 5 ? 7 : std::clamp(note.level, 3, 7);
    if (log::enabled(static_cast<log::Level>(level)))
      log::write(static_cast<log::Level>(level),
                 fmt::format("bus {}: {}", config_->name, note.text));
  }
}

void SerialBus::collect_trace(bool on) {
  trace_collecting_ = on && trace_.active();
  link_.want_labels(trace_collecting_);
}

void SerialBus::trace_transaction(const NodeRuntime& n, std::string_view outcome) {
  for (const auto& t : traced_)
    trace_.emit(t.at, n.config->name, t.tx ? TraceDirection::tx : TraceDirection::rx, outcome,
                printable_bytes(t.bytes), t.label);
  traced_.clear();
}

asio::awaitable<void> SerialBus::resync(NodeRuntime& n, const Reply& failed, bool heard) {
  if (!transport_->is_open()) co_return;
  collect_trace(true);
  const auto found = co_await family_.resync_after_failure(link_, n.timing);
  drained_before_proof_ += found.drained;
  collect_trace(false);
  trace_transaction(n, "resync");
  ++counters_.resyncs;
  counters_.resync_bytes += found.drained.size();
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(found.waited).count();
  const char* after = failed.status == Reply::Status::ok ? "stray bytes after a reply"
                                                         : to_string(failed.status).data();
  // Said so that a newcomer reading a start-up on a loaded machine sees a handled event, not a
  // broken link.
  if (!found.drained.empty())
    log::warning(
        "bus {}: resync after {} from node {} ({}): drained {} byte(s) '{}' in {} ms (a reply "
        "late, cut or corrupted on the line; none of it is used, and the line is proven in step "
        "before a reply is trusted again)",
        config_->name, after, n.config->name, n.config->address.text, found.drained.size(),
        printable_bytes(found.drained, 80), ms);
  else
    log::debug("bus {}: resync after {} from node {} ({}): line quiet after {} ms", config_->name,
               after, n.config->name, n.config->address.text, ms);
  if (!found.quiet) {
    // A line that never goes quiet cannot carry an untagged exchange: reopen it.
    log::error("bus {}: line still busy {} ms after the {} from node {}; reopening the link",
               config_->name, ms, after, n.config->name);
    transport_->close();
    aligned_ = false;
    co_return;
  }
  co_await prove_aligned(n, heard || !found.drained.empty());
}

asio::awaitable<void> SerialBus::prove_aligned(NodeRuntime& failed, bool heard) {
  if (!transport_->is_open()) {
    aligned_ = false;
    co_return;
  }
  // Nodes that have answered (online, or faulted: answering but refusing polls) come first: the
  // failed one if it sent something (in step again, its own backlog is through), then the one
  // that answered last, then the others. Then nodes not heard from yet, then a failed node that
  // fell silent (it may be gone), offline ones last: a proof addressed to an absent node only
  // times out, and its unanswered requests would be owed on the line.
  std::vector<NodeRuntime*> candidates;
  const auto add = [&](NodeRuntime* n) {
    if (n && std::find(candidates.begin(), candidates.end(), n) == candidates.end())
      candidates.push_back(n);
  };
  const auto answering = [](const NodeRuntime* n) {
    return n && (n->image->state == NodeState::online || n->image->state == NodeState::faulted);
  };
  if (heard && answering(&failed)) add(&failed);
  if (answering(last_answered_) && (heard || last_answered_ != &failed)) add(last_answered_);
  for (auto& n : nodes_)
    if (answering(n.get()) && (heard || n.get() != &failed)) add(n.get());
  for (auto& n : nodes_)
    if (n->image->state == NodeState::starting && (heard || n.get() != &failed)) add(n.get());
  add(&failed);
  for (auto& n : nodes_) add(n.get());
  // Attempts are bounded per call, so a command queued behind a proof on a bad line waits for a
  // few reply timeouts, not for every node's attempts: a Modbus client's own timeout is near.
  int attempts_left = kProofAttemptsPerCall;
  std::string why;
  for (auto* n : candidates) {
    if (attempts_left <= 0) break;
    auto proof = family_.alignment_proof(*n->family_context, n->timing);
    if (!proof) {
      aligned_ = true;  // the family's replies prove themselves
      debt_.clear();
      drained_before_proof_.clear();
      co_return;
    }
    ++counters_.alignment_proofs;
    // Whole replies drained while the line went quiet were owed ones arriving.
    debt_.settle(drained_before_proof_, proof->steps.front().splitter);
    drained_before_proof_.clear();
    collect_trace(true);
    const auto guard = guard_time(n->timing, link_.char_time_us());
    // A node that has not answered gets one attempt: it may be absent, and others may prove it.
    const int attempts = std::min(attempts_left, answering(n) ? 2 : 1);
    // The proof does not rely on its timeout (its answers are known and counted): twice the
    // node's, so a device slowed for a moment (a loaded host, a busy unit) is not taken for a
    // line out of step and its commands refused.
    LinkTiming patient = n->timing;
    patient.reply_timeout *= 2;
    const auto result = co_await prove_alignment(link_, *proof, patient, guard, attempts, debt_);
    log_notes(false);
    collect_trace(false);
    attempts_left -= std::max(result.attempts, 1);
    trace_transaction(*n, result.proved ? "proof" : "proof_failed");
    counters_.stray_replies += result.strays.size();
    if (!result.strays.empty()) {
      std::string strays;
      for (std::size_t i = 0; i < result.strays.size() && i < 4; ++i)
        strays += (i ? ", '" : "'") + printable_bytes(result.strays[i], 40) + "'";
      if (result.strays.size() > 4) strays += ", ...";
      log::warning("bus {}: drained {} late or stray repl{} ({}) while proving the line in step",
                   config_->name, result.strays.size(), result.strays.size() == 1 ? "y" : "ies",
                   strays);
    }
    if (!transport_->is_open()) break;
    // One lost reply is what every poll of an absent node leaves: not worth a warning each time.
    if (result.lost > 0)
      log::write(
          result.lost > 1 ? log::Level::warning : log::Level::debug,
          fmt::format("bus {}: {} repl{} never came and {} taken as lost (the device did not hear "
                      "the request)",
                      config_->name, result.lost, result.lost == 1 ? "y" : "ies",
                      result.lost == 1 ? "is" : "are"));
    // Each attempt the node did not answer as it must is an exchange that failed with it, even
    // when a later attempt proves the line: a garbled echo is counted wherever it lands.
    for (const auto& failure : result.failures) {
      if (failure.end == AttemptEnd::clean_but_owing || failure.end == AttemptEnd::not_sent)
        continue;
      record(*n,
             Reply::of(failure.end == AttemptEnd::no_reply ? Reply::Status::timeout
                                                           : Reply::Status::garbled,
                       "proof of alignment failed: " + failure.why),
             false);
    }
    if (result.proved) {
      if (!aligned_ || alignment_failure_logged_)
        log::info("bus {}: line in step again ({}, {} attempt(s))", config_->name, proof->name,
                  result.attempts);
      aligned_ = true;
      alignment_failure_logged_ = false;
      failed_proof_rounds_ = 0;
      debt_.clear();
      co_return;
    }
    ++counters_.alignment_failures;
    why = fmt::format("node {}: {}", n->config->name, result.why);
    // The failed attempts were recorded above against the node they went to, so a line that is
    // never proved takes its nodes offline rather than leaving them online with aging values.
    if (result.never_quiet) break;
  }
  aligned_ = false;
  if (++failed_proof_rounds_ >= kReopenAfterFailedProofRounds && transport_->is_open()) {
    // A device that re-powered while the line stayed open is back in its power-up settings (an
    // echo the start-up had switched off): only the family's start-up, run when the link
    // opens, brings it back.
    log::error(
        "bus {}: the line could not be proven in step in {} rounds ({}); reopening the "
        "link, so that the start-up runs again",
        config_->name, failed_proof_rounds_, why);
    failed_proof_rounds_ = 0;
    transport_->close();
  }
  // Nothing is sent before a later proof passes. A command that has already waited through
  // proofs learns it now, rather than after the proofs of the polls ahead of it: a Modbus
  // client's timeout is near. A newer one keeps its place and gets a proof of its own.
  const auto now = now_();
  std::erase_if(commands_, [&](const std::shared_ptr<PendingCommand>& cmd) {
    if (now - cmd->queued_at < kCommandPatience) return false;
    cmd->answer(Reply::of(Reply::Status::unreachable,
                          "line not in step (no proof of alignment passed), not sent"));
    return true;
  });
  if (!alignment_failure_logged_)
    log::warning(
        "bus {}: cannot prove the line in step ({}); no reply is trusted and nothing is "
        "sent until a proof passes",
        config_->name, why);
  alignment_failure_logged_ = true;
}

void SerialBus::record_latency(double seconds) {
  count_latency(counters_, seconds);
  counters_.bytes_sent = link_.stats().bytes_sent;
  counters_.bytes_received = link_.stats().bytes_received;
}

BusTurnInput SerialBus::turn_input(SteadyTime now, std::optional<PollPlan::Due> due) const {
  BusTurnInput in;
  in.now = now;
  in.commands_queued = !commands_.empty();
  if (due) in.poll = BusTurnInput::Poll{due->item, due->when, plan_.items()[due->item].period};
  for (const auto& n : nodes_) {
    if (n->image->state != NodeState::offline) continue;
    if (!in.probe || n->next_probe < in.probe->when)
      if (auto item = plan_.probe_item(n->index))
        in.probe = BusTurnInput::Poll{*item, n->next_probe, plan_.items()[*item].period};
  }
  in.commands_in_row = commands_in_row_;
  in.command_credit = command_credit_;
  in.all_nodes_offline = all_nodes_offline_now();
  in.link_opened = opened_at_;
  in.probe_interval = config_->timing.probe_interval;
  return in;
}

void SerialBus::arm_next_poll(std::size_t current) {
  armed_.reset();
  if (!commands_.empty() || !aligned_ || config_->timing.inter_frame_gap.count() > 0) return;
  const auto now = now_();
  const auto due = plan_.pick_after(current, now);
  if (!due) return;
  auto in = turn_input(now, due);
  in.commands_in_row = 0;  // as after the poll under way
  const BusTurn turn = next_bus_turn(in);
  if (turn.kind != BusTurn::Kind::poll) return;
  const auto& item = plan_.item(turn.item);
  const auto& node = nodes_[static_cast<std::size_t>(item.node)];
  if (node->image->state == NodeState::offline) return;  // a probe is not sent ahead
  auto bytes = family_.pipelined_request(*node->family_context, item.request);
  if (!bytes) return;
  armed_ = PollAhead{node, turn.item, plan_number_, std::move(*bytes)};
}

void SerialBus::send_armed_poll() {
  auto armed = std::exchange(armed_, std::nullopt);
  // The reply just taken proved the line in step; a command that came meanwhile goes first.
  if (!commands_.empty() || !aligned_ || stopping_ || link_.buffered() > 0 ||
      armed->plan != plan_number_ || armed->node->image->state == NodeState::offline ||
      !transport_->is_open())
    return;
  if (!link_.send_ahead(armed->bytes)) return;
  ++counters_.sent_ahead;
  ahead_ = std::move(armed);
}

void SerialBus::abandon_sent_ahead() {
  ahead_.reset();
  if (!link_.has_sent_ahead()) return;
  link_.drop_sent_ahead();
  ++counters_.sent_ahead_lost;
  debt_.add();
  aligned_ = false;
}

asio::awaitable<void> SerialBus::run_poll(std::size_t item_index, bool sent_ahead) {
  auto& item = plan_.item(item_index);
  const auto runtime = nodes_[static_cast<std::size_t>(item.node)];
  auto& n = *runtime;
  const auto plan = plan_number_;
  const bool probing = (*n.image).state == NodeState::offline;
  const Request request = item.request;
  const auto targets = item.targets;
  if (!probing) arm_next_poll(item_index);
  Reply reply =
      co_await transact(n, request, probing ? 0 : config_->timing.retries, false, true, sent_ahead);
  armed_.reset();
  const auto now = now_();
  if (probing) {
    n.next_probe = now + config_->timing.probe_interval;
  } else if (plan == plan_number_) {
    plan_.completed(item_index, now);
  }
  auto& img = (*n.image);
  std::vector<int> failed;
  if (reply.status != Reply::Status::ok) {
    // A probe of an offline node is not a poll: the node's state already says its values are old.
    if (!probing)
      for (const auto& t : targets) failed.push_back(t.point);
  } else {
    for (const auto& t : targets) {
      if (t.field >= static_cast<int>(reply.values.size())) {
        ++img.counters.errors;
        img.counters.last_error_text = "reply has fewer values than the model expects";
        failed.push_back(t.point);
        continue;
      }
      store_polled_value(img.points[static_cast<std::size_t>(t.point)],
                         reply.values[static_cast<std::size_t>(t.field)], now);
    }
  }
  for (const int p : failed) {
    auto& point = img.points[static_cast<std::size_t>(p)];
    ++point.failed_polls;
    ++point.failed_polls_total;
  }
  if (!failed.empty()) {
    ++img.counters.failed_polls;
    n.failure_report.failed(failed,
                            reply.status == Reply::Status::ok
                                ? "reply has fewer values than the model expects"
                                : fmt::format("{}: {}", to_string(reply.status), reply.text));
  }
  if (const auto line =
          n.failure_report.due(config_->name, n.config->name, img, *n.config->model, now))
    log::write(line->level, line->text);
  if (reply.status != Reply::Status::ok) co_return;
  if (on_update_) on_update_(first_node_index_ + n.index);
}

asio::awaitable<void> SerialBus::open_link() {
  // What was sent ahead on the closed port is gone with it (debt_ is cleared once it opens).
  armed_.reset();
  ahead_.reset();
  link_.drop_sent_ahead();
  auto delay = config_->timing.reconnect_min;
  while (!stopping_) {
    const auto ec = co_await transport_->open();
    counters_.open_attempted = true;
    if (!ec) {
      counters_.link_up = true;
      const auto now = now_();
      // A link reopened soon after its last opening, with no failure to open in between: the
      // periodic reopen of a line where nothing answers. Once per kReopenReminder, not each time.
      const bool churn = counters_.reconnects > 0 && !link_error_logged_ &&
                         now - opened_at_ < std::max<Clock::duration>(
                                                kBriefLink, 2 * config_->timing.probe_interval);
      const bool remind = churn && now - open_noticed_at_ >= kReopenReminder;
      opened_at_ = now;
      ++counters_.reconnects;
      quiet_reopens_ = churn ? quiet_reopens_ + 1 : 0;
      const auto level = churn && !remind ? log::Level::debug : log::Level::notice;
      if (log::enabled(level))
        log::write(level, remind ? fmt::format("bus {}: reopened {} {} time(s): nothing answers "
                                               "(reminded every {} min)",
                                               config_->name, transport_->describe(),
                                               quiet_reopens_, kReopenReminder.count())
                                 : fmt::format("bus {}: opened {}", config_->name,
                                               transport_->describe()));
      if (level == log::Level::notice) open_noticed_at_ = now;
      link_error_logged_ = false;
      // A reopened port starts with nothing owed (what the old one was owed is discarded).
      debt_.clear();
      drained_before_proof_.clear();
      co_await family_.on_link_open(link_, config_->timing.link);
      log_notes(level == log::Level::debug);
      for (auto& n : nodes_)
        if (n->image->state == NodeState::offline) n->next_probe = now_();
      co_return;
    }
    counters_.link_up = false;
    if (!link_error_logged_) {
      log::error(
          "bus {}: cannot open {}: {} (retrying with back-off up to {} s)", config_->name,
          transport_->describe(), ec.message(),
          std::chrono::duration_cast<std::chrono::seconds>(config_->timing.reconnect_max).count());
      link_error_logged_ = true;
    }
    all_nodes_offline("bus link is down");
    while (!commands_.empty()) {
      commands_.front()->answer(Reply::of(Reply::Status::unreachable, "bus link is down"));
      commands_.pop_front();
    }
    wake_.expires_after(delay);
    co_await wake_.async_wait(use_tuple);
    delay = std::min(delay * 2, config_->timing.reconnect_max);
  }
}

asio::awaitable<void> SerialBus::run() {
  plan_.start(now_());
  while (!stopping_) {
    if (!transport_->is_open()) {
      counters_.link_up = false;
      co_await open_link();
      continue;
    }
    if (ahead_) {
      // Its request is on the line: nothing else may go before its exchange.
      const auto ahead = *std::exchange(ahead_, std::nullopt);
      commands_in_row_ = 0;
      command_credit_ = command_credit_after(command_credit_, BusTurn::Kind::poll);
      if (ahead.plan == plan_number_) {
        co_await run_poll(ahead.item, true);
      } else {
        abandon_sent_ahead();  // a reload renumbered the plan under it
      }
      continue;
    }
    const auto now = now_();
    // The next poll: a due item of a node that is not offline (rate-monotonic, see PollPlan),
    // or the probe of an offline node, whichever is due first.
    const BusTurn turn = next_bus_turn(turn_input(now, plan_.pick(now)));
    command_credit_ = command_credit_after(command_credit_, turn.kind);
    if (turn.kind == BusTurn::Kind::command) {
      auto cmd = take_command();
      ++commands_in_row_;
      ++counters_.commands;
      const auto runtime = nodes_[static_cast<std::size_t>(cmd->node)];
      auto& n = *runtime;
      Reply reply;
      if ((*n.image).state == NodeState::offline && !cmd->request.bus_wide) {
        reply = Reply::of(Reply::Status::unreachable, "node is offline");
      } else {
        // Commands are not retried: a lost reply may hide a command the device already ran.
        if (cmd->options.on_sent) cmd->options.on_sent();
        reply = co_await transact(n, cmd->request, 0, cmd->options.accept_no_reply, false);
        if (reply.status == Reply::Status::timeout || reply.status == Reply::Status::garbled) {
          ++(*n.image).counters.unknown_writes;
          log::warning("bus {}: node {} ({}): '{}' got {}: outcome unknown, not retried",
                       config_->name, n.config->name, n.config->address.text, cmd->request.command,
                       reply.text.empty() ? std::string(to_string(reply.status)) : reply.text);
          reply.text = "no reply, outcome unknown (" +
                       (reply.text.empty() ? std::string(to_string(reply.status)) : reply.text) +
                       ")";
        }
      }
      cmd->answer(std::move(reply));
      continue;
    }
    commands_in_row_ = 0;
    if (turn.kind == BusTurn::Kind::reopen_link) {
      transport_->close();
      continue;
    }
    if (turn.kind == BusTurn::Kind::poll) {
      co_await run_poll(turn.item);
      continue;
    }
    // The sleep runs on the steady clock for as long as the time source says is left.
    if (turn.until == SteadyTime::max())
      wake_.expires_at(SteadyTime::max());
    else
      wake_.expires_after(turn.until - now_());
    co_await wake_.async_wait(use_tuple);
  }
  while (!commands_.empty()) {
    commands_.front()->abandon();
    commands_.pop_front();
  }
}

}  // namespace fieldgate
