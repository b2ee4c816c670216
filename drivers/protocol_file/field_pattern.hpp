#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/protocol_file/number_format.hpp"

namespace fieldgate::protocol_file {

// One typed field of a request or reply template, written `{name:type}` (docs/protocol-files.md):
//   int, int(N)        optional sign and decimal digits; N: exactly N characters (zero-padded
//                      when sent)
//   decimal(S)         optional sign, digits, optional point and decimals: the value times 10^S
//                      as an integer (S decimals of the device's unit per count)
//   hex, hex(N)        hexadecimal digits, either case (sent in upper case); N: exactly N
//   char               one character; its value is its code, compared as text
//   bits(N)            N characters 0/1, '_' between them ignored; the first is bit 0
//   text               any characters up to the next literal of the template (or the end)
// `{addr}` is the node's address as the protocol's address format writes it (`{addr:int(2)}`
// writes 01); in a reply it must be that node's address. A field named `_` is matched and
// dropped.
enum class FieldType { integer, decimal, hex, character, bits, text };

struct Field {
  std::string name;  // "_" skipped, "addr" the node address
  FieldType type = FieldType::integer;
  int width = 0;           // exact characters (digits for bits); 0: variable
  int scale = 0;           // decimal places of decimal(S)
  std::size_t offset = 0;  // where `{` stands in the template's text, for error marks
  // How the controller prints this int or decimal(S) field of a reply, where the file says so
  // (FieldPattern::declare_number); without it, the type's lenient reading.
  std::optional<NumberFormat> number;
};

std::string_view to_string(FieldType type);

struct Piece {
  std::string literal;         // when field is empty
  std::optional<Field> field;  // a typed field
};

// A captured field of a reply: its text as it came and its value (the number, a char's code,
// the bits as an integer; 0 for text).
struct Capture {
  std::string name;
  std::string text;
  int64_t value = 0;
  FieldType type = FieldType::integer;
};

struct PatternError {
  std::string message;
  std::size_t offset = 0;  // in the template's text
};

// A compiled template: literal text and typed fields, checked so that every field can be told
// from what follows it (a pattern that could never match is an error when it is compiled,
// e.g. two variable-width numbers side by side, or a hex field followed by a letter A-F).
class FieldPattern {
 public:
  static std::optional<FieldPattern> compile(std::string_view text, PatternError& error);

  const std::string& source() const { return source_; }
  const std::vector<Piece>& pieces() const { return pieces_; }
  // The named fields (not `_`, not addr), in order: a request's parameters, a reply's values.
  std::vector<const Field*> named_fields() const;
  bool has_address() const;

  // Matches the whole of `text`; nullopt with `why` set when it does not. `address` is the
  // node's address as the protocol writes it.
  std::optional<std::vector<Capture>> match(std::string_view text, std::string_view address,
                                            std::string& why) const;

  // Declares how the controller prints the int or decimal(S) field of piece `piece` in a reply,
  // and its width (0: the field's own). Fails (error set, at the field) for another type, or
  // where what follows the field could no longer be told from it (an exponent before an 'E').
  bool declare_number(std::size_t piece, const NumberFormat& format, int width,
                      PatternError& error);

  // Writes the template with `values` for its named fields, in order, and `address` for
  // {addr}. Fails (nullopt, why set) for a value the field cannot carry (a width too small,
  // a negative hex value).
  std::optional<std::string> render(const std::vector<int64_t>& values, std::string_view address,
                                    std::string& why) const;

 private:
  std::string source_;
  std::vector<Piece> pieces_;
};

// Formats one value as a field of that type writes it (used for {addr} too).
std::optional<std::string> format_field(const Field& field, int64_t value, std::string& why);

}  // namespace fieldgate::protocol_file
