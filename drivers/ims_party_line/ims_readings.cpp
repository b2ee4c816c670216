#include "drivers/ims_party_line/ims_readings.hpp"

#include <fmt/format.h>

#include "drivers/ims_party_line/ims_codec.hpp"

namespace fieldgate::ims {

std::string_view to_string(ResultPlacement placement) {
  return placement == ResultPlacement::next_line ? "next_line" : "echo_line";
}

std::string_view to_string(EchoLinefeed linefeed) {
  return linefeed == EchoLinefeed::at_once ? "at_once" : "at_execution";
}

bool parse_result_placement(std::string_view value, std::optional<ResultPlacement>& out) {
  out.reset();
  if (value == "next_line") out = ResultPlacement::next_line;
  if (value == "echo_line") out = ResultPlacement::echo_line;
  return out || value == "auto";
}

bool parse_echo_linefeed(std::string_view value, std::optional<EchoLinefeed>& out) {
  out.reset();
  if (value == "at_once") out = EchoLinefeed::at_once;
  if (value == "at_execution") out = EchoLinefeed::at_execution;
  return out || value == "auto";
}

ReadingPins UnitReadings::pins(char name) const {
  const auto it = units_.find(name);
  return it == units_.end() ? ReadingPins{} : it->second.pins;
}

namespace {

template <typename T>
std::optional<std::string> news(std::optional<T>& known, T now_seen, std::string_view what,
                                char name) {
  if (known == now_seen) return std::nullopt;
  const bool changed = known.has_value();
  const std::string was = changed ? std::string(to_string(*known)) : std::string();
  known = now_seen;
  if (changed)
    return fmt::format("unit {}: {} changed from {} to {}", printable({&name, 1}), what, was,
                       to_string(now_seen));
  return fmt::format("unit {}: {} detected: {}", printable({&name, 1}), what, to_string(now_seen));
}

}  // namespace

std::optional<std::string> UnitReadings::seen(char name, ResultPlacement placement) {
  return news(units_[name].placement, placement, "result_placement", name);
}

std::optional<std::string> UnitReadings::seen(char name, EchoLinefeed linefeed) {
  return news(units_[name].linefeed, linefeed, "echo_linefeed", name);
}

std::optional<std::string> UnitReadings::seen_name_echo(char name, bool with_name) {
  Unit& u = units_[name];
  if (u.with_name == with_name) return std::nullopt;
  const bool changed = u.with_name.has_value();
  u.with_name = with_name;
  return fmt::format("unit {}: echo {} its name{}", printable({&name, 1}),
                     with_name ? "includes" : "leaves out", changed ? " (changed)" : "");
}

std::optional<ResultPlacement> UnitReadings::placement(char name) const {
  const auto it = units_.find(name);
  return it == units_.end() ? std::nullopt : it->second.placement;
}

std::optional<EchoLinefeed> UnitReadings::linefeed(char name) const {
  const auto it = units_.find(name);
  return it == units_.end() ? std::nullopt : it->second.linefeed;
}

std::optional<bool> UnitReadings::echoes_name(char name) const {
  const auto it = units_.find(name);
  return it == units_.end() ? std::nullopt : it->second.with_name;
}

void LateReplies::owe_result(Clock::time_point now) {
  ++owed_;
  since_ = now;
}

void LateReplies::stray(std::string_view bytes, Clock::time_point now) {
  for (std::size_t n; (n = line_length(bytes)) > 0; bytes.remove_prefix(n)) {
    const std::string_view line = bytes.substr(0, n);
    switch (classify_stray(line)) {
      case StrayLine::result:
        pay();
        break;
      case StrayLine::query_echo:
        owe_result(now);
        // The late echo came: the unit that went silent is accounted for.
        for (auto it = silent_.begin(); it != silent_.end();)
          it = line.find(it->second.first) != std::string_view::npos ? silent_.erase(it)
                                                                     : std::next(it);
        break;
      default:
        break;
    }
  }
}

std::optional<std::string> LateReplies::expire(Clock::time_point now, Clock::duration window) {
  for (auto it = silent_.begin(); it != silent_.end();)
    it = now - it->second.second > window ? silent_.erase(it) : std::next(it);
  if (owed_ == 0 || now - since_ <= window) return std::nullopt;
  const int written_off = owed_;
  owed_ = 0;
  return fmt::format(
      "gave up waiting for {} late result line(s); results on their own line are trusted "
      "again",
      written_off);
}

void LateReplies::silent(char name, std::string command, Clock::time_point now) {
  silent_[name] = {std::move(command), now};
}

bool LateReplies::suspicious(char name, std::string_view command, Clock::time_point now,
                             Clock::duration window) const {
  for (const auto& [other, entry] : silent_)
    if (other != name && entry.first == command && now - entry.second <= window) return true;
  return false;
}

}  // namespace fieldgate::ims
