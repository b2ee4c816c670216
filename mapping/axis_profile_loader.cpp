#include "mapping/axis_profile_loader.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <set>

namespace fieldgate {

namespace {

constexpr std::array<StatusBit, 7> kMappedBits = {
    StatusBit::enabled,        StatusBit::homed,          StatusBit::moving, StatusBit::error,
    StatusBit::limit_positive, StatusBit::limit_negative, StatusBit::warning};

class ProfileParser {
 public:
  ProfileParser(YamlReader& reader, Model& model) : r_(reader), model_(model) {}

  void parse(const YAML::Node& node) {
    if (!r_.expect_map(node, "axis_profile")) return;
    std::set<std::string> seen;
    for (const auto& e : node) {
      const std::string name = e.first.Scalar();
      if (!seen.insert(name).second) {
        r_.error(e.first, fmt::format("axis_profile: axis '{}' is defined twice", name));
        continue;
      }
      if (auto axis = parse_axis(name, e.second)) {
        model_.profile_axes.push_back(std::move(*axis));
        commands_of_.push_back(e.second["commands"]);
      }
    }
    check_shared_setpoints();
  }

 private:
  bool polled_point(const YAML::Node& n, const std::string& name, const std::string& where) {
    const PointDef* p = model_.find_point(name);
    if (!p) {
      r_.error(n, fmt::format("{}: unknown point '{}'", where, name));
      return false;
    }
    if (!p->readable() || p->poll_class.empty()) {
      r_.error(n, fmt::format("{}: point '{}' is not polled", where, name));
      return false;
    }
    return true;
  }

  std::optional<StatusSource> parse_source(const YAML::Node& n, const std::string& where) {
    StatusSource s;
    s.mark = r_.mark(n);
    if (n.IsScalar()) {
      if (auto b = r_.boolean(n, where)) {
        s.constant = *b;
        return s;
      }
      return std::nullopt;
    }
    if (!r_.expect_map(n, where)) return std::nullopt;
    r_.reject_unknown_keys(n, {"point", "bit", "equals", "not_equals"}, where);
    const auto p = r_.require(n, "point", where);
    if (!p) return std::nullopt;
    s.point = r_.string(*p, where + " point").value_or("");
    if (!polled_point(*p, s.point, where)) return std::nullopt;
    const PointDef* point = model_.find_point(s.point);
    if (const auto bit = n["bit"]) {
      if (auto v = parse_integer_text(bit.Scalar()); v && *v >= 0 && *v <= 31) {
        s.bit = static_cast<int>(*v);
      } else if (const auto* b = point->find_bit(bit.Scalar())) {
        s.bit = b->bit;
      } else {
        r_.error(bit, fmt::format("{}: point '{}' has no bit '{}'", where, s.point, bit.Scalar()));
        return std::nullopt;
      }
    }
    if (n["equals"] && n["not_equals"]) {
      r_.error(n, fmt::format("{}: give 'equals' or 'not_equals', not both", where));
      return std::nullopt;
    }
    if (n["equals"])
      s.value = r_.integer(n["equals"], where + " equals", INT64_MIN, INT64_MAX).value_or(1);
    if (n["not_equals"]) {
      s.value =
          r_.integer(n["not_equals"], where + " not_equals", INT64_MIN, INT64_MAX).value_or(0);
      s.negate = true;
    }
    return s;
  }

  bool known_setpoint(const YAML::Node& n, const std::string& name, const std::string& where) {
    if (model_.find_setpoint(name)) return true;
    r_.error(n, fmt::format("{}: model {} has no setpoint '{}'", where, model_.name, name));
    return false;
  }

  bool known_action(const YAML::Node& n, const std::string& name, const std::string& where) {
    if (model_.find_action(name)) return true;
    r_.error(n, fmt::format("{}: model {} has no action '{}'", where, model_.name, name));
    return false;
  }

  std::optional<ProfileAxisDef> parse_axis(const std::string& name, const YAML::Node& n) {
    const std::string where = "axis_profile " + name;
    if (!r_.expect_map(n, where)) return std::nullopt;
    r_.reject_unknown_keys(
        n,
        {"position", "velocity", "error_code", "status", "setpoints", "fixed", "hold", "commands",
         "unsupported", "reset_only_in_error_stop", "position_tolerance", "reset_count"},
        where);
    ProfileAxisDef a;
    a.name = name;
    a.mark = r_.mark(n);
    if (auto p = r_.require(n, "position", where)) {
      a.position = r_.string(*p, where + " position").value_or("");
      polled_point(*p, a.position, where + " position");
    }
    if (n["velocity"]) {
      a.velocity = r_.string(n["velocity"], where + " velocity").value_or("");
      polled_point(n["velocity"], a.velocity, where + " velocity");
    }
    if (n["error_code"]) {
      a.error_code = r_.string(n["error_code"], where + " error_code").value_or("");
      polled_point(n["error_code"], a.error_code, where + " error_code");
    }
    if (auto status = r_.require(n, "status", where); status && r_.expect_map(*status, where)) {
      for (const auto& e : *status) {
        const std::string bit_name = e.first.Scalar();
        const auto bit = status_bit_named(bit_name);
        if (!bit || std::find(kMappedBits.begin(), kMappedBits.end(), *bit) == kMappedBits.end()) {
          r_.error(e.first, fmt::format("{} status: '{}' is no mapped status bit (enabled, homed, "
                                        "moving, error, limit_positive, limit_negative, warning)",
                                        where, bit_name));
          continue;
        }
        if (auto s = parse_source(e.second, where + " status " + bit_name)) a.status[*bit] = *s;
      }
      for (const auto b : {StatusBit::enabled, StatusBit::moving})
        if (!a.status.count(b))
          r_.error(*status, fmt::format("{} status: '{}' is required (true where the controller "
                                        "has no such notion)",
                                        where, to_string(b)));
    }
    if (const auto sp = n["setpoints"]; sp && r_.expect_map(sp, where + " setpoints")) {
      for (const auto& e : sp) {
        const std::string key = e.first.Scalar();
        const auto which = profile_setpoint_named(key);
        if (!which) {
          r_.error(e.first, fmt::format("{} setpoints: unknown profile value '{}' (target, "
                                        "distance, velocity, jog_velocity, acceleration, "
                                        "deceleration, home_velocity)",
                                        where, key));
          continue;
        }
        const std::string target = r_.string(e.second, where + " setpoint").value_or("");
        const PointDef* point = model_.find_point(target);
        if (!model_.find_setpoint(target) && !(point && point->writable())) {
          r_.error(e.second, fmt::format("{} setpoints: model {} has no setpoint or writable "
                                         "point '{}'",
                                         where, model_.name, target));
          continue;
        }
        a.setpoints[*which] = target;
      }
    }
    if (const auto f = n["fixed"]; f && r_.expect_map(f, where + " fixed")) {
      for (const auto& e : f) {
        const std::string sp = e.first.Scalar();
        if (!known_setpoint(e.first, sp, where + " fixed")) continue;
        if (auto v = r_.integer(e.second, where + " fixed " + sp, INT64_MIN, INT64_MAX))
          a.fixed[sp] = *v;
      }
    }
    if (const auto h = n["hold"]; h && r_.expect_map(h, where + " hold")) {
      for (const auto& e : h) {
        const std::string sp = e.first.Scalar();
        if (!known_setpoint(e.first, sp, where + " hold")) continue;
        const std::string point = r_.string(e.second, where + " hold " + sp).value_or("");
        if (polled_point(e.second, point, where + " hold " + sp)) a.hold[sp] = point;
      }
    }
    if (const auto cmds = n["commands"]; cmds && r_.expect_map(cmds, where + " commands")) {
      for (const auto& e : cmds) {
        const auto command = profile_command_named(e.first.Scalar());
        if (!command) {
          r_.error(e.first, fmt::format("{} commands: unknown profile command '{}'", where,
                                        e.first.Scalar()));
          continue;
        }
        std::vector<std::string> actions;
        if (e.second.IsSequence()) {
          for (const auto& s : e.second)
            if (auto t = r_.string(s, where + " command"); t && known_action(s, *t, where))
              actions.push_back(*t);
        } else if (auto t = r_.string(e.second, where + " command");
                   t && known_action(e.second, *t, where)) {
          actions.push_back(*t);
        }
        // reset: [] is a reset of a controller without error state: the gateway clears its own
        // ErrorStop latch. Every other command needs an action.
        if (actions.empty() && *command != ProfileCommand::reset)
          r_.error(e.second, fmt::format("{} commands {}: no action", where, e.first.Scalar()));
        a.commands[*command] = std::move(actions);
      }
    }
    std::set<ProfileCommand> unsupported;
    if (const auto u = n["unsupported"]; u && r_.expect_sequence(u, where + " unsupported")) {
      for (const auto& e : u) {
        const auto command = profile_command_named(e.Scalar());
        if (!command) {
          r_.error(e,
                   fmt::format("{} unsupported: unknown profile command '{}'", where, e.Scalar()));
          continue;
        }
        if (a.commands.count(*command))
          r_.error(e, fmt::format("{}: {} is both mapped and unsupported", where, e.Scalar()));
        unsupported.insert(*command);
      }
    }
    if (const auto only = n["reset_only_in_error_stop"]) {
      a.reset_only_in_error_stop =
          r_.boolean(only, where + " reset_only_in_error_stop").value_or(false);
      const auto reset = a.commands.find(ProfileCommand::reset);
      if (a.reset_only_in_error_stop && (reset == a.commands.end() || reset->second.empty()))
        r_.error(only, fmt::format("{}: reset_only_in_error_stop needs a reset action under "
                                   "'commands'",
                                   where));
    }
    if (const auto t = n["position_tolerance"])
      a.position_tolerance = r_.integer(t, where + " position_tolerance", 0, INT32_MAX).value_or(0);
    if (n["reset_count"]) {
      a.reset_count = r_.string(n["reset_count"], where + " reset_count").value_or("");
      polled_point(n["reset_count"], a.reset_count, where + " reset_count");
    }
    for (uint16_t c = 1; c < kProfileCommandCount; ++c) {
      const auto command = static_cast<ProfileCommand>(c);
      if (!a.commands.count(command) && !unsupported.count(command))
        r_.error(n, fmt::format("{}: command {} is neither mapped under 'commands' nor listed "
                                "under 'unsupported'",
                                where, to_string(command)));
    }
    return a;
  }

  // The setpoints a command of an axis fills itself: its profile values, fixed and held ones.
  std::set<std::string> filled_by(const ProfileAxisDef& a) const {
    std::set<std::string> filled;
    for (const auto& [_, name] : a.setpoints)
      if (model_.find_setpoint(name)) filled.insert(name);
    for (const auto& [name, _] : a.fixed) filled.insert(name);
    for (const auto& [name, _] : a.hold) filled.insert(name);
    return filled;
  }

  // A command runs with its own copy of the node's setpoints, so a setpoint that another axis's
  // command fills is safe only where this axis's command fills it too: otherwise it would go out
  // with whatever the other axis last sent.
  void check_shared_setpoints() {
    const auto& axes = model_.profile_axes;
    for (std::size_t i = 0; i < axes.size(); ++i) {
      const auto own = filled_by(axes[i]);
      for (const auto& [command, actions] : axes[i].commands) {
        for (const auto& action_name : actions) {
          const ActionDef* action = model_.find_action(action_name);
          if (!action) continue;
          for (const auto& step : action->steps) {
            if (step.kind != ActionStep::Kind::send) continue;
            for (const auto& used : step.command.placeholders()) {
              if (own.count(used)) continue;
              for (std::size_t j = 0; j < axes.size(); ++j) {
                if (j == i || !filled_by(axes[j]).count(used)) continue;
                const YAML::Node at = commands_of_[i]
                                          ? commands_of_[i][std::string(to_string(command))]
                                          : YAML::Node();
                const std::string message = fmt::format(
                    "axis_profile {} commands {}: action {} sends setpoint '{}', which axis {}'s "
                    "commands set and axis {}'s do not: give it to axis {} (setpoints, fixed or "
                    "hold), or use a setpoint of its own",
                    axes[i].name, to_string(command), action_name, used, axes[j].name, axes[i].name,
                    axes[i].name);
                if (at)
                  r_.error(at, message);
                else
                  r_.diagnostics().error(axes[i].mark, message);
                break;
              }
            }
          }
        }
      }
    }
  }

  YamlReader& r_;
  Model& model_;
  std::vector<YAML::Node> commands_of_;  // each parsed axis's commands: node, for error marks
};

}  // namespace

void parse_axis_profile(YamlReader& reader, const YAML::Node& node, Model& model) {
  if (!node) return;
  ProfileParser(reader, model).parse(node);
}

}  // namespace fieldgate
