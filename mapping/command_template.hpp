#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate {

// A request text with {name} placeholders, split once at load so a bad placeholder is a load
// error and rendering per transaction is a plain concatenation. "{{" and "}}" are literal braces.
// A placeholder may carry a format: {value} decimal, {value:x} lower-case hex, {value:X} upper.
class CommandTemplate {
 public:
  struct Piece {
    std::string literal;  // used when name is empty
    std::string name;     // placeholder name
    char format = 'd';    // 'd', 'x', 'X'
  };

  // Returns nullopt and sets error on unbalanced braces or an unknown format.
  static std::optional<CommandTemplate> compile(std::string_view text, std::string& error);

  const std::string& source() const { return source_; }
  std::vector<std::string> placeholders() const;
  std::string render(const std::function<int64_t(std::string_view)>& lookup) const;
  bool empty() const { return source_.empty(); }

 private:
  std::string source_;
  std::vector<Piece> pieces_;
};

}  // namespace fieldgate
