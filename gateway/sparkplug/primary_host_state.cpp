#include "gateway/sparkplug/primary_host_state.hpp"

#include <cctype>
#include <charconv>
#include <string>

namespace fieldgate::sparkplug {

namespace {

// A minimal reader for the one flat object STATE carries: "key": value pairs of literals.
class FlatJson {
 public:
  explicit FlatJson(std::string_view text) : s_(text) {}

  bool parse(HostState& out) {
    bool have_online = false, have_timestamp = false;
    skip();
    if (!take('{')) return false;
    skip();
    if (take('}')) return false;
    for (;;) {
      std::string key;
      if (!string(key)) return false;
      skip();
      if (!take(':')) return false;
      skip();
      if (key == "online") {
        if (literal("true")) {
          out.online = true;
        } else if (literal("false")) {
          out.online = false;
        } else {
          return false;
        }
        have_online = true;
      } else if (key == "timestamp") {
        const auto* begin = s_.data() + pos_;
        const auto* end = s_.data() + s_.size();
        const auto [ptr, ec] = std::from_chars(begin, end, out.timestamp);
        if (ec != std::errc{}) return false;
        pos_ += static_cast<std::size_t>(ptr - begin);
        have_timestamp = true;
      } else if (!skip_value()) {
        return false;
      }
      skip();
      if (take('}')) break;
      if (!take(',')) return false;
      skip();
    }
    skip();
    return pos_ == s_.size() && have_online && have_timestamp;
  }

 private:
  void skip() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
  }
  bool take(char c) {
    if (pos_ < s_.size() && s_[pos_] == c) {
      ++pos_;
      return true;
    }
    return false;
  }
  bool literal(std::string_view word) {
    if (s_.substr(pos_).starts_with(word)) {
      pos_ += word.size();
      return true;
    }
    return false;
  }
  bool string(std::string& out) {
    if (!take('"')) return false;
    while (pos_ < s_.size() && s_[pos_] != '"') {
      if (s_[pos_] == '\\') ++pos_;
      if (pos_ < s_.size()) out += s_[pos_++];
    }
    return take('"');
  }
  // Other members: a string, number or literal (no nesting in STATE).
  bool skip_value() {
    std::string ignored;
    if (pos_ < s_.size() && s_[pos_] == '"') return string(ignored);
    const std::size_t start = pos_;
    while (pos_ < s_.size() && s_[pos_] != ',' && s_[pos_] != '}') ++pos_;
    return pos_ > start;
  }

  std::string_view s_;
  std::size_t pos_ = 0;
};

}  // namespace

std::optional<HostState> parse_host_state(std::string_view json) {
  HostState state;
  if (!FlatJson(json).parse(state)) return std::nullopt;
  return state;
}

bool PrimaryHostTracker::update(const HostState& state) {
  if (current_ && state.timestamp < current_->timestamp) return false;
  current_ = state;
  return true;
}

}  // namespace fieldgate::sparkplug
