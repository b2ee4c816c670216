#include "mapping/command_template.hpp"

#include <fmt/format.h>

namespace fieldgate {

std::optional<CommandTemplate> CommandTemplate::compile(std::string_view text, std::string& error) {
  CommandTemplate t;
  t.source_ = std::string(text);
  std::string literal;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '{' && i + 1 < text.size() && text[i + 1] == '{') {
      literal += '{';
      ++i;
      continue;
    }
    if (c == '}' && i + 1 < text.size() && text[i + 1] == '}') {
      literal += '}';
      ++i;
      continue;
    }
    if (c == '}') {
      error = fmt::format("unbalanced '}}' at offset {} in '{}'", i, text);
      return std::nullopt;
    }
    if (c != '{') {
      literal += c;
      continue;
    }
    const auto close = text.find('}', i);
    if (close == std::string_view::npos) {
      error = fmt::format("unterminated '{{' at offset {} in '{}'", i, text);
      return std::nullopt;
    }
    std::string_view inner = text.substr(i + 1, close - i - 1);
    Piece piece;
    if (const auto colon = inner.find(':'); colon != std::string_view::npos) {
      const auto fmt_text = inner.substr(colon + 1);
      if (fmt_text != "d" && fmt_text != "x" && fmt_text != "X") {
        error =
            fmt::format("unknown format '{}' in '{{{}}}' (expected d, x or X)", fmt_text, inner);
        return std::nullopt;
      }
      piece.format = fmt_text[0];
      inner = inner.substr(0, colon);
    }
    if (inner.empty()) {
      error = fmt::format("empty placeholder '{{}}' in '{}'", text);
      return std::nullopt;
    }
    for (const char n : inner) {
      if (!std::isalnum(static_cast<unsigned char>(n)) && n != '_') {
        error = fmt::format("placeholder name '{}' may hold only letters, digits and _", inner);
        return std::nullopt;
      }
    }
    if (!literal.empty()) t.pieces_.push_back({std::move(literal), {}, 'd'});
    literal.clear();
    piece.name = std::string(inner);
    t.pieces_.push_back(std::move(piece));
    i = close;
  }
  if (!literal.empty()) t.pieces_.push_back({std::move(literal), {}, 'd'});
  return t;
}

std::vector<std::string> CommandTemplate::placeholders() const {
  std::vector<std::string> names;
  for (const auto& p : pieces_)
    if (!p.name.empty()) names.push_back(p.name);
  return names;
}

std::string CommandTemplate::render(const std::function<int64_t(std::string_view)>& lookup) const {
  std::string out;
  for (const auto& p : pieces_) {
    if (p.name.empty()) {
      out += p.literal;
      continue;
    }
    const int64_t v = lookup(p.name);
    if (p.format == 'x')
      out += fmt::format("{:x}", static_cast<uint64_t>(v) & 0xffffffffu);
    else if (p.format == 'X')
      out += fmt::format("{:X}", static_cast<uint64_t>(v) & 0xffffffffu);
    else
      out += fmt::format("{}", v);
  }
  return out;
}

std::vector<int64_t> CommandTemplate::arguments(
    const std::function<int64_t(std::string_view)>& lookup) const {
  std::vector<int64_t> values;
  for (const auto& p : pieces_)
    if (!p.name.empty()) values.push_back(lookup(p.name));
  return values;
}

}  // namespace fieldgate
