#include "mapping/yaml_reader.hpp"

#include <fmt/format.h>

#include <yaml-cpp/eventhandler.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

namespace fieldgate {

std::string kind_name(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Null:
      return "nothing";
    case YAML::NodeType::Scalar:
      return fmt::format("'{}'", node.Scalar());
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a mapping";
    default:
      return "nothing";
  }
}

namespace {

// Walks the parser's events (no alias is expanded, so the walk is linear in the text) and
// records every mapping key that repeats an earlier key of the same mapping: yaml-cpp keeps
// both, and lookups silently return the first.
class DuplicateKeyFinder : public YAML::EventHandler {
 public:
  DuplicateKeyFinder(const std::string& file, Diagnostics& diag) : file_(file), diag_(diag) {}

  void OnDocumentStart(const YAML::Mark&) override {}
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t) override { item(mark, nullptr); }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t) override { item(mark, nullptr); }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                const std::string& value) override {
    item(mark, &value);
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {
    item(mark, nullptr);
    stack_.push_back({false, 0, {}});
  }
  void OnSequenceEnd() override { stack_.pop_back(); }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {
    item(mark, nullptr);
    stack_.push_back({true, 0, {}});
  }
  void OnMapEnd() override { stack_.pop_back(); }

 private:
  struct Container {
    bool map;
    std::size_t items;                       // keys and values so far
    std::map<std::string, YAML::Mark> keys;  // scalar keys seen
  };

  // Called when a node starts; in a mapping, every other node is a key.
  void item(const YAML::Mark& mark, const std::string* scalar) {
    if (stack_.empty()) return;
    Container& c = stack_.back();
    const bool is_key = c.map && c.items % 2 == 0;
    ++c.items;
    if (!is_key || !scalar) return;  // only scalar keys can be compared by their text
    const auto [it, fresh] = c.keys.emplace(*scalar, mark);
    if (fresh) return;
    diag_.error({file_, mark.line + 1, mark.column + 1},
                fmt::format("'{}' is defined twice in this mapping (first at line {}, column "
                            "{}); YAML would silently keep only one",
                            *scalar, it->second.line + 1, it->second.column + 1));
  }

  const std::string& file_;
  Diagnostics& diag_;
  std::vector<Container> stack_;
};

// True if the text has no duplicate keys (each one found is recorded).
bool check_duplicate_keys(const std::string& text, const std::string& file, Diagnostics& diag) {
  const std::size_t before = diag.errors().size();
  std::istringstream in(text);
  YAML::Parser parser(in);
  DuplicateKeyFinder finder(file, diag);
  // The first document only, as YAML::Load reads: on some malformed inputs yaml-cpp 0.7 reports
  // further documents forever without consuming any text (found by fuzz_config).
  parser.HandleNextDocument(finder);
  return diag.errors().size() == before;
}

YAML::Node load_checked(const std::string& text, const std::string& file, Diagnostics& diag) {
  try {
    YAML::Node root = YAML::Load(text);
    if (!check_duplicate_keys(text, file, diag)) return YAML::Node(YAML::NodeType::Undefined);
    return root;
  } catch (const YAML::ParserException& e) {
    diag.error({file, e.mark.line + 1, e.mark.column + 1}, "YAML syntax: " + e.msg);
  }
  return YAML::Node(YAML::NodeType::Undefined);
}

}  // namespace

std::optional<int64_t> parse_integer_text(std::string_view text) {
  bool negative = false;
  if (!text.empty() && (text[0] == '-' || text[0] == '+')) {
    negative = text[0] == '-';
    text.remove_prefix(1);
  }
  int base = 10;
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    text.remove_prefix(2);
  }
  if (text.empty()) return std::nullopt;
  uint64_t magnitude = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), magnitude, base);
  if (ec != std::errc{} || end != text.data() + text.size()) return std::nullopt;
  if (magnitude > static_cast<uint64_t>(INT64_MAX)) return std::nullopt;
  const auto value = static_cast<int64_t>(magnitude);
  return negative ? -value : value;
}

std::optional<std::chrono::microseconds> parse_duration_text(std::string_view text) {
  size_t split = 0;
  while (split < text.size() &&
         (std::isdigit(static_cast<unsigned char>(text[split])) || text[split] == '.'))
    ++split;
  if (split == 0) return std::nullopt;
  const std::string number(text.substr(0, split));
  const std::string_view unit = text.substr(split);
  char* end = nullptr;
  const double value = std::strtod(number.c_str(), &end);
  if (end != number.c_str() + number.size() || !std::isfinite(value)) return std::nullopt;
  double micros = 0;
  if (unit == "ms")
    micros = value * 1e3;
  else if (unit == "us")
    micros = value;
  else if (unit == "s")
    micros = value * 1e6;
  else if (unit == "min")
    micros = value * 60e6;
  else
    return std::nullopt;
  if (micros > 1e13) return std::nullopt;
  return std::chrono::microseconds(static_cast<int64_t>(std::llround(micros)));
}

YAML::Node YamlReader::load_file() {
  std::ifstream in(file_, std::ios::binary);
  if (!in) {
    diag_.error({file_, 0, 0}, "cannot open file");
    return YAML::Node(YAML::NodeType::Undefined);
  }
  std::ostringstream text;
  text << in.rdbuf();
  return load_checked(text.str(), file_, diag_);
}

YAML::Node YamlReader::load_string(const std::string& text) {
  return load_checked(text, file_, diag_);
}

SourceMark YamlReader::mark(const YAML::Node& node) const {
  const auto m = node.Mark();
  if (m.is_null()) return {file_, 0, 0};
  return {file_, m.line + 1, m.column + 1};
}

void YamlReader::error(const YAML::Node& node, std::string message) {
  diag_.error(mark(node), std::move(message));
}

bool YamlReader::expect_map(const YAML::Node& node, std::string_view what) {
  if (node.IsMap()) return true;
  error(node, fmt::format("{}: expected a mapping, found {}", what, kind_name(node)));
  return false;
}

bool YamlReader::expect_sequence(const YAML::Node& node, std::string_view what) {
  if (node.IsSequence()) return true;
  error(node, fmt::format("{}: expected a list, found {}", what, kind_name(node)));
  return false;
}

void YamlReader::reject_unknown_keys(const YAML::Node& map,
                                     std::initializer_list<std::string_view> allowed,
                                     std::string_view where) {
  if (!map.IsMap()) return;
  for (const auto& entry : map) {
    const std::string key = entry.first.Scalar();
    bool known = false;
    for (const auto a : allowed) known = known || a == key;
    if (known) continue;
    std::string list;
    for (const auto a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    error(entry.first, fmt::format("{}: unknown key '{}' (expected one of: {})", where, key, list));
  }
}

std::optional<YAML::Node> YamlReader::require(const YAML::Node& map, std::string_view key,
                                              std::string_view where) {
  if (map.IsMap()) {
    const auto value = map[std::string(key)];
    if (value.IsDefined() && !value.IsNull()) return value;
  }
  error(map, fmt::format("{}: missing required key '{}'", where, key));
  return std::nullopt;
}

std::optional<std::string> YamlReader::string(const YAML::Node& node, std::string_view what) {
  if (node.IsScalar()) return node.Scalar();
  error(node, fmt::format("{}: expected text, found {}", what, kind_name(node)));
  return std::nullopt;
}

std::optional<int64_t> YamlReader::integer(const YAML::Node& node, std::string_view what,
                                           int64_t min, int64_t max) {
  if (!node.IsScalar()) {
    error(node, fmt::format("{}: expected an integer, found {}", what, kind_name(node)));
    return std::nullopt;
  }
  const auto value = parse_integer_text(node.Scalar());
  if (!value) {
    error(node, fmt::format("{}: expected an integer, found '{}'", what, node.Scalar()));
    return std::nullopt;
  }
  if (*value < min || *value > max) {
    error(node, fmt::format("{}: {} is out of range {}..{}", what, *value, min, max));
    return std::nullopt;
  }
  return value;
}

std::optional<double> YamlReader::number(const YAML::Node& node, std::string_view what) {
  if (node.IsScalar()) {
    const std::string& text = node.Scalar();
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    if (!text.empty() && end == text.c_str() + text.size() && std::isfinite(value)) return value;
  }
  error(node, fmt::format("{}: expected a number, found {}", what, kind_name(node)));
  return std::nullopt;
}

std::optional<bool> YamlReader::boolean(const YAML::Node& node, std::string_view what) {
  if (node.IsScalar()) {
    const std::string& t = node.Scalar();
    if (t == "true" || t == "yes" || t == "on") return true;
    if (t == "false" || t == "no" || t == "off") return false;
  }
  error(node, fmt::format("{}: expected true or false, found {}", what, kind_name(node)));
  return std::nullopt;
}

std::optional<std::chrono::microseconds> YamlReader::duration(const YAML::Node& node,
                                                              std::string_view what) {
  if (node.IsScalar()) {
    if (auto d = parse_duration_text(node.Scalar())) return d;
    if (parse_duration_text(node.Scalar() + "ms")) {
      error(node, fmt::format("{}: '{}' has no unit; write it with one, such as {}ms or {}s "
                              "(us, ms, s and min are understood)",
                              what, node.Scalar(), node.Scalar(), node.Scalar()));
      return std::nullopt;
    }
  }
  error(node, fmt::format("{}: expected a duration such as 250ms or 2s, found {}", what,
                          kind_name(node)));
  return std::nullopt;
}

std::vector<std::string> yaml_files_in(const std::string& directory, std::string_view what,
                                       Diagnostics& diagnostics) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<std::string> files;
  if (!fs::is_directory(directory, ec)) {
    diagnostics.error({directory, 0, 0}, fmt::format("{} directory does not exist", what));
    return files;
  }
  for (const auto& entry : fs::directory_iterator(directory, ec))
    if (entry.is_regular_file() &&
        (entry.path().extension() == ".yaml" || entry.path().extension() == ".yml"))
      files.push_back(entry.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace fieldgate
