#pragma once

#include <optional>
#include <string>
#include <string_view>

// The Whedco CMC command grammar (shared/protocols/whedco-cmc.md §2-§3), parsed from the text
// after the unit address. Parsing is separate from execution because lines typed between DEn and
// ED are checked and stored, not run.
namespace fieldgate::sim::whedco {

enum class Op {
  // System (§3.1)
  warm_boot,
  cold_boot,
  parallel_enable,
  empty_buffer,
  memory_transfer,  // MS, ML: not simulated, refused
  diagnostics,
  // Axis initialisation (§3.2)
  initialize,
  unit_ratio,
  axis_constant,  // NO PO WR LD GN ZR PL FF DB IB PB ER DF PC PS CT: stored and read back
  // Profiles and motion (§3.3)
  define,
  end_definition,
  profile128_enable,
  repeat,
  goto_profile,
  gosub,
  halt,
  set_position,  // STZ STP SHZ SHP SIZ SIP SBZ SBP; letter T H I B
  load,          // AM IM AC VX VW VOX VOW RX RW EL FS SN PHG PHZ PHO PHL PHC ADd AOd
  radius_increment,
  run_absolute,
  run_incremental,
  run_radius,
  run_circle,
  set_point,  // PT…, SP…: accepted and stored nowhere
  teach_start,
  teach_point,
  // Conditions (§3.4)
  wait_time,
  wait_motion,  // axis, or 'A' for all
  wait_index,
  wait_condition,
  if_branch,
  // Auxiliary position equation (§3.5)
  aux_enable,
  multiplier,
  input_source,
  pll_zero_counter,
  // I/O and variables (§3.7)
  set_bit,    // letter B or I
  reset_bit,  // letter B or I
  direction,
  report_analog,
  report_booleans,
  report_inputs,
  variable_query,
  variable_assign,
  // Status (§3.8)
  unit_status,
  axis_status,
  command_position,
  actual_position,
  following_error,
  unit_fault,
  axis_fault,
  // Editing (§3.9)
  edit_next,
  edit_delete,
};

struct Value {
  enum class Kind { none, number, variable, query };
  Kind kind = Kind::none;
  double number = 0;  // user units as entered
  int variable = 0;   // Vd
};

struct Command {
  Op op = Op::halt;
  std::string mnemonic;  // for load and axis_constant: "AM", "GN", "PHO", "AD", ...
  char axis = 0;         // W X Y Z; for VX/VW/RX/RW/IX/IW the pair's first axis
  std::string axes;      // RA/RI: the axis set; RR/CR: X, W or A
  Value value;
  int index = 0;       // profile n, hex digit d, repeat count
  bool flag = false;   // b
  char letter = 0;     // set_position mode; B/I for bits; LI source E/F; LM source A/N/V
  std::string text;    // variable expression or condition, checked at parse time
  bool gosub = false;  // if_branch: GS (true) or GT (false)
  bool query() const { return value.kind == Value::Kind::query; }
};

// nullopt for anything the grammar does not accept.
std::optional<Command> parse_command(std::string_view body);

// Commands §5.2 keeps out of defined profiles (system, axis initialisation, queries, (#) I/O).
bool allowed_in_profile(const Command& command);

// Checks an integer-variable right-hand side or a condition without evaluating it.
bool valid_expression(std::string_view rhs);
bool valid_condition(std::string_view condition);

}  // namespace fieldgate::sim::whedco
