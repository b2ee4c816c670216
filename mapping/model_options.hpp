#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mapping/diagnostics.hpp"

namespace fieldgate {

struct Model;

// One option a family declares for its models (`options:` of a model file): checked by
// check_model_options, listed by `fieldgate models --options FAMILY`.
struct ModelOptionSpec {
  enum class Type { flag, integer, number, duration, choice, text };
  std::string name;
  Type type = Type::text;
  std::string default_text;  // as a user would write it; empty: no default (see doc)
  std::string doc;
  std::vector<std::string> choices;  // choice: the words accepted; integer: the values accepted
  double min = 0, max = 0;           // integer, number: inclusive range when min < max
  std::chrono::microseconds min_duration{0}, max_duration{0};  // duration: when min < max
  bool required = false;
};

using ModelOptionSpecs = std::vector<ModelOptionSpec>;

// The declarations a family writes (an empty default_text: no default, see the doc).
ModelOptionSpec flag_option(std::string name, std::string default_text, std::string doc);
ModelOptionSpec integer_option(std::string name, std::string default_text, double min, double max,
                               std::string doc);
// An integer that takes only the listed values (a jumper setting, a byte count).
ModelOptionSpec integer_option(std::string name, std::string default_text,
                               std::vector<std::string> values, std::string doc);
ModelOptionSpec number_option(std::string name, std::string default_text, double min, double max,
                              std::string doc);
ModelOptionSpec duration_option(std::string name, std::string default_text,
                                std::chrono::microseconds min, std::chrono::microseconds max,
                                std::string doc);
ModelOptionSpec choice_option(std::string name, std::string default_text,
                              std::vector<std::string> choices, std::string doc);
// Checked further by the family (a per-axis list).
ModelOptionSpec text_option(std::string name, std::string default_text, std::string doc);
ModelOptionSpec required(ModelOptionSpec spec);

std::string_view to_string(ModelOptionSpec::Type type);

// A model's options, checked against its family's declaration. Getters return the given value,
// else the declared default; a value that failed its check reads as the default too (the error
// is in the diagnostics, and a model with errors never runs).
class ModelOptionValues {
 public:
  bool given(std::string_view name) const;
  bool flag(std::string_view name) const;
  int64_t integer(std::string_view name) const;
  double number(std::string_view name) const;
  std::chrono::microseconds duration(std::string_view name) const;
  // choice and text options: the word given (or the default)
  const std::string& text(std::string_view name) const;
  // Where the value was written (the model's own mark when the option was not given).
  const SourceMark& mark(std::string_view name) const;

 private:
  friend ModelOptionValues check_model_options(const Model&, std::string_view,
                                               const ModelOptionSpecs&, Diagnostics&,
                                               std::string_view);
  struct Value {
    std::string text;
    bool given = false;
    bool flag = false;
    int64_t integer = 0;
    double number = 0;
    std::chrono::microseconds duration{0};
    SourceMark mark;
  };
  const Value& at(std::string_view name) const;
  std::map<std::string, Value, std::less<>> values_;
};

// The one parser of model options: unknown names, wrong types and values out of range are
// errors at the option's own file:line:col, naming what was expected.
// `hint` follows the error for an unknown option (where a family's users look for a setting).
ModelOptionValues check_model_options(const Model& model, std::string_view family,
                                      const ModelOptionSpecs& specs, Diagnostics& diagnostics,
                                      std::string_view hint = {});

// A flag's words: true/false, yes/no, on/off (as YAML 1.1 and the gateway config accept them).
std::optional<bool> parse_flag_text(std::string_view text);

// The table `fieldgate models --options FAMILY` prints.
std::string describe_model_options(std::string_view family, const ModelOptionSpecs& specs);

}  // namespace fieldgate
