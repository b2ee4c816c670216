#include "gateway/lifecycle/reload_verdict.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace fieldgate {

namespace {

template <typename T>
bool parse_number(std::string_view text, T& value) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  return ec == std::errc() && end == text.data() + text.size();
}

std::optional<ReloadVerdict::Result> parse_result(std::string_view text) {
  for (auto r : {ReloadVerdict::Result::started, ReloadVerdict::Result::accepted,
                 ReloadVerdict::Result::rejected})
    if (to_string(r) == text) return r;
  return std::nullopt;
}

}  // namespace

std::string ReloadVerdict::in_force() const {
  return fmt::format("config #{} ({})", config_number, config_id.empty() ? "unread" : config_id);
}

std::string_view to_string(ReloadVerdict::Result result) {
  switch (result) {
    case ReloadVerdict::Result::started:
      return "started";
    case ReloadVerdict::Result::accepted:
      return "accepted";
    case ReloadVerdict::Result::rejected:
      return "rejected";
  }
  return "started";
}

std::string to_text(const ReloadVerdict& v) {
  std::string text = fmt::format(
      "pid={}\nreload={}\nresult={}\nconfig_file={}\nconfig_number={}\nconfig_id={}\n", v.pid,
      v.reload, to_string(v.result), v.config_file, v.config_number, v.config_id);
  for (const auto& m : v.messages) {
    std::string line = m;
    for (auto& c : line)
      if (c == '\n') c = ' ';
    text += "message=" + line + "\n";
  }
  text += "end=1\n";  // a verdict without it was cut short
  return text;
}

std::optional<ReloadVerdict> parse_verdict(std::string_view text) {
  ReloadVerdict v;
  bool pid = false, reload = false, result = false, number = false, end = false;
  while (!text.empty()) {
    const auto eol = text.find('\n');
    if (eol == std::string_view::npos) return std::nullopt;  // every line ends with a newline
    const auto line = text.substr(0, eol);
    text.remove_prefix(eol + 1);
    const auto eq = line.find('=');
    if (eq == std::string_view::npos) return std::nullopt;
    const auto key = line.substr(0, eq);
    const auto value = line.substr(eq + 1);
    if (key == "pid") {
      pid = parse_number(value, v.pid);
    } else if (key == "reload") {
      reload = parse_number(value, v.reload);
    } else if (key == "result") {
      const auto r = parse_result(value);
      if (r) v.result = *r;
      result = r.has_value();
    } else if (key == "config_file") {
      v.config_file = value;
    } else if (key == "config_number") {
      number = parse_number(value, v.config_number);
    } else if (key == "config_id") {
      v.config_id = value;
    } else if (key == "message") {
      v.messages.emplace_back(value);
    } else if (key == "end") {
      end = value == "1";
    }  // other keys: written by a newer daemon, ignored
  }
  if (!(pid && reload && result && number && end)) return std::nullopt;
  return v;
}

bool write_verdict_file(const std::filesystem::path& path, const ReloadVerdict& verdict,
                        std::string& error) {
  const auto temporary = path.string() + ".new";
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << to_text(verdict);
    out.flush();
    if (!out) {
      error = fmt::format("cannot write {}", temporary);
      return false;
    }
  }
  std::error_code ec;
  std::filesystem::rename(temporary, path, ec);
  if (ec) {
    error = fmt::format("cannot rename {} to {}: {}", temporary, path.string(), ec.message());
    return false;
  }
  return true;
}

std::optional<ReloadVerdict> read_verdict_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) return std::nullopt;
  std::stringstream text;
  text << in.rdbuf();
  return parse_verdict(text.str());
}

std::string config_fingerprint(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "";
  uint64_t hash = 0xcbf29ce484222325ULL;
  char c;
  while (in.get(c)) {
    hash ^= static_cast<unsigned char>(c);
    hash *= 0x100000001b3ULL;
  }
  return fmt::format("{:016x}", hash);
}

std::optional<std::filesystem::path> runtime_directory(const std::string& option) {
  if (!option.empty()) return std::filesystem::path(option);
  const char* env = std::getenv("RUNTIME_DIRECTORY");
  if (env == nullptr || *env == '\0') return std::nullopt;
  std::string_view dirs(env);
  return std::filesystem::path(std::string(dirs.substr(0, dirs.find(':'))));
}

std::optional<ReloadVerdict> wait_for_verdict(
    const std::function<std::optional<ReloadVerdict>()>& read, uint64_t after,
    const std::function<bool()>& pause) {
  for (;;) {
    if (auto v = read(); v && v->reload > after) return v;
    if (!pause()) return std::nullopt;
  }
}

}  // namespace fieldgate
