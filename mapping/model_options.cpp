#include "mapping/model_options.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "mapping/model.hpp"
#include "mapping/yaml_reader.hpp"

namespace fieldgate {

namespace {

std::string join(const std::vector<std::string>& words, std::string_view last = "or") {
  std::string out;
  for (std::size_t i = 0; i < words.size(); ++i) {
    if (i > 0) out += i + 1 == words.size() ? fmt::format(" {} ", last) : ", ";
    out += words[i];
  }
  return out;
}

std::optional<double> parse_number_text(std::string_view text) {
  const std::string s(text);
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::string show_number(double v) {
  return fmt::format("{}", v);
}

std::string show_duration(std::chrono::microseconds d) {
  if (d.count() % 1'000'000 == 0) return fmt::format("{}s", d.count() / 1'000'000);
  if (d.count() % 1'000 == 0) return fmt::format("{}ms", d.count() / 1'000);
  return fmt::format("{}us", d.count());
}

// What a value of the spec must be, for error messages and the option table.
std::string expected(const ModelOptionSpec& s) {
  using T = ModelOptionSpec::Type;
  switch (s.type) {
    case T::flag:
      return "true or false";
    case T::integer:
      if (!s.choices.empty()) return join(s.choices);
      if (s.min < s.max)
        return fmt::format("an integer {}..{}", show_number(s.min), show_number(s.max));
      return "an integer";
    case T::number:
      if (s.min < s.max)
        return fmt::format("a number {}..{}", show_number(s.min), show_number(s.max));
      return "a number";
    case T::duration:
      if (s.min_duration < s.max_duration)
        return fmt::format("a duration {}..{} (with its unit: us, ms, s)",
                           show_duration(s.min_duration), show_duration(s.max_duration));
      return "a duration with its unit (us, ms, s)";
    case T::choice:
      return join(s.choices);
    case T::text:
      return "text";
  }
  return "";
}

}  // namespace

namespace {

ModelOptionSpec make(std::string name, ModelOptionSpec::Type type, std::string default_text,
                     std::string doc) {
  ModelOptionSpec s;
  s.name = std::move(name);
  s.type = type;
  s.default_text = std::move(default_text);
  s.doc = std::move(doc);
  return s;
}

ModelOptionSpec ranged(std::string name, ModelOptionSpec::Type type, std::string default_text,
                       double min, double max, std::string doc) {
  auto s = make(std::move(name), type, std::move(default_text), std::move(doc));
  s.min = min;
  s.max = max;
  return s;
}

}  // namespace

ModelOptionSpec flag_option(std::string name, std::string default_text, std::string doc) {
  return make(std::move(name), ModelOptionSpec::Type::flag, std::move(default_text),
              std::move(doc));
}

ModelOptionSpec integer_option(std::string name, std::string default_text, double min, double max,
                               std::string doc) {
  return ranged(std::move(name), ModelOptionSpec::Type::integer, std::move(default_text), min, max,
                std::move(doc));
}

ModelOptionSpec integer_option(std::string name, std::string default_text,
                               std::vector<std::string> values, std::string doc) {
  auto s = make(std::move(name), ModelOptionSpec::Type::integer, std::move(default_text),
                std::move(doc));
  s.choices = std::move(values);
  return s;
}

ModelOptionSpec number_option(std::string name, std::string default_text, double min, double max,
                              std::string doc) {
  return ranged(std::move(name), ModelOptionSpec::Type::number, std::move(default_text), min, max,
                std::move(doc));
}

ModelOptionSpec duration_option(std::string name, std::string default_text,
                                std::chrono::microseconds min, std::chrono::microseconds max,
                                std::string doc) {
  auto s = make(std::move(name), ModelOptionSpec::Type::duration, std::move(default_text),
                std::move(doc));
  s.min_duration = min;
  s.max_duration = max;
  return s;
}

ModelOptionSpec choice_option(std::string name, std::string default_text,
                              std::vector<std::string> choices, std::string doc) {
  auto s =
      make(std::move(name), ModelOptionSpec::Type::choice, std::move(default_text), std::move(doc));
  s.choices = std::move(choices);
  return s;
}

ModelOptionSpec text_option(std::string name, std::string default_text, std::string doc) {
  return make(std::move(name), ModelOptionSpec::Type::text, std::move(default_text),
              std::move(doc));
}

ModelOptionSpec required(ModelOptionSpec spec) {
  spec.required = true;
  return spec;
}

std::string_view to_string(ModelOptionSpec::Type type) {
  using T = ModelOptionSpec::Type;
  switch (type) {
    case T::flag:
      return "flag";
    case T::integer:
      return "integer";
    case T::number:
      return "number";
    case T::duration:
      return "duration";
    case T::choice:
      return "choice";
    case T::text:
      return "text";
  }
  return "?";
}

std::optional<bool> parse_flag_text(std::string_view t) {
  if (t == "true" || t == "yes" || t == "on") return true;
  if (t == "false" || t == "no" || t == "off") return false;
  return std::nullopt;
}

const ModelOptionValues::Value& ModelOptionValues::at(std::string_view name) const {
  const auto it = values_.find(name);
  // A family asking for an option it did not declare is a programming error, not bad input.
  if (it == values_.end())
    throw std::logic_error(fmt::format("model option '{}' was never declared", name));
  return it->second;
}

bool ModelOptionValues::given(std::string_view name) const {
  return at(name).given;
}
bool ModelOptionValues::flag(std::string_view name) const {
  return at(name).flag;
}
int64_t ModelOptionValues::integer(std::string_view name) const {
  return at(name).integer;
}
double ModelOptionValues::number(std::string_view name) const {
  return at(name).number;
}
std::chrono::microseconds ModelOptionValues::duration(std::string_view name) const {
  return at(name).duration;
}
const std::string& ModelOptionValues::text(std::string_view name) const {
  return at(name).text;
}
const SourceMark& ModelOptionValues::mark(std::string_view name) const {
  return at(name).mark;
}

ModelOptionValues check_model_options(const Model& model, std::string_view family,
                                      const ModelOptionSpecs& specs, Diagnostics& diagnostics,
                                      std::string_view hint) {
  using T = ModelOptionSpec::Type;
  ModelOptionValues out;
  const auto mark_of = [&](const std::string& name) -> const SourceMark& {
    const auto it = model.option_marks.find(name);
    return it == model.option_marks.end() ? model.mark : it->second;
  };
  for (const auto& option : model.options) {
    // A named reference, not a structured binding: clang before 16 cannot capture bindings.
    const std::string& name = option.first;
    const bool known = std::any_of(specs.begin(), specs.end(),
                                   [&](const ModelOptionSpec& s) { return s.name == name; });
    if (known) continue;
    std::vector<std::string> names;
    for (const auto& s : specs) names.push_back(s.name);
    std::string message =
        specs.empty() ? fmt::format("model {}: option '{}': the {} family has no model options",
                                    model.name, name, family)
                      : fmt::format(
                            "model {}: unknown {} option '{}' (known: {}; `fieldgate models "
                            "--options {}` describes them)",
                            model.name, family, name, join(names, "and"), family);
    if (!hint.empty()) message += fmt::format(" ({})", hint);
    diagnostics.error(mark_of(name), std::move(message));
  }
  for (const auto& spec : specs) {
    ModelOptionValues::Value v;
    const auto given = model.options.find(spec.name);
    v.given = given != model.options.end();
    v.mark = mark_of(spec.name);
    if (spec.required && !v.given)
      diagnostics.error(model.mark, fmt::format("model {}: option {} is required ({}): {}",
                                                model.name, spec.name, expected(spec), spec.doc));
    const auto parse = [&](const std::string& text, bool report) {
      const auto bad = [&] {
        if (report)
          diagnostics.error(v.mark, fmt::format("model {}: option {}: expected {}, found '{}'",
                                                model.name, spec.name, expected(spec), text));
        return false;
      };
      v.text = text;
      switch (spec.type) {
        case T::flag: {
          const auto b = parse_flag_text(text);
          if (!b) return bad();
          v.flag = *b;
          return true;
        }
        case T::integer: {
          const auto n = parse_integer_text(text);
          if (!n) return bad();
          if (!spec.choices.empty() && std::find(spec.choices.begin(), spec.choices.end(),
                                                 std::to_string(*n)) == spec.choices.end())
            return bad();
          if (spec.min < spec.max &&
              (static_cast<double>(*n) < spec.min || static_cast<double>(*n) > spec.max))
            return bad();
          v.integer = *n;
          v.number = static_cast<double>(*n);
          return true;
        }
        case T::number: {
          const auto n = parse_number_text(text);
          if (!n || (spec.min < spec.max && (*n < spec.min || *n > spec.max))) return bad();
          v.number = *n;
          return true;
        }
        case T::duration: {
          const auto d = parse_duration_text(text);
          if (!d || (spec.min_duration < spec.max_duration &&
                     (*d < spec.min_duration || *d > spec.max_duration)))
            return bad();
          v.duration = *d;
          return true;
        }
        case T::choice:
          if (std::find(spec.choices.begin(), spec.choices.end(), text) == spec.choices.end())
            return bad();
          return true;
        case T::text:
          return true;
      }
      return false;
    };
    if (!spec.default_text.empty() && !parse(spec.default_text, false))
      throw std::logic_error(fmt::format("{} option {}: default '{}' fails its own check", family,
                                         spec.name, spec.default_text));
    const ModelOptionValues::Value defaults = v;
    if (v.given && !parse(given->second, true)) {
      const SourceMark mark = v.mark;
      v = defaults;
      v.mark = mark;
    }
    out.values_.emplace(spec.name, std::move(v));
  }
  return out;
}

std::string describe_model_options(std::string_view family, const ModelOptionSpecs& specs) {
  if (specs.empty()) return fmt::format("The {} family has no model options.\n", family);
  std::string out = fmt::format(
      "Model options of the {} family (a model file's `options:`):\n\n"
      "| option | type | default | accepts | meaning |\n"
      "|---|---|---|---|---|\n",
      family);
  for (const auto& s : specs)
    out += fmt::format("| {} | {} | {} | {} | {} |\n", s.name, to_string(s.type),
                       s.required               ? "(required)"
                       : s.default_text.empty() ? "-"
                                                : s.default_text,
                       expected(s), s.doc);
  return out;
}

}  // namespace fieldgate
