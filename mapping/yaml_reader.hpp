#pragma once

#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mapping/diagnostics.hpp"

namespace fieldgate {

// Typed, position-aware access to one parsed YAML file. Every failed expectation is recorded
// in the Diagnostics with file:line:column and what was expected; accessors then return
// nullopt so the caller can go on and find further errors.
class YamlReader {
 public:
  YamlReader(std::string file, Diagnostics& diagnostics)
      : file_(std::move(file)), diag_(diagnostics) {}

  // Parses a file; a syntax error, or a key repeated within one mapping (yaml-cpp would keep
  // both and lookups would silently see the first), is recorded and an undefined node returned.
  YAML::Node load_file();
  YAML::Node load_string(const std::string& text);

  SourceMark mark(const YAML::Node& node) const;
  const std::string& file() const { return file_; }
  Diagnostics& diagnostics() { return diag_; }
  void error(const YAML::Node& node, std::string message);

  bool expect_map(const YAML::Node& node, std::string_view what);
  bool expect_sequence(const YAML::Node& node, std::string_view what);
  // Records every key of a map that is not in allowed, with the list of allowed keys.
  void reject_unknown_keys(const YAML::Node& map, std::initializer_list<std::string_view> allowed,
                           std::string_view where);
  // A required key missing from a map is reported at the map's position.
  std::optional<YAML::Node> require(const YAML::Node& map, std::string_view key,
                                    std::string_view where);

  std::optional<std::string> string(const YAML::Node& node, std::string_view what);
  // Integers in decimal or 0x hex, optionally negative, checked against [min, max].
  std::optional<int64_t> integer(const YAML::Node& node, std::string_view what, int64_t min,
                                 int64_t max);
  std::optional<double> number(const YAML::Node& node, std::string_view what);
  std::optional<bool> boolean(const YAML::Node& node, std::string_view what);
  // "250ms", "2s", "1.5s", "500us", "1min". A bare number is an error: "0.05" was once read
  // as milliseconds (50 us) where seconds were meant, and any default unit invites that.
  std::optional<std::chrono::microseconds> duration(const YAML::Node& node, std::string_view what);

 private:
  std::string file_;
  Diagnostics& diag_;
};

// A document of a file (or of a text, named for its errors) read by a Parser: a class built on a
// YamlReader whose parse(root) returns what the document describes.
template <class Parser>
auto parse_yaml_file(const std::string& path, Diagnostics& diagnostics) {
  YamlReader reader(path, diagnostics);
  Parser parser(reader);
  return parser.parse(reader.load_file());
}

template <class Parser>
auto parse_yaml_text(const std::string& text, const std::string& name_for_errors,
                     Diagnostics& diagnostics) {
  YamlReader reader(name_for_errors, diagnostics);
  Parser parser(reader);
  return parser.parse(reader.load_string(text));
}

// The *.yaml and *.yml files of a directory, sorted; a directory that is not there is an error
// ("WHAT directory does not exist") and no files.
std::vector<std::string> yaml_files_in(const std::string& directory, std::string_view what,
                                       Diagnostics& diagnostics);

// What an error says it found: 'text', a list, a mapping or nothing.
std::string kind_name(const YAML::Node& node);
// Parses integer text as the reader does ("0x1A", "-12", "12"); nullopt on anything else.
std::optional<int64_t> parse_integer_text(std::string_view text);
// A number with one of the units us, ms, s, min; nullopt without a unit or on anything else.
std::optional<std::chrono::microseconds> parse_duration_text(std::string_view text);

}  // namespace fieldgate
