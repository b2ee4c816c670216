#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate::whedco {

// Whedco CMC host protocol (shared/protocols/whedco-cmc.md). Out: `<address><command>\r`, one
// address digit per CMC-0. Back: in echo mode the characters of the line as they arrive, then
// the reply text if the command has one, then the `*` prompt. The excerpt of the manual lacks
// the reply layouts; README.md lists the readings chosen here.

inline constexpr char kTerminator = '\r';
inline constexpr char kPrompt = '*';
// A `!` anywhere after the address makes a unit ignore the whole line (§5.17), and a line that
// starts with `!` carries no address: so this voids a partial line left in any unit without
// executing it, where a bare CR (§6.1.1) would run whatever had arrived.
inline constexpr std::string_view kLineVoid = "!\r";

// Whether the unit echoes (CMC-0 DIP switch SW2-5, per unit).
enum class EchoMode { automatic, echo, non_echo };

struct Address {
  int unit = 0;  // 0..7 (three DIP switches, SW2-1..3)
  EchoMode mode = EchoMode::automatic;
};

// "4", "4/auto", "4/echo" or "4/non-echo".
std::optional<Address> parse_address(std::string_view text, std::string& error);

// "4" + command + CR.
std::string encode_command(int unit, std::string_view command);

// The line as the unit sees it (address and command, no CR): what an echo repeats.
std::string sent_line(int unit, std::string_view command);

// Length of the complete reply at the start of `buffer`: the echo of `line` (when the mode
// allows one), then everything up to and including the `*` prompt. 0 while more is needed.
// An echo is recognised with or without the address character and in any letter case.
std::size_t frame_length(std::string_view buffer, std::string_view line, EchoMode mode);

// Removes leading CR/LF/spaces and, if present, the echo of `line` (and the CR/LF after it).
// Sets echoed when an echo was found.
std::string_view strip_echo(std::string_view frame, std::string_view line, bool& echoed);

// --- Commands ------------------------------------------------------------------------------

// Axis-set masks as the PLC writes them: bit 0 X, 1 Y, 2 W, 3 Z (the order of the FC axis byte,
// §6.1.2). Letters come out in the manual's order X Y W Z (`RAXYWZ`).
std::optional<std::string> axis_letters(int64_t mask);

// What the unit ratio (UR, position pulses per user unit) applies to. Literal numbers in
// commands and parameter values in replies are user units (§2.1, §5.3.1); the gateway side
// always speaks internal units (pulses, pulses/s, pulses/s²).
enum class Quantity { none, length, velocity, acceleration };

enum class QueryKind {
  plain,        // numbers
  axis_fault,   // FCa: a hex code (non-echo) or the §6.2 text (echo)
  unit_fault,   // FC: a number (non-echo) or the §6.1.2 texts (echo)
  bit_list,     // RDI, RDB: a number, or a string of 0/1 digits (first = I/O 1)
  status_word,  // RS, RSa: a 16-bit word printed in decimal, hex or binary (§4.3.1 missing)
};

struct PreparedCommand {
  std::string text;  // axis masks expanded; literal numbers still internal units
  Quantity quantity = Quantity::none;
  char axis = 0;                        // whose unit ratio applies
  std::size_t literal_begin = 0;        // the literal number in text, if literal_end > 0
  std::size_t literal_end = 0;          //
  bool scaled_reply = false;            // the reply carries the quantity (a query)
  QueryKind kind = QueryKind::plain;    //
  std::optional<char> unit_ratio_axis;  // URa? or URa<n>: the family keeps its cache current
  std::optional<int64_t> unit_ratio_written;
};

// Checks a command (without address) and expands `[n]` axis masks: `RA[3]` is `RAXY`; after any
// other mnemonic the mask must select exactly one axis (`STZ[4]` is `STZW`). Refuses what a
// gateway must not send: `!` (voids the line), the commands the digest keeps out of a gateway
// (CB, MS, ML, DG, profile definition and editing DEn/ED/DEL/X, teach mode TC), an address
// digit in front, lower case, spaces and control characters.
std::optional<PreparedCommand> prepare_command(std::string_view command, std::string& error);

// The command as it goes on the wire: the literal number converted to user units with the
// unit ratio, at the entry resolution of its quantity (lengths 4 decimals, velocities 2,
// accelerations whole units, §2.3), rounded half away from zero.
std::string wire_command(const PreparedCommand& command, int unit_ratio);

// Internal value -> user units text, e.g. (5, 4, length) -> "1.25".
std::string user_units(int64_t internal, int unit_ratio, Quantity quantity);

inline constexpr int kMinUnitRatio = 1;
inline constexpr int kMaxUnitRatio = 10000;

// --- Replies -------------------------------------------------------------------------------

// A decimal number as printed: mantissa * 10^-decimals.
struct Decimal {
  int64_t mantissa = 0;
  int decimals = 0;
};

// Whitespace-separated numbers of a reply body. Decimal: optional sign, optional point
// ("-12.5", "+3", ".5"); hex: hex digits. One leading label such as `V1=` or `X:` is skipped.
// nullopt when the body holds anything else.
std::optional<std::vector<Decimal>> parse_numbers(std::string_view body, bool hex);

// value * factor, rounded half away from zero; nullopt if it does not fit 64 bits.
std::optional<int64_t> to_internal(const Decimal& value, int64_t factor);

// §6.2 code of an axis fault text; recognised by its key word, so spacing, case and hyphens do
// not matter. nullopt for text that names no fault.
std::optional<int> axis_fault_from_text(std::string_view text);
std::string_view axis_fault_text(int code);
inline constexpr int kAxisFunctional = 8;

// FC in echo mode, encoded the way this family reads the non-echo number (§6.1.2 "one of the
// base numbers plus the axis byte"): base in the high byte (0 Unit Functional, 1 Power Failure,
// 2 Axis Initialized, 3 Arithmetic Overflow), axis byte in the low byte (bits 0-3 "not
// functional" X Y W Z, bits 4-7 "faulted" X Y W Z). Several lines add up.
std::optional<int64_t> unit_fault_from_text(std::string_view text);
inline constexpr int64_t kUnitFunctional = 0;
inline constexpr int64_t kUnitPowerFailure = 0x100;
inline constexpr int64_t kUnitAxisInitialized = 0x200;
inline constexpr int64_t kUnitArithmeticOverflow = 0x300;
// Bit of the axis byte: "not functional" (b) or "faulted" (a) for axis X, Y, W or Z.
int unit_fault_axis_bit(char axis, bool faulted);

// RDI/RDB as a string of 0/1 digits, first digit I/O 1 (bit 0). Only strings of 8 or more
// digits are taken as bit strings: shorter ones are ordinary numbers.
std::optional<int64_t> parse_bit_string(std::string_view body);

// How a unit prints its status words; the excerpt lacks §4.3.1, so each is plausible.
enum class StatusForm { decimal, hex, binary };
std::string_view to_string(StatusForm form);

// The bit layout of RS/RSa (§4.3.1 missing). busy_first: bit 0 busy, 1 fault, then the bits the
// models name (RS 2 profile running, 3 defining; RSa 2 auxiliary equation, 3 homing, 4 home
// input; RS 7 Memory Lost) - the layout the models are written in. outputs: like the unit's
// hardware status outputs in pin order (A.2: set point A, set point B, Busy, Fault; RS 7 Memory
// Lost).
enum class StatusLayout { busy_first, outputs };
std::string_view to_string(StatusLayout layout);
// A word a unit printed in `layout`, in the busy_first layout the models read: outputs' busy
// and fault move to bits 0 and 1, its set points A and B to bits 8 and 9; bits 4-7 stay.
int64_t to_model_layout(int64_t word, StatusLayout layout);

struct StatusWord {
  int64_t value = 0;
  // The form the text proves (binary digits, hex letters, four digits with a leading zero);
  // nullopt when decimal and unpadded hex would read it alike.
  std::optional<StatusForm> evidence;
};

// A status word: 8 or 16 binary digits (most significant first); hex when it has hex letters,
// is four digits with a leading zero, or the unit is known to print hex; else decimal. Anything
// that does not fit 16 bits is refused (problem says why).
std::optional<StatusWord> parse_status_word(std::string_view body, std::optional<StatusForm> known,
                                            std::string& problem);

// Device codes this family reports (Reply::device_code, the action error register).
inline constexpr int64_t kRejected = 1;  // the unit answered text, not the prompt or a value
inline constexpr int64_t kRefusedByGateway = 2;  // not sent: bad axis mask, bus-wide, ...

}  // namespace fieldgate::whedco
