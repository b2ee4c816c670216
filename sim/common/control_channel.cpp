#include "sim/common/control_channel.hpp"

#include <unistd.h>

#include <cerrno>
#include <charconv>

namespace fieldgate::sim {
namespace {

std::vector<std::string> split_words(std::string_view line) {
  std::vector<std::string> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t begin = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > begin) words.emplace_back(line.substr(begin, i - begin));
  }
  return words;
}

constexpr std::string_view kGenericHelp =
    "silence on|off   ignore every request (nothing is executed)\n"
    "garbage N        answer the next N requests with random bytes\n"
    "truncate N       answer the next N requests with half a reply and no terminator\n"
    "delay MS         wait MS milliseconds more before every reply (0 = off)\n"
    "swallow TEXT     run the next request containing TEXT, but lose its reply\n"
    "chaos SEED LATE% DROP% GARBLE% TRUNCATE% LATE_MS\n"
    "                 random faults on every reply (executed all the same): late by LATE_MS,\n"
    "                 dropped, garbled, truncated; chaos off ends it\n"
    "quit             remove the link and exit\n";

}  // namespace

std::optional<long long> parse_control_integer(std::string_view text) {
  bool negative = false;
  if (!text.empty() && text.front() == '-') {
    negative = true;
    text.remove_prefix(1);
  }
  int base = 10;
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    text.remove_prefix(2);
  }
  if (text.empty() || text.front() == '-' || text.front() == '+') return std::nullopt;
  long long value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value, base);
  if (error != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return negative ? -value : value;
}

ControlChannel::ControlChannel(int input_fd, int output_fd, FaultInjection& faults,
                               FamilyControl family, std::string family_help)
    : input_fd_(input_fd),
      output_fd_(output_fd),
      faults_(faults),
      family_(std::move(family)),
      family_help_(std::move(family_help)) {}

void ControlChannel::on_readable() {
  if (input_fd_ < 0) return;
  char buffer[512];
  const ssize_t n = ::read(input_fd_, buffer, sizeof buffer);
  if (n < 0) {
    if (errno == EAGAIN || errno == EINTR) return;
    input_fd_ = -1;
    return;
  }
  if (n == 0) {
    // Stdin closed (e.g. </dev/null in a demo): keep simulating, just stop listening.
    input_fd_ = -1;
    return;
  }
  pending_.append(buffer, static_cast<std::size_t>(n));
  std::size_t newline;
  while ((newline = pending_.find('\n')) != std::string::npos) {
    std::string line = pending_.substr(0, newline);
    pending_.erase(0, newline + 1);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (split_words(line).empty()) continue;
    reply(execute(line));
  }
}

std::string ControlChannel::execute(std::string_view line) {
  const std::vector<std::string> words = split_words(line);
  if (words.empty()) return "error: empty command";
  const std::string& verb = words.front();
  const std::span<const std::string> arguments(words.begin() + 1, words.end());

  auto count_argument = [&]() -> std::optional<unsigned> {
    if (arguments.size() != 1) return std::nullopt;
    const auto value = parse_control_integer(arguments[0]);
    if (!value || *value < 0 || *value > 1'000'000'000) return std::nullopt;
    return static_cast<unsigned>(*value);
  };

  if (verb == "silence") {
    if (arguments.size() == 1 && (arguments[0] == "on" || arguments[0] == "off")) {
      faults_.silence = arguments[0] == "on";
      return "ok silence " + arguments[0];
    }
    return "error: usage: silence on|off";
  }
  if (verb == "garbage") {
    if (const auto n = count_argument()) {
      faults_.garbage_replies = *n;
      return "ok garbage " + std::to_string(*n);
    }
    return "error: usage: garbage N";
  }
  if (verb == "truncate") {
    if (const auto n = count_argument()) {
      faults_.truncated_replies = *n;
      return "ok truncate " + std::to_string(*n);
    }
    return "error: usage: truncate N";
  }
  if (verb == "delay") {
    if (const auto n = count_argument()) {
      faults_.reply_delay = std::chrono::milliseconds(*n);
      return "ok delay " + std::to_string(*n);
    }
    return "error: usage: delay MS";
  }
  if (verb == "swallow") {
    if (arguments.empty()) return "error: usage: swallow TEXT (part of a request)";
    std::string text;
    for (const auto& a : arguments) text += (text.empty() ? "" : " ") + a;
    faults_.swallow_reply_to = text;
    return "ok swallow " + text;
  }
  if (verb == "chaos") {
    if (arguments.size() == 1 && arguments[0] == "off") {
      faults_.chaos.on = false;
      return "ok chaos off";
    }
    std::vector<long long> v;
    for (const auto& a : arguments) {
      const auto n = parse_control_integer(a);
      if (!n || *n < 0 || *n > 1'000'000'000) break;
      v.push_back(*n);
    }
    if (arguments.size() != 6 || v.size() != 6 || v[1] + v[2] + v[3] + v[4] > 100)
      return "error: usage: chaos SEED LATE% DROP% GARBLE% TRUNCATE% LATE_MS (percentages "
             "summing to at most 100) | chaos off";
    auto& c = faults_.chaos;
    c.on = true;
    c.seed = static_cast<std::uint32_t>(v[0]);
    c.late_percent = static_cast<unsigned>(v[1]);
    c.drop_percent = static_cast<unsigned>(v[2]);
    c.garble_percent = static_cast<unsigned>(v[3]);
    c.truncate_percent = static_cast<unsigned>(v[4]);
    c.late = std::chrono::milliseconds(v[5]);
    ++c.generation;
    return "ok chaos";
  }
  if (verb == "quit") {
    quit_ = true;
    return "ok quit";
  }
  if (verb == "help") {
    std::string text(kGenericHelp);
    text += family_help_;
    // One reply per command: the help text is sent as comment lines before the "ok".
    std::string out;
    std::size_t begin = 0;
    while (begin < text.size()) {
      const std::size_t end = text.find('\n', begin);
      out += "# " + text.substr(begin, end - begin) + "\n";
      if (end == std::string::npos) break;
      begin = end + 1;
    }
    return out + "ok help";
  }
  if (family_) {
    if (auto result = family_(verb, arguments)) return *result;
  }
  return "error: unknown command '" + verb + "' (try help)";
}

void ControlChannel::reply(std::string_view line) {
  std::string out(line);
  out += '\n';
  std::size_t written = 0;
  while (written < out.size()) {
    const ssize_t n = ::write(output_fd_, out.data() + written, out.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      return;  // nobody listens to the replies; the command has still been executed
    }
    written += static_cast<std::size_t>(n);
  }
}

}  // namespace fieldgate::sim
