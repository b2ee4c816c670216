#include "drivers/protocol_file/protocol_spec.hpp"

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

const CommandSpec* ProtocolSpec::find(std::string_view command) const {
  for (const auto& c : commands)
    if (c.name == command) return &c;
  return nullptr;
}

std::string ProtocolSpec::address_text(int number) const {
  std::string why;
  const auto& pieces = address_format.pieces();
  if (pieces.size() == 1 && pieces[0].field)
    if (auto s = format_field(*pieces[0].field, number, why)) return *s;
  return std::to_string(number);
}

}  // namespace fieldgate::protocol_file
