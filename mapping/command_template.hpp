#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate {

// What a family made of a command template when the configuration loaded (CANopen: the
// operation, and which of its fields each placeholder fills), so that running a command is
// filling in values, never parsing text. Opaque outside the family that compiled it.
class CompiledCommand {
 public:
  virtual ~CompiledCommand() = default;
};

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
  const std::vector<Piece>& pieces() const { return pieces_; }
  std::vector<std::string> placeholders() const;
  std::string render(const std::function<int64_t(std::string_view)>& lookup) const;
  // The value of each placeholder, in the order placeholders() names them.
  std::vector<int64_t> arguments(const std::function<int64_t(std::string_view)>& lookup) const;
  bool empty() const { return source_.empty(); }

  // The family's compiled form (null for a family that sends the rendered text). Set while the
  // configuration loads, before anything runs on it (Family::compile_commands).
  const std::shared_ptr<const CompiledCommand>& compiled() const { return compiled_; }
  void set_compiled(std::shared_ptr<const CompiledCommand> compiled) {
    compiled_ = std::move(compiled);
  }

 private:
  std::string source_;
  std::vector<Piece> pieces_;
  std::shared_ptr<const CompiledCommand> compiled_;
};

}  // namespace fieldgate
