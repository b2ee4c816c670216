#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

// IMS indexer party-line framing (shared/protocols/ims-indexer.md §1–4): `<name><command>\n`
// out; the named unit echoes the line (with or without its name) and queries add a result line
// `   1000\r\n`. Replies carry no address. Global characters reach every unit on the chain.
namespace fieldgate::ims {

inline constexpr char kLineFeed = '\n';
inline constexpr char kEscape = 0x1b;        // hard stop of every axis, clears the input line
inline constexpr char kControlC = 0x03;      // software reset of every axis
inline constexpr char kSoftStop = '@';       // soft stop, typed Global
inline constexpr char kGlobalAddress = '*';  // "all axes", firmware 1.15 and later

// Names a unit can be given (§2): A–Z, a–z and 0x5B–0x60 ([ \ ] ^ _ `).
bool valid_name(char c);
// A config address is exactly one valid name character; error says why not.
std::optional<char> parse_name(std::string_view text, std::string& error);

// What a command does on a party line; decides echo, result line, guards and what a model may
// use where.
enum class CommandClass {
  query,      // Z z ^ ] A129 [ : echo, then a result line
  parameter,  // B D E H I K T V Y l A(write) d e h r s t v k : echo, completion
  index,      // + - R F G : starts motion; a second one queues and stalls the unit
  velocity,   // M : constant velocity, changes on the fly
  origin,     // O o : set origin, refused while moving
  eeprom,     // S C \ : writes (or erases) the EEPROM
  no_echo,    // P Q q X : no echo in party mode (§2)
  wait,       // W : holds its echoed LF until the motion ends
  soft_stop,  // @ : typed Global
  hard_stop,  // ESC
  reset,      // ^C
  program,    // J j L y : program-only or program flow
  unknown,
};
CommandClass classify(std::string_view command);

// The data fields of a command: at most two decimal numbers with an optional sign and up to two
// decimals, separated by spaces (§1 "Line syntax"). nullopt if the text after the command
// character is anything else.
struct CommandData {
  std::vector<double> fields;
};
std::optional<CommandData> parse_data(std::string_view after_command_character);

// Rewrites what a template can produce but a unit does not accept: a relative index rendered
// with a signed distance ("+-500" is sent as "-500", "--500" as "+500").
std::string normalize_command(std::string_view command);

// `<name><command>\n`, the addressed form.
std::string encode_line(char name, std::string_view command);
// The global form of a command for every axis: ESC and ^C alone, "@[0|1]\n", else "*<cmd>\n".
std::string encode_global(std::string_view command);
// True for the commands a bus-wide request may carry without the global address: ESC, ^C, @.
bool is_global_character_command(std::string_view command);

// Length of the first LF-terminated line in buf, or 0 while no LF has arrived.
std::size_t line_length(std::string_view buf);

// A line made of CR and LF only: a completion, possibly a late one from an earlier command.
bool is_blank_line(std::string_view line);

// What a unit in Single mode sends back to `<name><command>\n` (p.10-11): the name, and the
// command if it has signed on, every character echoed but the LF, which is no terminator there
// (CR is), so the line never ends. A party-line unit never echoes that without the LF; one such
// echo may still be a cut line, so the family waits for it twice in a row.
bool single_mode_echo(char name, std::string_view command, std::string_view partial);

enum class EchoMatch { with_name, without_name, mismatch };
// Compares an echo line (LF included) with what was sent. The manual does not say whether the
// name is echoed (§2, §10.1), so both forms match; CRs before the echo (a late completion) are
// ignored.
EchoMatch match_echo(char name, std::string_view command, std::string_view echo);

// A result line: space padding, one or more signed decimals (optionally with .d or .dd), CR LF
// (a missing CR is tolerated). Values are rounded to whole counts; `hundredths` keeps the VR
// fraction. nullopt for anything else.
struct ResultLine {
  std::vector<int64_t> values;
  std::vector<int64_t> hundredths;
};
std::optional<ResultLine> parse_result(std::string_view line);

// How a unit lays out what follows the echoed command (issue 20: the manual supports several
// readings, README "Reply layouts"). One line, LF included:
//   [CR…][name]<command>LF              the echo alone (the LF echoed at once)
//   [CR…][name]<command>CR LF           the echo, its LF held until execution, with the CR of
//                                       "execution complete" (or of the result) before it
//   [CR…][name]<command>[ …]<number>[ …][CR]LF   a query's result on the echo's line
struct EchoLine {
  EchoMatch match = EchoMatch::mismatch;
  bool carriage_return = false;      // a CR before the line's LF
  std::optional<ResultLine> result;  // a value after the echoed command
  std::string rest;                  // what followed the echoed command, CR LF removed
};
EchoLine parse_echo_line(char name, std::string_view command, std::string_view line);

// A line that arrived outside any exchange that wanted it (drained, flushed, or in the place of
// another unit's echo): what it says about the replies still on their way.
enum class StrayLine {
  blank,       // CR/LF only: a completion
  result,      // a number line: a result some unit owed
  query_echo,  // an echo of a query alone: its result is still to come
  other,       // an echo with its result, a non-query echo, noise
};
StrayLine classify_stray(std::string_view line);

// `^` status bits (§4).
namespace status {
inline constexpr int64_t moving = 1;
inline constexpr int64_t constant_velocity = 2;
inline constexpr int64_t homing = 8;
inline constexpr int64_t hunting = 16;
inline constexpr int64_t ramping = 32;
inline constexpr int64_t meaningful = 0x3b;  // "Ignore the others"
}  // namespace status

// Line limit of §1: 12 characters including spaces.
inline constexpr std::size_t kLineLimit = 12;

// "AZ\n" -> "AZ\\n", for reply texts.
std::string printable(std::string_view bytes);

}  // namespace fieldgate::ims
