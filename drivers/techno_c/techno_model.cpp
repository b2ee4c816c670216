#include "drivers/techno_c/techno_model.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <set>

#include "mapping/yaml_reader.hpp"

namespace fieldgate::techno {

namespace {

std::optional<double> parse_number(std::string_view text) {
  if (text.empty()) return std::nullopt;
  const std::string s(text);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

// "2540" (every axis) or "2540,2540,400" (X Y Z).
std::optional<std::array<double, 3>> parse_per_axis(std::string_view text) {
  std::vector<double> values;
  while (true) {
    const auto comma = text.find(',');
    std::string_view token = text.substr(0, comma);
    while (!token.empty() && token.front() == ' ') token.remove_prefix(1);
    while (!token.empty() && token.back() == ' ') token.remove_suffix(1);
    const auto v = parse_number(token);
    if (!v || *v <= 0) return std::nullopt;
    values.push_back(*v);
    if (comma == std::string_view::npos) break;
    text.remove_prefix(comma + 1);
  }
  if (values.size() == 1) return std::array<double, 3>{values[0], values[0], values[0]};
  if (values.size() == 3) return std::array<double, 3>{values[0], values[1], values[2]};
  return std::nullopt;
}

struct Range {
  int64_t lo = 0;
  int64_t hi = 0;
  bool within(int64_t min, int64_t max) const { return lo >= min && hi <= max; }
};

std::string show(const Range& r) {
  return r.lo == r.hi ? std::to_string(r.lo) : fmt::format("{}..{}", r.lo, r.hi);
}

enum class Use { read, write, step };

// One value of a command: a number, or one placeholder whose limits the model gives.
struct Value {
  std::string text;
  std::optional<Range> range;  // nullopt: not a number or placeholder (already reported)
  bool literal = false;
};

class ModelChecker {
 public:
  ModelChecker(const Model& model, const Profile& profile, Diagnostics& diagnostics)
      : model_(model), profile_(profile), diag_(diagnostics) {}

  void run() {
    for (const auto& p : model_.points) {
      if (p.read) check_read(p);
      if (p.write) {
        const Range limits{p.min.value_or(min_value(p.type)), p.max.value_or(max_value(p.type))};
        check(p.write->request.source(), Use::write, p.mark, "point " + p.name + " write",
              [&](std::string_view name) -> std::optional<Range> {
                if (name == "value") return limits;
                return std::nullopt;
              });
        if (p.write->object)
          error(p.mark, fmt::format("point {}: objects are for the canopen family", p.name));
      }
    }
    for (const auto& a : model_.actions) check_action(a);
  }

 private:
  void error(const SourceMark& mark, std::string message) { diag_.error(mark, std::move(message)); }

  void check_read(const PointDef& p) {
    const std::string what = "point " + p.name + " read";
    if (p.read->object) {
      error(p.mark, what + ": objects are for the canopen family");
      return;
    }
    const std::string& source = p.read->request.source();
    if (!check_text(source, p.mark, what)) return;
    const Command c = classify(source);
    if (c.kind == CommandKind::position) {
      if (!c.values.empty()) error(p.mark, what + ": P takes no values");
      if (p.read->format != NumberFormat::hex24)
        error(p.mark, what + ": the P reply is 24-bit hex; give format: hex24");
      if (p.read->field >= kPositionFields)
        error(p.mark, fmt::format("{}: P has fields 0..{} (X Y Z steps, in_motion, X Y Z units, "
                                  "motion_fault, motion_error)",
                                  what, kPositionFields - 1));
      if (p.read->field >= kFieldUnitsX && p.read->field < kFieldMotionFault &&
          !profile_.steps_per_unit)
        error(p.mark, what +
                          ": fields 4..6 are user units; the model needs the steps_per_unit "
                          "option");
      return;
    }
    if (c.kind == CommandKind::peek) {
      const auto address = parse_values(c.values);
      if (!address || address->size() != 1 || (*address)[0] < 0 || (*address)[0] > 65535)
        error(p.mark, what + ": peek takes one address 0..65535, e.g. b65531");
      if (p.read->format != NumberFormat::hex)
        error(p.mark, what + ": the peek reply is '0' and two hex digits; give format: hex");
      if (p.read->field != 0) error(p.mark, what + ": a peek reply has one field (0)");
      return;
    }
    error(p.mark, fmt::format("{}: '{}' is no query; the controller answers data only to P "
                              "(positions) and b/c (peek)",
                              what, source));
  }

  void check_action(const ActionDef& a) {
    const std::string what = "action " + a.name;
    const auto setpoint_range = [&](std::string_view name) -> std::optional<Range> {
      const SetpointDef* s = model_.find_setpoint(std::string(name));
      if (!s) return std::nullopt;
      return Range{s->min.value_or(min_value(s->type)), s->max.value_or(max_value(s->type))};
    };
    for (const auto& step : a.steps) {
      if (step.kind != ActionStep::Kind::send) continue;
      const std::string& source = step.command.source();
      const Command c = classify(source);
      const bool raw = c.kind == CommandKind::stop || c.kind == CommandKind::reset;
      if (step.urgent && !raw)
        error(step.mark, fmt::format("{}: only {} and {} may be urgent: every other command "
                                     "needs the line to itself",
                                     what, kStopCommand, kResetCommand));
      if (a.bus_wide && !raw)
        error(step.mark, fmt::format("{}: techno-c has no broadcast address; only the raw {} and "
                                     "{} bytes reach every controller on the line",
                                     what, kStopCommand, kResetCommand));
      check(source, Use::step, step.mark, what, setpoint_range);
    }
  }

  // Text-level rules shared by every use; false when the command cannot be checked further.
  bool check_text(const std::string& s, const SourceMark& mark, const std::string& what) {
    if (s.empty()) {
      error(mark, what + ": empty command");
      return false;
    }
    if (s.find_first_of("\r\n") != std::string::npos) {
      error(mark, fmt::format("{}: the family adds the CR; remove it from '{}'", what, s));
      return false;
    }
    if (s.front() == '@') {
      error(mark, fmt::format("{}: the family adds '@<device>'; write '{}'", what, s.substr(1)));
      return false;
    }
    if (s.find(' ') != std::string::npos) {
      error(mark, fmt::format("{}: send the canonical form without spaces (values joined by "
                              "commas): '{}'",
                              what, s));
      return false;
    }
    return true;
  }

  std::vector<Value> values_of(
      std::string_view text, const SourceMark& mark, const std::string& what,
      const std::function<std::optional<Range>(std::string_view)>& range_of) {
    std::vector<Value> out;
    if (text.empty()) return out;
    while (true) {
      const auto comma = text.find(',');
      const std::string_view token = text.substr(0, comma);
      Value v;
      v.text = std::string(token);
      if (token.size() > 2 && token.front() == '{' && token.back() == '}') {
        std::string_view name = token.substr(1, token.size() - 2);
        if (const auto colon = name.find(':'); colon != std::string_view::npos) {
          if (name.substr(colon + 1) != "d")
            error(mark, fmt::format("{}: values are decimal; '{}' asks for hex", what, token));
          name = name.substr(0, colon);
        }
        v.range = range_of(name);
      } else if (auto n = parse_integer_text(token); n && token.find('x') == std::string::npos) {
        v.range = Range{*n, *n};
        v.literal = true;
      } else {
        error(mark, fmt::format("{}: '{}' is neither a decimal number nor one {{placeholder}}",
                                what, token));
      }
      out.push_back(std::move(v));
      if (comma == std::string_view::npos) break;
      text.remove_prefix(comma + 1);
    }
    return out;
  }

  void require_range(const Value& v, int64_t min, int64_t max, const SourceMark& mark,
                     const std::string& what, std::string_view meaning) {
    if (!v.range) return;
    if (!v.range->within(min, max))
      error(mark, fmt::format("{}: {} '{}' can be {}, the controller takes {}..{}{}", what, meaning,
                              v.text, show(*v.range), min, max,
                              v.literal ? "" : " (give the setpoint or point min/max)"));
  }

  void require_mask(const Value& v, const SourceMark& mark, const std::string& what) {
    if (!v.range) return;
    const bool small = v.range->hi - v.range->lo <= 8;
    bool ok = small;
    for (int64_t m = v.range->lo; ok && m <= v.range->hi; ++m)
      ok = valid_axis_mask(m, profile_.axes);
    if (!ok)
      error(mark, fmt::format("{}: axis mask '{}' can be {}; with axes {} defined only masks of "
                              "defined axes are valid (X=1, Y=2, Z=4), anything else answers '3'",
                              what, v.text, show(*v.range), profile_.axes));
  }

  void check(const std::string& source, Use use, const SourceMark& mark, const std::string& what,
             const std::function<std::optional<Range>(std::string_view)>& range_of) {
    if (!check_text(source, mark, what)) return;
    const Command c = classify(source);
    if (c.kind == CommandKind::unknown) {
      error(mark, fmt::format("{}: '{}' is no C-series command", what, source));
      return;
    }
    const bool c142 = profile_.arc_commands;
    const auto values = values_of(
        c.kind == CommandKind::specify_axes ? std::string_view{} : c.values, mark, what, range_of);
    const auto count = [&](std::size_t n, std::string_view form) {
      if (values.size() == n) return true;
      error(mark, fmt::format("{}: '{}' needs {} value(s): {}", what, source, n, form));
      return false;
    };
    const auto step_only = [&](std::string_view why) {
      if (use == Use::step) return true;
      error(mark, fmt::format("{}: '{}' {}; put it in an action", what, source, why));
      return false;
    };
    switch (c.kind) {
      case CommandKind::specify_axes: {
        if (!step_only("clears the program memory")) return;
        const auto axes = parse_integer_text(c.values);
        if (!axes || !valid_axes_definition(static_cast<int>(*axes)) || *axes != profile_.axes)
          error(mark, fmt::format("{}: the axes definition must be the model's axes option ({}); "
                                  "'{}' is not",
                                  what, profile_.axes, source));
        return;
      }
      case CommandKind::move_relative:
      case CommandKind::move_absolute: {
        if (!step_only("waits for or starts a motion")) return;
        const int n = move_value_count(profile_.axes);
        if (!count(static_cast<std::size_t>(n),
                   fmt::format("distance/position and speed for each of the {} value pairs of "
                               "axes {}",
                               n / 2, profile_.axes)))
          return;
        const bool relative = c.kind == CommandKind::move_relative;
        for (std::size_t i = 0; i < values.size(); ++i) {
          if (i % 2 == 0)
            require_range(values[i], -kMaxSteps, kMaxSteps, mark, what,
                          relative ? "distance" : "position");
          else
            require_range(values[i], kMinSpeed, kMaxSpeed, mark, what, "speed");
        }
        return;
      }
      case CommandKind::home:
      case CommandKind::zero:
        if (c.kind == CommandKind::home && !step_only("waits for or starts a homing run")) return;
        if (count(1, "the axis mask (X=1, Y=2, Z=4)")) require_mask(values[0], mark, what);
        return;
      case CommandKind::home_speed:
        if (!count(static_cast<std::size_t>(axis_count(profile_.axes)),
                   "one home speed per defined axis, in X Y Z order"))
          return;
        for (const auto& v : values) require_range(v, kMinSpeed, kMaxSpeed, mark, what, "speed");
        return;
      case CommandKind::position:
      case CommandKind::peek:
        error(mark, fmt::format("{}: '{}' is a query; it belongs in a point's read", what, source));
        return;
      case CommandKind::poke:
        if (!count(2, "address,data")) return;
        if (!values[0].literal || !values[0].range || values[0].range->lo < 32768 ||
            values[0].range->lo > 65535)
          error(mark, fmt::format("{}: poke address must be a number 32768..65535 (lower "
                                  "addresses are EPROM)",
                                  what));
        require_range(values[1], 0, 255, mark, what, "data");
        return;
      case CommandKind::plane:
        if (count(1, "0 XY, 1 XZ, 2 YZ")) require_range(values[0], 0, 2, mark, what, "plane");
        return;
      case CommandKind::interpolation_3d:
      case CommandKind::circle_direction:
      case CommandKind::circle:
        if (!c142) {
          error(mark, fmt::format("{}: '{}' exists only on the C142 (interface card 5.0) and "
                                  "controllers like it; the model's variant {} has "
                                  "arc_commands: false",
                                  what, source, profile_.variant));
          return;
        }
        if (c.kind == CommandKind::interpolation_3d) {
          if (count(1, "1 on, 0 off")) require_range(values[0], 0, 1, mark, what, "switch");
        } else if (c.kind == CommandKind::circle_direction) {
          if (count(1, "-1 CCW, 0 CW")) require_range(values[0], -1, 0, mark, what, "direction");
        } else {
          if (!step_only("waits for a motion")) return;
          if (!count(7, "B,V,E,X,Y,Rx,Ry")) return;
          require_range(values[0], 1, kMaxSteps, mark, what, "arc length");
          require_range(values[1], kMinSpeed, kMaxSpeed, mark, what, "speed");
          require_range(values[3], -kMaxSteps, kMaxSteps, mark, what, "start X");
          require_range(values[4], -kMaxSteps, kMaxSteps, mark, what, "start Y");
          for (std::size_t i : {std::size_t{5}, std::size_t{6}}) {
            const auto& v = values[i];
            if (v.range && !(v.range->lo == v.range->hi && std::llabs(v.range->lo) == 1))
              error(mark,
                    fmt::format("{}: quadrant value '{}' must be exactly -1 or 1", what, v.text));
          }
        }
        return;
      case CommandKind::start_program:
        if (step_only("starts the stored program")) count(0, "none");
        return;
      case CommandKind::clear_program:
        if (step_only("erases the stored program")) count(0, "none");
        return;
      case CommandKind::enter_program:
        error(mark, fmt::format("{}: program downloads (i ... 9) are not served through the "
                                "gateway: a download is many lines and an error aborts it midway",
                                what));
        return;
      case CommandKind::trace:
        error(mark, fmt::format("{}: trace mode waits for a character per step and would hold "
                                "the line; it is not served through the gateway",
                                what));
        return;
      case CommandKind::save_to_card:
        error(mark, fmt::format("{}: u overwrites the memory card with no size check and its "
                                "reply is not documented; it is not served through the gateway",
                                what));
        return;
      case CommandKind::stop:
      case CommandKind::reset:
        step_only("is a raw byte for actions");
        return;
      case CommandKind::unknown:
        return;
    }
  }

  const Model& model_;
  const Profile& profile_;
  Diagnostics& diag_;
};

}  // namespace

const ModelOptionSpecs& option_specs() {
  using std::chrono::microseconds;
  const microseconds zero{0}, hour = std::chrono::hours(1);
  static const ModelOptionSpecs specs{
      required(text_option("variant", "",
                           "the controller: it116g (one axis), c10, c116, c142, or the name of "
                           "another C-series controller, which then gives fitted_axes and "
                           "arc_commands")),
      integer_option("fitted_axes", "", 1, 3,
                     "the axes the controller has: 1 X, 2 XY, 3 XYZ (default: 1 on the it116g, "
                     "3 on the c10, c116 and c142)"),
      flag_option("arc_commands", "",
                  "the controller knows 3D interpolation and circles (z, f, Y; default: true on "
                  "the c142, whose interface card 5.0 added them, else false)"),
      integer_option("axes", "", {"1", "3", "5", "7"},
                     "the axes definition sent at initialisation: 1 X, 3 XY, 5 XZ, 7 XYZ, within "
                     "fitted_axes (default: every fitted axis)"),
      integer_option("acceleration", "", {"25", "50", "75", "100"},
                     "the card's acceleration jumper in Hz/ms (default 25 with one fitted axis "
                     "(the IT116G), else 75; p.4.5)"),
      integer_option("home_speed", "2000", static_cast<double>(kMinSpeed),
                     static_cast<double>(kMaxSpeed),
                     "reference run speed in steps/s, sent with `d` (p.63)"),
      text_option("travel", "50000",
                  "steps > 0, one value or X,Y,Z: the furthest an axis can be from home"),
      number_option("timeout_factor", "1.25", 1, 100,
                    "a motion's reply timeout: its computed duration times this, plus "
                    "timeout_margin"),
      duration_option("timeout_margin", "1s", zero, hour,
                      "added to every motion's computed duration"),
      duration_option("program_timeout", "60s", zero, hour,
                      "reply timeout of a stored program's start"),
      duration_option("stop_settle", "500ms", zero, hour,
                      "time the axes take to stand still after a stop"),
      duration_option("motion_settle", "300ms", zero, hour,
                      "a lower-case (non-waiting) motion is over once the polled positions "
                      "stood still this long"),
      text_option("steps_per_unit", "",
                  "steps per user unit > 0, one value or X,Y,Z (2540 per inch at 4 mm pitch, "
                  "100 per mm); none: positions in steps"),
      number_option("unit_resolution", "0.001", 1e-9, 1e9,
                    "user units per register count (with steps_per_unit)"),
      choice_option("position_reply", "auto", {"auto", "bare", "ack"},
                    "the position query's reply: detected (auto), the bare value, or after an "
                    "ack"),
      integer_option("stop_bytes", "2", {"1", "2"}, "bytes of the stop command"),
      flag_option("stop_on_timeout", "true",
                  "send a stop when a motion's reply does not come in time"),
      flag_option("init_on_connect", "false",
                  "initialise the controller (axes definition) on every connect"),
      flag_option("init_when_undefined", "true",
                  "answer a `4` (axes not defined: the controller powered up) by initialising "
                  "and sending the request again"),
  };
  return specs;
}

Profile read_profile(const Model& model, Diagnostics& diagnostics) {
  Profile p;
  p.model = model.name;
  const auto v = check_model_options(model, "techno-c", option_specs(), diagnostics);
  const auto fail = [&](const std::string& key, std::string_view expect) {
    diagnostics.error(v.mark(key), fmt::format("model {}: option {}: '{}' is not {}", model.name,
                                               key, v.text(key), expect));
  };
  // The manual's four controllers; another one is named by the model, which then says how it
  // differs (fitted_axes, arc_commands).
  struct Known {
    const char* name;
    int fitted_axes;
    bool arc_commands;
  };
  static constexpr Known kKnown[] = {
      {"it116g", 1, false}, {"c10", 3, false}, {"c116", 3, false}, {"c142", 3, true}};
  p.variant = v.text("variant");
  const Known* known = nullptr;
  for (const auto& k : kKnown)
    if (p.variant == k.name) known = &k;
  if (known) {
    p.fitted_axes = known->fitted_axes;
    p.arc_commands = known->arc_commands;
  } else if (v.given("variant") && !(v.given("fitted_axes") && v.given("arc_commands"))) {
    diagnostics.error(v.mark("variant"),
                      fmt::format("model {}: option variant: expected it116g, c10, c116 or c142, "
                                  "found '{}' (another controller gives fitted_axes and "
                                  "arc_commands)",
                                  model.name, p.variant));
  }
  if (v.given("fitted_axes")) p.fitted_axes = static_cast<int>(v.integer("fitted_axes"));
  if (v.given("arc_commands")) p.arc_commands = v.flag("arc_commands");
  const int fitted_mask = p.fitted_axes == 1 ? 1 : p.fitted_axes == 2 ? 3 : 7;
  p.acceleration = p.fitted_axes == 1 ? 25'000 : 75'000;  // jumper defaults (p.4.5)
  p.axes = fitted_mask;
  if (v.given("axes")) {
    const int axes = static_cast<int>(v.integer("axes"));
    if ((axes & ~fitted_mask) != 0)
      fail("axes", fmt::format("within the {} fitted axes: the {} is a {} controller",
                               fitted_mask == 1   ? "X"
                               : fitted_mask == 3 ? "XY"
                                                  : "XYZ",
                               p.variant,
                               p.fitted_axes == 1 ? "single-axis"
                                                  : std::to_string(p.fitted_axes) + "-axis"));
    else
      p.axes = axes;
  }
  if (v.given("acceleration"))
    p.acceleration = static_cast<double>(v.integer("acceleration")) * 1000;
  p.home_speed = static_cast<double>(v.integer("home_speed"));
  if (auto t = parse_per_axis(v.text("travel")))
    p.travel = *t;
  else
    fail("travel", "steps > 0, one value or X,Y,Z");
  p.timeout_factor = v.number("timeout_factor");
  p.timeout_margin = v.duration("timeout_margin");
  p.program_timeout = v.duration("program_timeout");
  p.stop_settle = v.duration("stop_settle");
  p.motion_settle = v.duration("motion_settle");
  if (v.given("steps_per_unit")) {
    if (auto s = parse_per_axis(v.text("steps_per_unit")))
      p.steps_per_unit = *s;
    else
      fail("steps_per_unit",
           "steps per user unit > 0, one value or X,Y,Z (2540 per inch at 4 mm pitch, 100 per mm)");
  }
  p.unit_resolution = v.number("unit_resolution");
  const std::string& reply = v.text("position_reply");
  p.position_reply = reply == "bare"  ? PositionReply::bare
                     : reply == "ack" ? PositionReply::ack
                                      : PositionReply::automatic;
  p.stop_bytes = static_cast<int>(v.integer("stop_bytes"));
  p.stop_on_timeout = v.flag("stop_on_timeout");
  p.init_on_connect = v.flag("init_on_connect");
  p.init_when_undefined = v.flag("init_when_undefined");
  return p;
}

void check_model(const Model& model, const Profile& profile, Diagnostics& diagnostics) {
  ModelChecker(model, profile, diagnostics).run();
}

Profile merge_profiles(const std::vector<Profile>& profiles) {
  if (profiles.empty()) return Profile{};
  Profile merged = profiles.front();
  for (const auto& p : profiles) {
    Profile same_name = p;
    same_name.model = merged.model;
    if (same_name == merged) continue;
    merged.model += "+" + p.model;
    merged.acceleration = std::min(merged.acceleration, p.acceleration);
    merged.home_speed = std::min(merged.home_speed, p.home_speed);
    for (std::size_t i = 0; i < 3; ++i) merged.travel[i] = std::max(merged.travel[i], p.travel[i]);
    merged.timeout_factor = std::max(merged.timeout_factor, p.timeout_factor);
    merged.timeout_margin = std::max(merged.timeout_margin, p.timeout_margin);
    merged.program_timeout = std::max(merged.program_timeout, p.program_timeout);
    merged.stop_settle = std::max(merged.stop_settle, p.stop_settle);
    if (merged.steps_per_unit != p.steps_per_unit || merged.unit_resolution != p.unit_resolution)
      merged.steps_per_unit.reset();
    if (merged.position_reply != p.position_reply) merged.position_reply = PositionReply::automatic;
    merged.stop_bytes = std::max(merged.stop_bytes, p.stop_bytes);
    merged.stop_on_timeout = merged.stop_on_timeout || p.stop_on_timeout;
    if (merged.axes != p.axes) {
      merged.init_on_connect = false;
      merged.axes = 7;
    }
    merged.init_on_connect = merged.init_on_connect && p.init_on_connect;
    merged.init_when_undefined = merged.init_when_undefined && p.init_when_undefined;
    merged.motion_settle = std::max(merged.motion_settle, p.motion_settle);
  }
  return merged;
}

}  // namespace fieldgate::techno
