#include "drivers/protocol_file/protocol_spec.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace fieldgate::protocol_file {

bool capture_equals(const Capture& capture, const CaptureValue& value) {
  if (value.is_text) return capture.text == value.text;
  return capture.value == value.number;
}

std::vector<std::string> CommandSpec::parameters() const {
  std::vector<std::string> out;
  for (const Field* f : request.named_fields()) out.push_back(f->name);
  return out;
}

std::vector<std::string> CommandSpec::value_names() const {
  std::vector<std::string> out;
  if (reply)
    for (const Field* f : reply->named_fields()) out.push_back(f->name);
  if (!flags.empty()) out.push_back("flags");
  return out;
}

bool CommandSpec::reply_has_text() const {
  if (!reply) return false;
  if (reply_parts.empty()) return !reply->pieces().empty();
  return std::any_of(reply_parts.begin(), reply_parts.end(),
                     [](const ReplyPart& p) { return !p.text.empty(); });
}

SourceMark CommandSpec::reply_mark_at(std::size_t offset) const {
  const ReplyPart* part = nullptr;
  for (const auto& p : reply_parts)
    if (p.mark.line > 0 && p.offset <= offset) part = &p;
  if (!part) return {};
  SourceMark m = part->mark;
  m.column += static_cast<int>(offset - part->offset);
  return m;
}

std::optional<std::string> argument_problem(const CommandSpec& command, std::size_t index,
                                            int64_t value) {
  const auto fields = command.request.named_fields();
  if (index >= fields.size()) return std::nullopt;
  std::string why;
  if (format_field(*fields[index], value, why)) return std::nullopt;
  return fmt::format("{} argument {} ({}) cannot be sent: {}", command.name, index + 1, value, why);
}

const CommandSpec* ProtocolSpec::find(std::string_view command) const {
  for (const auto& c : commands)
    if (c.name == command) return &c;
  return nullptr;
}

std::string ProtocolSpec::address_text(int number) const {
  if (const auto it = address_overrides.find(number); it != address_overrides.end())
    return it->second;
  std::string out;
  for (const auto& piece : address_format.pieces()) {
    if (!piece.field) {
      out += piece.literal;
      continue;
    }
    std::string why;
    out += format_field(*piece.field, number, why).value_or(std::to_string(number));
  }
  return out;
}

}  // namespace fieldgate::protocol_file
