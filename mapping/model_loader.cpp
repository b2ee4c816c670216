#include "mapping/model_loader.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <set>

#include "mapping/axis_profile_loader.hpp"
#include "mapping/yaml_reader.hpp"

namespace fieldgate {

namespace {

class ModelParser {
 public:
  ModelParser(YamlReader& reader) : r_(reader) {}

  ModelPtr parse(const YAML::Node& root) {
    if (!root.IsDefined()) return nullptr;
    if (!r_.expect_map(root, "model file")) return nullptr;
    r_.reject_unknown_keys(root,
                           {"model", "family", "description", "options", "poll_classes", "points",
                            "setpoints", "actions", "axis_profile"},
                           "model");
    auto model = std::make_shared<Model>();
    model->mark = r_.mark(root);
    if (auto n = r_.require(root, "model", "model"))
      if (auto s = r_.string(*n, "model name")) model->name = *s;
    if (auto n = r_.require(root, "family", "model"))
      if (auto s = r_.string(*n, "family")) model->family = *s;
    if (root["description"])
      if (auto s = r_.string(root["description"], "description")) model->description = *s;
    if (const auto options = root["options"]; options && r_.expect_map(options, "options")) {
      for (const auto& e : options)
        if (auto s = r_.string(e.second, "option " + e.first.Scalar())) {
          model->options[e.first.Scalar()] = *s;
          model->option_marks[e.first.Scalar()] = r_.mark(e.first);
        }
    }
    parse_poll_classes(root["poll_classes"], *model);
    parse_points(root["points"], *model);
    parse_setpoints(root["setpoints"], *model);
    parse_actions(root["actions"], *model);
    parse_axis_profile(r_, root["axis_profile"], *model);
    return model;
  }

 private:
  // Iterates a mapping, reporting duplicate keys, which yaml-cpp would otherwise accept.
  template <typename F>
  void for_each_entry(const YAML::Node& map, std::string_view what, F&& f) {
    if (!map) return;
    if (!r_.expect_map(map, what)) return;
    std::set<std::string> seen;
    for (const auto& e : map) {
      const std::string key = e.first.Scalar();
      if (!seen.insert(key).second) {
        r_.error(e.first, fmt::format("{}: '{}' is defined twice", what, key));
        continue;
      }
      f(key, e.first, e.second);
    }
  }

  // What every named definition (point, setpoint, action) starts with: a map of known keys, its
  // name, its place in the file and its description.
  template <typename Def>
  std::optional<Def> definition(const std::string& name, const std::string& where,
                                const YAML::Node& spec,
                                std::initializer_list<std::string_view> keys) {
    if (!r_.expect_map(spec, where)) return std::nullopt;
    r_.reject_unknown_keys(spec, keys, where);
    Def d;
    d.name = name;
    d.mark = r_.mark(spec);
    if (spec["description"])
      d.description = r_.string(spec["description"], "description").value_or("");
    return d;
  }

  std::optional<CommandTemplate> compile(const YAML::Node& node, std::string_view what) {
    auto text = r_.string(node, what);
    if (!text) return std::nullopt;
    std::string error;
    auto t = CommandTemplate::compile(*text, error);
    if (!t) r_.error(node, fmt::format("{}: {}", what, error));
    return t;
  }

  std::optional<ObjectRef> object(const YAML::Node& node, const YAML::Node& type_node,
                                  std::string_view what) {
    auto text = r_.string(node, what);
    if (!text) return std::nullopt;
    const auto colon = text->find(':');
    auto index = parse_integer_text(text->substr(0, colon));
    std::optional<int64_t> sub = 0;
    if (colon != std::string::npos) sub = parse_integer_text(text->substr(colon + 1));
    if (!index || *index < 0 || *index > 0xffff || !sub || *sub < 0 || *sub > 0xff) {
      r_.error(node, fmt::format("{}: expected INDEX:SUBINDEX such as 0x6064:0, found '{}'", what,
                                 *text));
      return std::nullopt;
    }
    ObjectRef ref{static_cast<uint16_t>(*index), static_cast<uint8_t>(*sub), {}};
    if (type_node) {
      if (auto t = r_.string(type_node, "data_type")) ref.data_type = *t;
    } else {
      r_.error(node, fmt::format("{}: an object needs a data_type (e.g. INTEGER32)", what));
    }
    return ref;
  }

  void parse_poll_classes(const YAML::Node& node, Model& model) {
    for_each_entry(
        node, "poll_classes",
        [&](const std::string& name, const YAML::Node&, const YAML::Node& value) {
          if (auto d = r_.duration(value, "poll class " + name)) {
            if (d->count() <= 0)
              r_.error(value, fmt::format("poll class {}: period must be greater than 0", name));
            model.poll_classes.push_back({name, *d});
          }
        });
  }

  void parse_points(const YAML::Node& node, Model& model) {
    for_each_entry(
        node, "points", [&](const std::string& name, const YAML::Node&, const YAML::Node& spec) {
          const std::string where = "point " + name;
          auto defined = definition<PointDef>(name, where, spec,
                                              {"description", "type", "units", "scale", "read",
                                               "write", "poll", "bits", "min", "max", "none"});
          if (!defined) return;
          PointDef& p = *defined;
          if (auto t = r_.require(spec, "type", where)) {
            if (auto s = r_.string(*t, where + " type")) {
              if (auto vt = parse_value_type(*s))
                p.type = *vt;
              else
                r_.error(*t,
                         fmt::format("{}: unknown type '{}' (expected bool, int16, uint16, int32 "
                                     "or uint32)",
                                     where, *s));
            }
          }
          if (spec["units"]) p.units = r_.string(spec["units"], where + " units").value_or("");
          if (spec["scale"]) p.scale = r_.number(spec["scale"], where + " scale").value_or(1.0);
          if (const auto read = spec["read"]) p.read = parse_read(read, where);
          if (const auto write = spec["write"]) p.write = parse_write(write, where);
          if (!p.read && !p.write)
            r_.error(spec, fmt::format("{}: needs 'read', 'write' or both", where));
          if (const auto poll = spec["poll"]) {
            if (auto s = r_.string(poll, where + " poll")) {
              p.poll_class = *s;
              if (!model.find_poll_class(*s)) {
                std::string known;
                for (const auto& c : model.poll_classes)
                  known += (known.empty() ? "" : ", ") + c.name;
                r_.error(poll, fmt::format("{}: unknown poll class '{}' (defined: {})", where, *s,
                                           known.empty() ? "none" : known));
              }
            }
          } else if (p.read) {
            r_.error(spec, fmt::format("{}: a readable point needs a poll class ('poll')", where));
          }
          for_each_entry(spec["bits"], where + " bits",
                         [&](const std::string& bit_name, const YAML::Node&, const YAML::Node& b) {
                           const int width = register_count(p.type) * 16;
                           if (auto v = r_.integer(b, where + " bit " + bit_name, 0, width - 1))
                             p.bits.push_back({bit_name, static_cast<int>(*v)});
                         });
          if (spec["min"]) p.min = r_.integer(spec["min"], where + " min", INT64_MIN, INT64_MAX);
          if (spec["max"]) p.max = r_.integer(spec["max"], where + " max", INT64_MIN, INT64_MAX);
          check_limits(spec, where, p.type, p.min, p.max);
          p.none = parse_none(spec, where, p.type);
          model.points.push_back(std::move(p));
        });
  }

  std::optional<int64_t> parse_none(const YAML::Node& spec, const std::string& where,
                                    ValueType type) {
    if (!spec["none"]) return std::nullopt;
    return r_.integer(spec["none"], where + " none", min_value(type), max_value(type));
  }

  void check_limits(const YAML::Node& spec, const std::string& where, ValueType type,
                    const std::optional<int64_t>& min, const std::optional<int64_t>& max) {
    if (min && !in_range(type, *min))
      r_.error(spec["min"],
               fmt::format("{}: min {} does not fit {}", where, *min, to_string(type)));
    if (max && !in_range(type, *max))
      r_.error(spec["max"],
               fmt::format("{}: max {} does not fit {}", where, *max, to_string(type)));
    if (min && max && *min > *max)
      r_.error(spec["min"], fmt::format("{}: min {} is greater than max {}", where, *min, *max));
  }

  std::optional<ReadSpec> parse_read(const YAML::Node& node, const std::string& where) {
    ReadSpec spec;
    if (node.IsScalar()) {
      auto t = compile(node, where + " read");
      if (!t) return std::nullopt;
      spec.request = *t;
    } else {
      if (!r_.expect_map(node, where + " read")) return std::nullopt;
      r_.reject_unknown_keys(node, {"request", "field", "format", "object", "data_type"},
                             where + " read");
      if (node["request"]) {
        auto t = compile(node["request"], where + " read request");
        if (!t) return std::nullopt;
        spec.request = *t;
      }
      if (node["field"])
        spec.field =
            static_cast<int>(r_.integer(node["field"], where + " field", 0, 63).value_or(0));
      if (node["format"]) {
        const auto f = r_.string(node["format"], where + " format").value_or("");
        if (f == "decimal")
          spec.format = NumberFormat::decimal;
        else if (f == "hex")
          spec.format = NumberFormat::hex;
        else if (f == "hex24")
          spec.format = NumberFormat::hex24;
        else
          r_.error(
              node["format"],
              fmt::format("{}: unknown format '{}' (expected decimal, hex or hex24)", where, f));
      }
      if (node["object"]) spec.object = object(node["object"], node["data_type"], where + " read");
      if (spec.request.empty() && !spec.object)
        r_.error(node, fmt::format("{}: read needs a 'request' or an 'object'", where));
    }
    if (!spec.request.placeholders().empty())
      r_.error(node, fmt::format("{}: a read request takes no placeholders", where));
    return spec;
  }

  std::optional<WriteSpec> parse_write(const YAML::Node& node, const std::string& where) {
    WriteSpec spec;
    const YAML::Node* request = nullptr;
    if (node.IsScalar()) {
      request = &node;
    } else {
      if (!r_.expect_map(node, where + " write")) return std::nullopt;
      r_.reject_unknown_keys(node, {"request", "object", "data_type"}, where + " write");
      if (node["object"]) spec.object = object(node["object"], node["data_type"], where + " write");
    }
    YAML::Node request_node = request ? *request : node["request"];
    if (request_node) {
      auto t = compile(request_node, where + " write");
      if (!t) return std::nullopt;
      spec.request = *t;
      for (const auto& name : spec.request.placeholders())
        if (name != "value")
          r_.error(
              request_node,
              fmt::format("{}: write request may use only {{value}}, found {{{}}}", where, name));
    } else if (!spec.object) {
      r_.error(node, fmt::format("{}: write needs a 'request' or an 'object'", where));
    }
    return spec;
  }

  void parse_setpoints(const YAML::Node& node, Model& model) {
    for_each_entry(
        node, "setpoints", [&](const std::string& name, const YAML::Node&, const YAML::Node& spec) {
          const std::string where = "setpoint " + name;
          auto defined = definition<SetpointDef>(
              name, where, spec,
              {"description", "type", "units", "scale", "default", "min", "max", "none"});
          if (!defined) return;
          SetpointDef& s = *defined;
          if (model.find_point(name))
            r_.error(spec, fmt::format("{}: a point has the same name", where));
          if (auto t = r_.require(spec, "type", where)) {
            if (auto text = r_.string(*t, where + " type")) {
              if (auto vt = parse_value_type(*text))
                s.type = *vt;
              else
                r_.error(*t, fmt::format("{}: unknown type '{}'", where, *text));
            }
          }
          if (spec["units"]) s.units = r_.string(spec["units"], where + " units").value_or("");
          if (spec["scale"]) s.scale = r_.number(spec["scale"], where + " scale").value_or(1.0);
          if (spec["min"]) s.min = r_.integer(spec["min"], where + " min", INT64_MIN, INT64_MAX);
          if (spec["max"]) s.max = r_.integer(spec["max"], where + " max", INT64_MIN, INT64_MAX);
          check_limits(spec, where, s.type, s.min, s.max);
          s.none = parse_none(spec, where, s.type);
          if (spec["default"]) {
            if (auto d = r_.integer(spec["default"], where + " default", min_value(s.type),
                                    max_value(s.type))) {
              s.default_value = *d;
              if ((s.min && *d < *s.min) || (s.max && *d > *s.max))
                r_.error(spec["default"],
                         fmt::format("{}: default {} is outside min/max", where, *d));
            }
          } else if (s.min && *s.min > 0) {
            s.default_value = *s.min;
          }
          model.setpoints.push_back(std::move(s));
        });
  }

  std::optional<Condition> parse_condition(const YAML::Node& node, const Model& model,
                                           const std::string& where) {
    if (!r_.expect_map(node, where)) return std::nullopt;
    r_.reject_unknown_keys(node, {"point", "bit", "equals", "error_from"}, where);
    Condition c;
    const PointDef* point = nullptr;
    if (auto p = r_.require(node, "point", where)) {
      if (auto s = r_.string(*p, where + " point")) {
        c.point = *s;
        point = model.find_point(*s);
        if (!point)
          r_.error(*p, fmt::format("{}: unknown point '{}'", where, *s));
        else if (!point->readable() || point->poll_class.empty())
          r_.error(*p, fmt::format("{}: point '{}' is not polled, so it cannot end an action",
                                   where, *s));
      }
    }
    if (const auto bit = node["bit"]) {
      if (auto value = parse_integer_text(bit.Scalar()); value && bit.IsScalar()) {
        if (*value < 0 || *value > 31)
          r_.error(bit, fmt::format("{}: bit {} out of range 0..31", where, *value));
        c.bit = static_cast<int>(*value);
      } else if (point) {
        if (const auto* b = point->find_bit(bit.Scalar()))
          c.bit = b->bit;
        else
          r_.error(bit, fmt::format("{}: point '{}' has no bit named '{}'", where, c.point,
                                    bit.Scalar()));
      }
    }
    if (auto e = r_.require(node, "equals", where))
      c.equals = r_.integer(*e, where + " equals", INT64_MIN, INT64_MAX).value_or(0);
    if (const auto e = node["error_from"]) {
      if (auto s = r_.string(e, where + " error_from")) {
        const PointDef* source = model.find_point(*s);
        if (!source || !source->readable() || source->poll_class.empty())
          r_.error(e,
                   fmt::format("{}: error_from names '{}', which is no polled point", where, *s));
        else
          c.error_from = *s;
      }
    }
    return c;
  }

  // One condition, or a list of them.
  std::vector<Condition> parse_failed(const YAML::Node& node, const Model& model,
                                      const std::string& where) {
    std::vector<Condition> conditions;
    if (!node.IsSequence()) {
      if (auto c = parse_condition(node, model, where)) conditions.push_back(std::move(*c));
      return conditions;
    }
    if (node.size() == 0)
      r_.error(node,
               fmt::format("{}: an empty list; give a condition, or a list of one or more", where));
    int number = 0;
    for (const auto& entry : node) {
      const std::string entry_where = fmt::format("{} condition {}", where, ++number);
      if (!entry.IsMap()) {
        r_.error(entry, fmt::format("{}: expected a condition such as {{point: status, bit: "
                                    "fault, equals: 1}}, found {}",
                                    entry_where, kind_name(entry)));
        continue;
      }
      if (auto c = parse_condition(entry, model, entry_where)) conditions.push_back(std::move(*c));
    }
    return conditions;
  }

  void parse_actions(const YAML::Node& node, Model& model) {
    std::map<int64_t, std::string> codes;
    for_each_entry(
        node, "actions", [&](const std::string& name, const YAML::Node&, const YAML::Node& spec) {
          const std::string where = "action " + name;
          auto defined = definition<ActionDef>(
              name, where, spec,
              {"description", "code", "steps", "done", "failed", "timeout", "bus_wide"});
          if (!defined) return;
          ActionDef& a = *defined;
          if (auto c = r_.require(spec, "code", where)) {
            if (auto v = r_.integer(*c, where + " code", 1, 0xffff)) {
              a.code = static_cast<uint16_t>(*v);
              if (auto [it, fresh] = codes.emplace(*v, name); !fresh)
                r_.error(*c, fmt::format("{}: code {} is already used by action {}", where, *v,
                                         it->second));
            }
          }
          if (auto steps = r_.require(spec, "steps", where);
              steps && r_.expect_sequence(*steps, where))
            for (const auto& step : *steps) parse_step(step, model, a, where);
          if (spec["done"]) a.done = parse_condition(spec["done"], model, where + " done");
          if (spec["failed"]) a.failed = parse_failed(spec["failed"], model, where + " failed");
          if (spec["timeout"])
            a.timeout = r_.duration(spec["timeout"], where + " timeout").value_or(a.timeout);
          if (spec["bus_wide"])
            a.bus_wide = r_.boolean(spec["bus_wide"], where + " bus_wide").value_or(false);
          model.actions.push_back(std::move(a));
        });
  }

  void parse_step(const YAML::Node& step, const Model& model, ActionDef& action,
                  const std::string& where) {
    ActionStep s;
    s.mark = r_.mark(step);
    // A default YAML::Node is a defined null node, so presence needs its own flag.
    YAML::Node send;
    bool has_send = false;
    if (step.IsScalar()) {
      send = step;
      has_send = true;
    } else if (r_.expect_map(step, where + " step")) {
      r_.reject_unknown_keys(
          step, {"send", "delay", "accept_errors", "accept_no_reply", "urgent", "confirm_after"},
          where + " step");
      if (step["delay"]) {
        s.kind = ActionStep::Kind::delay;
        s.duration = r_.duration(step["delay"], where + " delay").value_or(s.duration);
      } else if (step["send"]) {
        send = step["send"];
        has_send = true;
      } else {
        r_.error(step, fmt::format("{}: a step needs 'send' or 'delay'", where));
        return;
      }
      if (const auto errors = step["accept_errors"]; errors && r_.expect_sequence(errors, where))
        for (const auto& e : errors)
          if (auto v = r_.integer(e, where + " accept_errors", 0, 0xffffffff))
            s.accept_errors.push_back(static_cast<int>(*v));
      if (step["urgent"]) s.urgent = r_.boolean(step["urgent"], where + " urgent").value_or(false);
      if (step["accept_no_reply"])
        s.accept_no_reply =
            r_.boolean(step["accept_no_reply"], where + " accept_no_reply").value_or(false);
      if (const auto confirm = step["confirm_after"]) {
        s.confirm_after = r_.duration(confirm, where + " confirm_after");
        if (s.confirm_after && s.confirm_after->count() < 0)
          r_.error(confirm, fmt::format("{}: confirm_after must not be negative", where));
        if (s.kind == ActionStep::Kind::delay)
          r_.error(confirm, fmt::format("{}: confirm_after belongs to a 'send' step", where));
        if (s.urgent)
          r_.error(confirm, fmt::format("{}: an urgent step does not wait for the line, so "
                                        "confirm_after has no meaning there",
                                        where));
        for (const auto& earlier : action.steps)
          if (earlier.confirm_after)
            r_.error(confirm, fmt::format("{}: only one step may carry confirm_after (the Modbus "
                                          "write is confirmed at the first)",
                                          where));
      }
    } else {
      return;
    }
    if (has_send) {
      auto t = compile(send, where + " step");
      if (!t) return;
      for (const auto& name : t->placeholders())
        if (!model.find_setpoint(name))
          r_.error(send, fmt::format("{}: step uses {{{}}}, which is not a setpoint of the model",
                                     where, name));
      s.command = *t;
    }
    action.steps.push_back(std::move(s));
  }

  YamlReader& r_;
};

}  // namespace

ModelPtr load_model_file(const std::string& path, Diagnostics& diagnostics) {
  return parse_yaml_file<ModelParser>(path, diagnostics);
}

ModelPtr load_model_text(const std::string& text, const std::string& name_for_errors,
                         Diagnostics& diagnostics) {
  return parse_yaml_text<ModelParser>(text, name_for_errors, diagnostics);
}

void ModelLibrary::load_directory(const std::string& directory, Diagnostics& diagnostics) {
  for (const auto& f : yaml_files_in(directory, "model", diagnostics))
    add(load_model_file(f, diagnostics), diagnostics);
}

void ModelLibrary::add(ModelPtr model, Diagnostics& diagnostics) {
  if (!model || model->name.empty()) return;
  auto [it, fresh] = models_.emplace(model->name, std::make_shared<Model>(*model));
  if (!fresh)
    diagnostics.error(model->mark, fmt::format("model '{}' is already defined in {}", model->name,
                                               to_string(it->second->mark)));
}

ModelPtr ModelLibrary::find(const std::string& name) const {
  const auto it = models_.find(name);
  return it == models_.end() ? nullptr : it->second;
}

Model* ModelLibrary::for_compiling(const std::string& name) {
  const auto it = models_.find(name);
  return it == models_.end() ? nullptr : it->second.get();
}

std::vector<std::string> ModelLibrary::names() const {
  std::vector<std::string> n;
  for (const auto& [name, _] : models_) n.push_back(name);
  return n;
}

}  // namespace fieldgate
