#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

// The Copley ASCII grammar as the amplifier enforces it (shared/protocols/copley-ascii.md §3):
//   [<node>[.<axis>] ]<code> [<params>…]<CR>
namespace fieldgate::sim::copley {

// App. E error codes, the ones the simulator produces.
enum class Error : int {
  line_too_long = 1,  // "Too much data passed with command"
  unknown_command = 3,
  not_enough_data = 4,
  too_much_data = 5,
  unknown_variable = 9,
  out_of_range = 10,
  read_only = 11,
  bad_axis_state = 14,  // "Unknown axis state"
  wrong_bank = 15,      // "Variable doesn't exist on requested page"
  moving = 18,
  bad_velocity = 19,
  bad_acceleration = 20,
  bad_deceleration = 21,
  bad_jerk = 22,
  bad_trajectory_mode = 25,
  bad_node = 31,
  can_failure = 32,
  parse_error = 33,
};

enum class Bank { ram, flash };

struct Address {
  std::optional<int> node;   // absent: the amplifier on the serial port
  std::optional<char> axis;  // 'a'..'c'
};

struct AddressParse {
  Address address;
  std::string_view body;  // the command after the prefix
  std::optional<Error> error;
};

// Splits off the node/axis prefix. Syntax errors give e 33, node IDs above 127 e 31.
AddressParse parse_address(std::string_view line);

enum class Code : char {
  set = 's',
  get = 'g',
  copy = 'c',
  reset = 'r',
  trajectory = 't',
  cvm_register = 'i',
};

struct Command {
  Code code = Code::get;
  Bank bank = Bank::ram;             // s, g, c
  int variable = -1;                 // s, g, c
  std::vector<std::int64_t> values;  // s: the values; t: the sub-command; i: the value to write
  int cvm_register = -1;             // i
};

struct CommandParse {
  Command command;
  std::optional<Error> error;
};

// Parses the command after the prefix. Value counts of `s` are checked later, against the
// variable; everything else the grammar decides is checked here.
CommandParse parse_command(std::string_view body);

// Reply lines, CR included. `compact` drops the space after the tag (§2.8 shows `v1200`).
std::string ok_reply();
std::string error_reply(Error error, bool compact = false);
std::string values_reply(std::span<const std::int64_t> values, bool compact = false);
std::string register_reply(std::int64_t value, bool compact = false);

}  // namespace fieldgate::sim::copley
