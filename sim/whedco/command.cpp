#include "sim/whedco/command.hpp"

#include <array>
#include <charconv>
#include <cstdint>

namespace fieldgate::sim::whedco {
namespace {

bool is_axis(char c) {
  return c == 'W' || c == 'X' || c == 'Y' || c == 'Z';
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

class Cursor {
 public:
  explicit Cursor(std::string_view text) : text_(text) {}

  bool done() const { return pos_ == text_.size(); }
  void skip_rest() { pos_ = text_.size(); }
  std::size_t position() const { return pos_; }
  std::string_view rest() const { return text_.substr(pos_); }
  char peek(std::size_t ahead = 0) const {
    return pos_ + ahead < text_.size() ? text_[pos_ + ahead] : '\0';
  }
  bool eat(std::string_view prefix) {
    if (!rest().starts_with(prefix)) return false;
    pos_ += prefix.size();
    return true;
  }
  std::optional<char> axis() {
    if (!is_axis(peek())) return std::nullopt;
    return text_[pos_++];
  }
  std::optional<int> hex_digit() {
    const int v = hex_value(peek());
    if (v < 0) return std::nullopt;
    ++pos_;
    return v;
  }
  std::optional<bool> binary() {
    if (peek() != '0' && peek() != '1') return std::nullopt;
    return text_[pos_++] == '1';
  }
  std::optional<long long> integer() {
    const std::size_t begin = pos_;
    std::size_t end = pos_;
    if (end < text_.size() && (text_[end] == '+' || text_[end] == '-')) ++end;
    while (end < text_.size() && text_[end] >= '0' && text_[end] <= '9') ++end;
    std::string_view digits = text_.substr(begin, end - begin);
    if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
    long long v = 0;
    const auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (digits.empty() || ec != std::errc{} || p != digits.data() + digits.size())
      return std::nullopt;
    pos_ = end;
    return v;
  }
  // Signed decimal as §5.3.1 allows it: "+" optional, leading zeros, a decimal point (".5").
  std::optional<double> number() {
    std::size_t end = pos_;
    if (end < text_.size() && (text_[end] == '+' || text_[end] == '-')) ++end;
    std::size_t digits = 0;
    bool point = false;
    while (end < text_.size()) {
      const char c = text_[end];
      if (c >= '0' && c <= '9') {
        ++digits;
      } else if (c == '.' && !point) {
        point = true;
      } else {
        break;
      }
      ++end;
    }
    if (digits == 0) return std::nullopt;
    std::string_view token = text_.substr(pos_, end - pos_);
    if (token.front() == '+') token.remove_prefix(1);
    double v = 0;
    const auto [p, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
    if (ec != std::errc{} || p != token.data() + token.size()) return std::nullopt;
    pos_ = end;
    return v;
  }

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
};

// A number, a variable (Vd, internal units) or `?` (read back, §5.3.1).
std::optional<Value> value(Cursor& c, bool allow_variable) {
  Value v;
  if (c.eat("?")) {
    v.kind = Value::Kind::query;
    return v;
  }
  if (allow_variable && c.peek() == 'V' && hex_value(c.peek(1)) >= 0) {
    c.eat("V");
    v.kind = Value::Kind::variable;
    v.variable = *c.hex_digit();
    return v;
  }
  if (const auto n = c.number()) {
    v.kind = Value::Kind::number;
    v.number = *n;
    return v;
  }
  return std::nullopt;
}

bool logical_term(Cursor& c) {
  c.eat("N");
  if (!c.eat("B") && !c.eat("I")) return false;
  return c.hex_digit().has_value();
}

bool condition(Cursor& c) {
  if (c.peek() == 'V') {
    c.eat("V");
    if (!c.hex_digit()) return false;
    if (!c.eat("<>") && !c.eat(">") && !c.eat("=") && !c.eat("<")) return false;
    return c.eat("V") && c.hex_digit();
  }
  if (!logical_term(c)) return false;
  const char op = c.peek();
  if (op == 'A' || op == 'O' || op == 'X') {
    c.eat(std::string_view(&op, 1));
    return logical_term(c);
  }
  return true;
}

bool operand(Cursor& c) {
  if (c.eat("PHE") || c.eat("PHP")) return true;
  if (c.eat("P")) return c.axis().has_value();
  if (c.eat("N")) return (c.eat("B") || c.eat("I")) && c.hex_digit();
  for (const char* letter : {"E", "V", "B", "I", "T", "A"})
    if (c.eat(letter)) return c.hex_digit().has_value();
  return false;
}

// Single-axis command: mnemonic + axis, then maybe a value.
std::optional<Command> axis_value(Cursor& c, Op op, std::string mnemonic, bool allow_variable,
                                  bool value_required = true) {
  Command cmd;
  cmd.op = op;
  cmd.mnemonic = std::move(mnemonic);
  const auto a = c.axis();
  if (!a) return std::nullopt;
  cmd.axis = *a;
  if (c.done()) {
    if (value_required) return std::nullopt;
    return cmd;
  }
  const auto v = value(c, allow_variable);
  if (!v) return std::nullopt;
  cmd.value = *v;
  return cmd;
}

std::optional<Command> parse(Cursor& c) {
  Command cmd;
  const auto simple = [&](Op op) -> std::optional<Command> {
    cmd.op = op;
    return cmd;
  };
  // Stores an argument just read in `field`; false when there was none.
  const auto take = [](const auto& argument, auto& field) {
    if (argument) field = *argument;
    return argument.has_value();
  };
  // Reads a hex digit from lo to hi into the index; false when there is none in that range.
  const auto index_digit = [&](int lo, int hi) {
    const auto d = c.hex_digit();
    return d && *d >= lo && *d <= hi && take(d, cmd.index);
  };
  // The command, if its arguments were read.
  const auto done = [&](bool read) -> std::optional<Command> {
    if (!read) return std::nullopt;
    return cmd;
  };
  const auto with_flag = [&](Op op) -> std::optional<Command> {
    cmd.op = op;
    return done(take(c.binary(), cmd.flag));
  };
  const auto with_index = [&](Op op) -> std::optional<Command> {
    cmd.op = op;
    const auto n = c.integer();
    if (!n || *n < 0 || *n > 255) return std::nullopt;
    cmd.index = static_cast<int>(*n);
    return cmd;
  };
  const auto with_axis = [&](Op op) -> std::optional<Command> {
    cmd.op = op;
    return done(take(c.axis(), cmd.axis));
  };
  const auto with_digit = [&](Op op, char letter) -> std::optional<Command> {
    cmd.op = op;
    cmd.letter = letter;
    return done(take(c.hex_digit(), cmd.index));
  };
  const auto with_value = [&](Op op, char axis, bool allow_variable) -> std::optional<Command> {
    cmd.op = op;
    cmd.axis = axis;
    return done(take(value(c, allow_variable), cmd.value));
  };
  const auto load = [&](std::string mnemonic, char axis, bool allow_variable) {
    cmd.mnemonic = std::move(mnemonic);
    return with_value(Op::load, axis, allow_variable);
  };
  const auto axis_set = [&](Op op) -> std::optional<Command> {
    cmd.op = op;
    while (const auto a = c.axis()) {
      if (cmd.axes.find(*a) != std::string::npos) return std::nullopt;
      cmd.axes += *a;
    }
    if (cmd.axes.empty()) return std::nullopt;
    return cmd;
  };
  const auto pair = [&](Op op) -> std::optional<Command> {
    cmd.op = op;
    if (c.eat("X"))
      cmd.axes = "X";
    else if (c.eat("W"))
      cmd.axes = "W";
    else if (c.eat("A"))
      cmd.axes = "A";
    else
      return std::nullopt;
    return cmd;
  };
  const auto set_position = [&](char mode, bool with_position) -> std::optional<Command> {
    cmd.op = Op::set_position;
    cmd.letter = mode;
    if (!take(c.axis(), cmd.axis)) return std::nullopt;
    if (with_position) {
      const auto v = value(c, false);
      if (!v || v->kind != Value::Kind::number) return std::nullopt;
      cmd.value = *v;
    }
    return cmd;
  };

  // Longer mnemonics before their prefixes (digest §7 item 5).
  if (c.eat("WB")) return simple(Op::warm_boot);
  if (c.eat("CB")) return simple(Op::cold_boot);
  if (c.eat("PE")) return with_flag(Op::parallel_enable);
  if (c.eat("EB")) return simple(Op::empty_buffer);
  if (c.eat("MS") || c.eat("ML")) return simple(Op::memory_transfer);
  if (c.eat("DG")) return with_flag(Op::diagnostics);
  if (c.eat("DEL")) return simple(Op::edit_delete);
  if (c.eat("DE")) return with_index(Op::define);
  if (c.eat("ED")) return simple(Op::end_definition);
  if (c.eat("EL")) return axis_value(c, Op::load, "EL", true);
  if (c.eat("IT")) return with_axis(Op::initialize);
  if (c.eat("UR")) return axis_value(c, Op::unit_ratio, "UR", false);
  if (c.eat("UE")) return with_flag(Op::profile128_enable);
  if (c.eat("WR")) {
    cmd.op = Op::axis_constant;
    cmd.mnemonic = "WR";
    if (!take(c.axis(), cmd.axis)) return std::nullopt;
    if (c.eat("?")) {
      cmd.value.kind = Value::Kind::query;
      return cmd;
    }
    const auto b = c.binary();
    if (!b) return std::nullopt;
    cmd.value = {Value::Kind::number, *b ? 1.0 : 0.0, 0};
    return cmd;
  }
  for (const char* constant :
       {"NO", "PO", "LD", "GN", "ZR", "PL", "FF", "DB", "IB", "PB", "ER", "DF", "PC", "PS", "CT"})
    if (c.eat(constant)) return axis_value(c, Op::axis_constant, constant, false);
  if (c.eat("RM")) return with_index(Op::repeat);
  if (c.eat("GT")) return with_index(Op::goto_profile);
  if (c.eat("GS")) return with_index(Op::gosub);
  if (c.eat("HT")) return simple(Op::halt);
  if (c.eat("STZ")) return set_position('T', false);
  if (c.eat("STP")) return set_position('T', true);
  if (c.eat("SHZ")) return set_position('H', false);
  if (c.eat("SHP")) return set_position('H', true);
  if (c.eat("SIZ")) return set_position('I', false);
  if (c.eat("SIP")) return set_position('I', true);
  if (c.eat("SBZ")) return set_position('B', false);
  if (c.eat("SBP")) return set_position('B', true);
  if (c.eat("STB")) return with_digit(Op::set_bit, 'B');
  if (c.eat("STI")) return with_digit(Op::set_bit, 'I');
  if (c.eat("RSB")) return with_digit(Op::reset_bit, 'B');
  if (c.eat("RSI")) return with_digit(Op::reset_bit, 'I');
  if (c.eat("RS")) {
    if (c.done()) return simple(Op::unit_status);
    return with_axis(Op::axis_status);
  }
  if (c.eat("AM")) return axis_value(c, Op::load, "AM", true);
  if (c.eat("IM")) return axis_value(c, Op::load, "IM", true);
  if (c.eat("AC")) return axis_value(c, Op::load, "AC", true);
  if (c.eat("VOX")) return load("VOX", 'X', false);
  if (c.eat("VOW")) return load("VOW", 'W', false);
  if (c.eat("VX")) return load("VX", 'X', true);
  if (c.eat("VW")) return load("VW", 'W', true);
  if (c.eat("IX")) return with_value(Op::radius_increment, 'X', false);
  if (c.eat("IW")) return with_value(Op::radius_increment, 'W', false);
  if (c.eat("IF")) {
    cmd.op = Op::if_branch;
    const std::size_t begin = c.position();
    Cursor probe = c;
    if (!condition(probe)) return std::nullopt;
    cmd.text = std::string(c.rest().substr(0, probe.position() - begin));
    c = probe;
    if (c.eat("GS"))
      cmd.gosub = true;
    else if (!c.eat("GT"))
      return std::nullopt;
    return with_index(Op::if_branch);
  }
  if (c.eat("RX")) return load("RX", 'X', true);
  if (c.eat("RW")) return load("RW", 'W', true);
  if (c.eat("RR")) return pair(Op::run_radius);
  if (c.eat("CR")) return pair(Op::run_circle);
  if (c.eat("RDB")) return simple(Op::report_booleans);
  if (c.eat("RDI")) return simple(Op::report_inputs);
  if (c.eat("RA")) {
    if (hex_value(c.peek()) >= 0) return with_digit(Op::report_analog, 'A');
    return axis_set(Op::run_absolute);
  }
  if (c.eat("RI")) return axis_set(Op::run_incremental);
  if (c.eat("RC")) return with_axis(Op::command_position);
  if (c.eat("RP")) return with_axis(Op::actual_position);
  if (c.eat("FE")) return with_axis(Op::following_error);
  if (c.eat("FC")) {
    if (c.done()) return simple(Op::unit_fault);
    return with_axis(Op::axis_fault);
  }
  if (c.eat("FS")) return axis_value(c, Op::load, "FS", true);
  if (c.eat("SN")) return axis_value(c, Op::load, "SN", false);
  if (c.eat("PT")) {
    // PTAxxBannn / PTAxxEannn / PTAxxFa (§5.14.1): accepted, not simulated.
    cmd.op = Op::set_point;
    if (!c.eat("A") && !c.eat("B")) return std::nullopt;
    const auto range = c.integer();
    if (!range || *range < 1 || *range > 50) return std::nullopt;
    if (c.eat("F")) return c.axis() ? std::optional<Command>{cmd} : std::nullopt;
    if (!c.eat("B") && !c.eat("E")) return std::nullopt;
    if (!c.axis() || !c.number()) return std::nullopt;
    return cmd;
  }
  if (c.eat("SPH")) return simple(Op::pll_zero_counter);
  if (c.eat("SP")) {
    cmd.op = Op::set_point;
    if (!c.eat("A") && !c.eat("B") && !c.eat("C") && !c.eat("D")) return std::nullopt;
    if (c.eat("F")) return cmd;
    for (int k = 0; k < 2; ++k)
      if (!c.axis() || (!c.eat("A") && !c.eat("B"))) return std::nullopt;
    return cmd;
  }
  if (c.eat("TC")) return with_index(Op::teach_start);
  if (c.eat("TM")) return axis_value(c, Op::teach_point, "TM", false, false);
  if (c.eat("WTT")) {
    cmd.op = Op::wait_time;
    const auto v = value(c, false);
    if (!v || v->kind != Value::Kind::number || v->number < 0 || v->number > 655.35)
      return std::nullopt;
    cmd.value = *v;
    return cmd;
  }
  if (c.eat("WTMA")) {
    cmd.op = Op::wait_motion;
    cmd.axis = 'A';
    return cmd;
  }
  if (c.eat("WTM")) return with_axis(Op::wait_motion);
  if (c.eat("WTI")) return simple(Op::wait_index);
  if (c.eat("WTE")) {
    cmd.op = Op::wait_condition;
    cmd.text = std::string(c.rest());
    Cursor probe = c;
    if (!condition(probe) || !probe.done()) return std::nullopt;
    c = probe;
    return cmd;
  }
  if (c.eat("AE")) {
    cmd.op = Op::aux_enable;
    const auto a = c.axis();
    const auto b = c.binary();
    if (!a || !b) return std::nullopt;
    cmd.axis = *a;
    cmd.flag = *b;
    return cmd;
  }
  if (c.eat("LM")) {
    cmd.op = Op::multiplier;
    if (!take(c.axis(), cmd.axis)) return std::nullopt;
    if (c.eat("?")) {
      cmd.value.kind = Value::Kind::query;
      return cmd;
    }
    if (c.eat("A")) {
      cmd.letter = 'A';
      return done(index_digit(1, 4));
    }
    if (c.eat("N")) {
      cmd.letter = 'N';
      const auto v = c.number();
      if (!v || *v < -100 || *v > 100) return std::nullopt;
      cmd.value = {Value::Kind::number, *v, 0};
      return cmd;
    }
    if (c.eat("V")) {
      cmd.letter = 'V';
      return done(take(c.hex_digit(), cmd.index));
    }
    return std::nullopt;
  }
  if (c.eat("LI")) {
    cmd.op = Op::input_source;
    if (!take(c.axis(), cmd.axis)) return std::nullopt;
    if (c.eat("F")) {
      cmd.letter = 'F';
      return cmd;
    }
    if (c.eat("E")) {
      cmd.letter = 'E';
      return done(index_digit(1, 3));
    }
    return std::nullopt;
  }
  for (const std::string_view pll : {"PHO", "PHL", "PHG", "PHZ", "PHC"})
    if (c.eat(pll)) return load(std::string(pll), 0, pll == "PHO" || pll == "PHL");
  for (const bool offset : {false, true}) {
    if (!c.eat(offset ? "AO" : "AD")) continue;
    if (!index_digit(1, 4)) return std::nullopt;
    return load(offset ? "AO" : "AD", 0, offset);
  }
  if (c.eat("DR")) {
    cmd.op = Op::direction;
    const auto d = c.hex_digit();
    const auto b = c.binary();
    if (!d || *d < 1 || *d > 12 || !b) return std::nullopt;
    cmd.index = *d;
    cmd.flag = *b;
    return cmd;
  }
  if (c.peek() == 'V' && hex_value(c.peek(1)) >= 0 && c.peek(2) == '=') {
    c.eat("V");
    cmd.index = *c.hex_digit();
    c.eat("=");
    if (c.eat("?")) {
      cmd.op = Op::variable_query;
      return cmd;
    }
    cmd.op = Op::variable_assign;
    cmd.text = std::string(c.rest());
    if (!valid_expression(cmd.text)) return std::nullopt;
    c.skip_rest();
    return cmd;
  }
  if (c.eat("X")) return simple(Op::edit_next);
  return std::nullopt;
}

}  // namespace

std::optional<Command> parse_command(std::string_view body) {
  Cursor c(body);
  auto cmd = parse(c);
  if (!cmd || !c.done()) return std::nullopt;
  return cmd;
}

bool allowed_in_profile(const Command& command) {
  if (command.query()) return false;
  switch (command.op) {
    case Op::warm_boot:
    case Op::cold_boot:
    case Op::parallel_enable:
    case Op::empty_buffer:
    case Op::memory_transfer:
    case Op::diagnostics:
    case Op::initialize:
    case Op::unit_ratio:
    case Op::axis_constant:
    case Op::define:
    case Op::direction:
    case Op::report_analog:
    case Op::report_booleans:
    case Op::report_inputs:
    case Op::variable_query:
    case Op::unit_status:
    case Op::axis_status:
    case Op::command_position:
    case Op::actual_position:
    case Op::following_error:
    case Op::unit_fault:
    case Op::axis_fault:
    case Op::edit_next:
    case Op::edit_delete:
    case Op::teach_start:
      return false;
    default:
      return true;
  }
}

bool valid_expression(std::string_view rhs) {
  Cursor c(rhs);
  if (c.peek() == '+' || c.peek() == '-' || (c.peek() >= '0' && c.peek() <= '9')) {
    const auto v = c.integer();
    return v && *v >= INT32_MIN && *v <= INT32_MAX && c.done();
  }
  if (!operand(c)) return false;
  if (c.done()) return true;
  if (!c.eat("*") && !c.eat("/") && !c.eat("+") && !c.eat("-")) return false;
  // A fixed number inside an expression is illegal (§5.11.2: VC=10*T1).
  return operand(c) && c.done();
}

bool valid_condition(std::string_view text) {
  Cursor c(text);
  return condition(c) && c.done();
}

}  // namespace fieldgate::sim::whedco
