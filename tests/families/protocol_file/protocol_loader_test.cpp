// Protocol files as fieldgate check reads them: every shipped file loads, and a broken one is
// refused at the file:line:column of what is wrong, with what is wrong.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "drivers/protocol_file/protocol_file_family.hpp"
#include "drivers/protocol_file/protocol_loader.hpp"
#include "mapping/model_loader.hpp"

namespace fieldgate::protocol_file {
namespace {

// A small valid file; each broken case below changes one thing.
constexpr const char* kGood = R"(protocol: test-line
address: {range: [1, 9]}
commands:
  state:
    send: "{addr}TS"
    reply: "{addr}TS{s:hex(2)}"
  error:
    send: "{addr}TE"
    reply: "{addr}TE{c:char}"
    error: {capture: c, ok: "@"}
alignment: [state, error]
)";

// The text as a protocol file named `name` (in a scratch folder of this process), loaded.
ProtocolSpecPtr load_protocol_text(const std::string& text, const std::string& name,
                                   Diagnostics& d) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("fieldgate-protocol-test-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto path = (dir / name).string();
  std::ofstream(path) << text;
  return load_protocol_file(path, d);
}

std::string with(std::string text, std::string_view from, std::string_view to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// tests/families/protocol_file/broken/: each file is broken in one way and says on its second
// line where and how it must be refused, "# expect: LINE:COLUMN: TEXT" (the same files
// check_broken_files.sh gives `fieldgate check --protocol`).
struct Broken {
  std::string path;
  int line = 0;
  int column = 0;
  std::string says;
};

void PrintTo(const Broken& b, std::ostream* os) {
  *os << std::filesystem::path(b.path).filename().string();
}

std::vector<Broken> broken_files() {
  std::vector<Broken> files;
  const auto dir =
      std::filesystem::path(FIELDGATE_SOURCE_DIR) / "tests/families/protocol_file/broken";
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() != ".yaml") continue;
    Broken b;
    b.path = entry.path().string();
    std::ifstream in(b.path);
    std::string comment, expect;
    std::getline(in, comment);
    std::getline(in, expect);
    char colon1 = 0, colon2 = 0;
    std::istringstream fields(expect.substr(expect.find(':') + 1));
    fields >> b.line >> colon1 >> b.column >> colon2;
    std::getline(fields >> std::ws, b.says);
    files.push_back(b);
  }
  std::sort(files.begin(), files.end(),
            [](const Broken& a, const Broken& b) { return a.path < b.path; });
  return files;
}

class BrokenProtocolFile : public ::testing::TestWithParam<Broken> {};

TEST_P(BrokenProtocolFile, IsRefusedWhereItSaysItIsBroken) {
  const Broken& b = GetParam();
  ASSERT_GT(b.line, 0) << b.path << ": no '# expect: LINE:COLUMN: TEXT' on its second line";
  Diagnostics d;
  EXPECT_FALSE(load_protocol_file(b.path, d));
  ASSERT_FALSE(d.ok());
  const auto& first = d.errors().front();
  EXPECT_EQ(first.mark.file, b.path);
  EXPECT_EQ(first.mark.line, b.line) << d.to_text();
  EXPECT_EQ(first.mark.column, b.column) << d.to_text();
  EXPECT_NE(first.message.find(b.says), std::string::npos) << d.to_text();
}

TEST(BrokenProtocolFiles, AtLeastTenWaysAreThere) {
  EXPECT_GE(broken_files().size(), 10u);
}

INSTANTIATE_TEST_SUITE_P(Files, BrokenProtocolFile, ::testing::ValuesIn(broken_files()),
                         [](const ::testing::TestParamInfo<Broken>& info) {
                           std::string name =
                               std::filesystem::path(info.param.path).stem().string();
                           std::replace(name.begin(), name.end(), '-', '_');
                           return "file_" + name;
                         });

TEST(ProtocolFiles, EveryShippedProtocolFileLoads) {
  Diagnostics d;
  ProtocolLibrary library;
  library.load_directory(std::string(FIELDGATE_SOURCE_DIR) + "/config/protocols", d);
  EXPECT_TRUE(d.ok()) << d.to_text();
  EXPECT_TRUE(library.find("newport-smc100"));
  EXPECT_TRUE(library.find("newport-esp301"));
  EXPECT_TRUE(library.find("parker-6k"));
}

TEST(ProtocolFiles, TheGoodFileLoadsWithItsProof) {
  Diagnostics d;
  const auto spec = load_protocol_text(kGood, "good.yaml", d);
  ASSERT_TRUE(spec) << d.to_text();
  EXPECT_EQ(spec->name, "test-line");
  ASSERT_EQ(spec->alignment.size(), 2u);
  EXPECT_EQ(spec->alignment[0].command, "state");
  EXPECT_EQ(spec->alignment[1].command, "error");
  EXPECT_EQ(spec->address_text(7), "7");
}

TEST(ProtocolFiles, StartupStepsAndAlignmentStepsInTheirLongForm) {
  Diagnostics d;
  const auto spec = load_protocol_text(
      with(with(kGood, "alignment: [state, error]",
                "  mode:\n    send: \"{addr}M{m:int}\"\n    reply: \"{addr}M{m:int}\"\n"
                "error_reply: {pattern: \"E{n:int}\", code: n}\n"
                "startup:\n  - {command: mode, arguments: [3], tolerate_errors: true}\n"
                "alignment:\n  - {command: state, error: 7}\n  - error\n"),
           "", ""),
      "long.yaml", d);
  ASSERT_TRUE(spec) << d.to_text();
  ASSERT_EQ(spec->startup.size(), 1u);
  EXPECT_EQ(spec->startup[0].command, "mode");
  EXPECT_EQ(spec->startup[0].arguments, std::vector<int64_t>{3});
  EXPECT_TRUE(spec->startup[0].tolerate_errors);
  ASSERT_EQ(spec->alignment.size(), 2u);
  EXPECT_EQ(spec->alignment[0].error, 7);
  EXPECT_FALSE(spec->alignment[1].error);
}

TEST(ProtocolFiles, ANameTakenByABuiltInFamilyIsRefused) {
  Diagnostics d;
  EXPECT_FALSE(load_protocol_text(with(kGood, "test-line", "copley-ascii"), "p.yaml", d));
  EXPECT_NE(d.to_text().find("built-in family"), std::string::npos) << d.to_text();
}

// Issue 50's defects: what check accepted and must not. Each is refused where it is written, with
// what to do.

// The one error a broken text gives, as "LINE:COLUMN: MESSAGE" (the file name checked apart).
std::string only_error(const Diagnostics& d, const std::string& file) {
  if (d.errors().size() != 1) return "not one error: " + d.to_text();
  const auto& e = d.errors().front();
  EXPECT_EQ(std::filesystem::path(e.mark.file).filename().string(), file);
  return std::to_string(e.mark.line) + ":" + std::to_string(e.mark.column) + ": " + e.message;
}

std::string with_framing(const std::string& reply_terminator, const std::string& error_terminator) {
  return with(kGood, "address:",
              "framing:\n  reply_terminator: \"" + reply_terminator + "\"\n  error_terminator: \"" +
                  error_terminator + "\"\naddress:");
}

TEST(ProtocolFileDefects, AnErrorTerminatorThatIsTheReplyTerminatorIsRefusedAtItsLine) {
  Diagnostics d;
  EXPECT_FALSE(load_protocol_text(with_framing("\\r\\n", "\\r\\n"), "same.yaml", d));
  EXPECT_EQ(only_error(d, "same.yaml"),
            "4:21: framing: error_terminator '\\r\\n' is the reply_terminator, so every reply "
            "would read as refused: give the ending only a refused reply has (Parker 6K: "
            "reply_terminator '\\r\\n> ', error_terminator '\\r\\n? ')");
}

TEST(ProtocolFileDefects, TerminatorsThatCannotBeToldApartAsTheyArriveAreRefused) {
  Diagnostics part;
  EXPECT_FALSE(load_protocol_text(with_framing("\\r\\n> ", "\\r\\n"), "part.yaml", part));
  EXPECT_NE(only_error(part, "part.yaml")
                .find("4:21: framing: error_terminator '\\r\\n' is part of the reply_terminator "
                      "'\\r\\n> ', so a reply would read as refused"),
            std::string::npos)
      << part.to_text();
  Diagnostics holds;
  EXPECT_FALSE(load_protocol_text(with_framing("\\r\\n", "\\r\\nERR\\r\\n"), "holds.yaml", holds));
  EXPECT_NE(only_error(holds, "holds.yaml")
                .find("4:21: framing: error_terminator '\\r\\nERR\\r\\n' holds the "
                      "reply_terminator '\\r\\n' before its end, so a refusal would be cut there"),
            std::string::npos)
      << holds.to_text();
}

TEST(ProtocolFileDefects, TerminatorsThatCanBeToldApartLoad) {
  for (const auto& [reply, error] : {std::pair{"\\r\\n> ", "\\r\\n? "},  // Parker 6K
                                     std::pair{"\\r\\n", "?\\r\\n"}}) {  // a refusal ends in '?'
    Diagnostics d;
    EXPECT_TRUE(load_protocol_text(with_framing(reply, error), "apart.yaml", d)) << d.to_text();
  }
}

// A protocol file with a char parameter (the axis letter a controller is switched to).
std::string with_axis_command(const std::string& startup) {
  return with(
      kGood, "alignment:",
      "  axis:\n    send: \"{addr}AX{letter:char}\"\n    reply: \"\"\n" + startup + "alignment:");
}

TEST(ProtocolFileDefects, AStartUpCharArgumentOf300IsRefusedAtTheArgument) {
  Diagnostics d;
  EXPECT_FALSE(load_protocol_text(
      with_axis_command("startup:\n  - {command: axis, arguments: [300]}\n"), "char.yaml", d));
  EXPECT_EQ(only_error(d, "char.yaml"),
            "15:33: startup: axis argument 1 (300) cannot be sent: {letter:char}: 300 is not the "
            "code of a printable character (32..126)");
  Diagnostics good;
  EXPECT_TRUE(load_protocol_text(
      with_axis_command("startup:\n  - {command: axis, arguments: [0x41]}\n"), "a.yaml", good))
      << good.to_text();
}

TEST(ProtocolFileDefects, ADiscoverCountItsFieldCannotCarryIsRefused) {
  Diagnostics d;
  EXPECT_FALSE(load_protocol_text(
      with(kGood, "alignment:",
           "  probe:\n    send: \"{n:int(1)}MO?\"\n    reply: \"{on:int}\"\n"
           "startup:\n  - discover: {command: probe, to: 12, until_error: 9}\nalignment:"),
      "count.yaml", d));
  EXPECT_EQ(only_error(d, "count.yaml"),
            "15:36: discover: probe argument 1 (12) cannot be sent: {n:int(1)}: 12 needs 2 "
            "characters");
}

TEST(ProtocolFileDefects, AConfirmationThatComparesATextCaptureWithNumbersIsRefused) {
  Diagnostics d;
  EXPECT_FALSE(load_protocol_text(
      with(kGood, "alignment:",
           "  message:\n    send: \"{addr}MS\"\n    reply: \"{addr}MS{m:text}\"\n"
           "  go:\n    send: \"{addr}GO\"\n    reply: none\n"
           "    confirm: {command: message, capture: m, in: [0]}\nalignment:"),
      "in.yaml", d));
  EXPECT_EQ(only_error(d, "in.yaml"),
            "17:14: command go confirm: message's {m:text} is text, which 'in:' cannot compare "
            "with numbers: capture the state as a number (int, hex, char, bits(N)) or confirm "
            "with the command alone");
}

TEST(ProtocolFileDefects, APlaceholderInAFlowListGetsAHint) {
  Diagnostics d;
  EXPECT_FALSE(load_protocol_text(with(kGood, "alignment:",
                                       "  go:\n    send: \"{addr}GO\"\n    reply: none\n"
                                       "    confirm: [error, {addr}TE]\nalignment:"),
                                  "flow.yaml", d));
  EXPECT_EQ(only_error(d, "flow.yaml"),
            "14:28: YAML syntax: end of sequence flow not found; a {placeholder} inside a YAML "
            "flow list [...] starts a mapping there: quote the step or use a block list (one '- ' "
            "line per step)");
}

TEST(ProtocolFileDefects, OtherYamlSyntaxErrorsGetNoHint) {
  EXPECT_EQ(flow_collection_hint("YAML syntax: end of sequence flow not found", "  x: [a, b"), "");
  EXPECT_EQ(flow_collection_hint("YAML syntax: illegal map value", "  steps: [move {target}]"), "");
  EXPECT_NE(flow_collection_hint("YAML syntax: end of map flow not found",
                                 "  read: {send: {addr}TP, reply: none}"),
            "");
}

// A protocol file with a reply of a number and a text, and a char parameter, and models of it.
constexpr const char* kVersionCommands = R"(  version:
    send: "{addr}VE"
    reply: "{addr}VE{release:int} {model:text}"
  axis:
    send: "{addr}AX{letter:char}"
    reply: ""
)";

Diagnostics validated(const std::string& model_text) {
  Diagnostics d;
  const auto spec = load_protocol_text(
      with(kGood, "alignment:", kVersionCommands + std::string("alignment:")), "text.yaml", d);
  EXPECT_TRUE(spec) << d.to_text();
  const auto model = load_model_text(model_text, "m.yaml", d);
  EXPECT_TRUE(model) << d.to_text();
  if (spec && model) ProtocolFileFamily(spec).validate_model(*model, d);
  return d;
}

TEST(ProtocolFileDefects, ATextCaptureFeedingANumericPointIsALoadError) {
  const auto d = validated(R"(model: m
family: test-line
poll_classes: {slow: 1s}
points:
  release: {type: uint16, read: {request: version, field: 0}, poll: slow}
  firmware: {type: int32, read: {request: version, field: 1}, poll: slow}
)");
  const std::string error = only_error(d, "m.yaml");
  EXPECT_EQ(error.substr(0, error.find('(')),
            "6:13: point firmware read: value 1 of version is {model:text} ");
  EXPECT_NE(error.find("text.yaml:13:35: '{addr}VE{release:int} {model:text}'), which no int32 "
                       "point can hold: capture a number there in the protocol file (int, "
                       "decimal(S), hex, char or bits(N)), or read another value of version"),
            std::string::npos)
      << error;
}

TEST(ProtocolFileDefects, ATextCaptureFeedsNoPointOfAnyType) {
  for (const char* type : {"bool", "int16", "uint16", "uint32"}) {
    const auto d = validated(fmt::format(R"(model: m
family: test-line
poll_classes: {{slow: 1s}}
points:
  firmware: {{type: {}, read: {{request: version, field: 1}}, poll: slow}}
)",
                                         type));
    EXPECT_NE(only_error(d, "m.yaml").find(fmt::format("which no {} point can hold", type)),
              std::string::npos)
        << d.to_text();
  }
}

TEST(ProtocolFileDefects, AModelCharArgumentOf300IsALoadErrorAtTheStep) {
  const auto d = validated(R"(model: m
family: test-line
actions:
  select_a: {code: 1, steps: [axis 65]}
  select:
    code: 2
    steps:
      - axis 300
)");
  EXPECT_EQ(only_error(d, "m.yaml"),
            "8:9: action select: 'axis 300': axis argument 1 (300) cannot be sent: "
            "{letter:char}: 300 is not the code of a printable character (32..126)");
}

// Issue 50's format: numbers as the controller prints them, a refusal explained by a follow-up
// query, a line of several commands answered by a prompt each.
ProtocolSpecPtr galil_style(Diagnostics& d) {
  return load_protocol_file(
      std::string(FIELDGATE_SOURCE_DIR) + "/tests/families/protocol_file/galil-style.yaml", d);
}

const Field& reply_field_of(const ProtocolSpec& spec, std::string_view command,
                            std::string_view name) {
  static const Field none;
  const CommandSpec* c = spec.find(command);
  if (!c || !c->reply) return none;
  for (const auto& piece : c->reply->pieces())
    if (piece.field && piece.field->name == name) return *piece.field;
  return none;
}

TEST(ProtocolFileFormat, TheFilesNumbersApplyToEveryReplyAndACapturesKeysOverrideThem) {
  Diagnostics d;
  const auto spec = galil_style(d);
  ASSERT_TRUE(spec) << d.to_text();
  using Sign = NumberFormat::Sign;
  const Field& position = reply_field_of(*spec, "read_position", "position");
  ASSERT_TRUE(position.number);
  EXPECT_EQ(position.number->sign, Sign::space_or_minus);
  EXPECT_EQ(position.number->pad, NumberFormat::Pad::none);
  EXPECT_EQ(position.width, 0);
  const Field& padded = reply_field_of(*spec, "read_padded", "position");
  ASSERT_TRUE(padded.number);
  EXPECT_EQ(padded.number->sign, Sign::space_or_minus);
  EXPECT_EQ(padded.number->pad, NumberFormat::Pad::zeros);
  EXPECT_EQ(padded.width, 11);
  const Field& code = reply_field_of(*spec, "tell_error", "code");
  ASSERT_TRUE(code.number);
  EXPECT_EQ(code.number->sign, Sign::minus);
  const Field& moving = reply_field_of(*spec, "read_moving", "moving");
  ASSERT_TRUE(moving.number);
  EXPECT_EQ(moving.number->form, NumberFormat::Form::decimal);
  EXPECT_EQ(moving.number->places, 4);
  const Field& speed = reply_field_of(*spec, "read_speed", "speed");
  ASSERT_TRUE(speed.number);
  EXPECT_EQ(speed.number->form, NumberFormat::Form::exponent);
  EXPECT_EQ(spec->refusal_query, "tell_error");
}

TEST(ProtocolFileFormat, WithoutNumbersNoFieldIsDeclared) {
  Diagnostics d;
  const auto spec = load_protocol_text(kGood, "good.yaml", d);
  ASSERT_TRUE(spec) << d.to_text();
  for (const auto& c : spec->commands)
    for (const auto& piece : c.reply->pieces())
      EXPECT_FALSE(piece.field && piece.field->number) << c.name;
  Diagnostics shipped;
  ProtocolLibrary library;
  library.load_directory(std::string(FIELDGATE_SOURCE_DIR) + "/config/protocols", shipped);
  // Galil declares its numbers and its compound lines; every other shipped file declares none,
  // and reads as it did before those keys existed.
  for (const auto& p : library.all()) {
    if (p->name == "galil-dmc") continue;
    for (const auto& c : p->commands) {
      EXPECT_EQ(c.prompts(), 1u) << p->name << " " << c.name;
      if (!c.reply) continue;
      for (const auto& piece : c.reply->pieces())
        EXPECT_FALSE(piece.field && piece.field->number) << p->name << " " << c.name;
    }
  }
  EXPECT_NE(library.find("galil-dmc"), nullptr);
}

TEST(ProtocolFileFormat, PromptsComeFromTheLineTheListOrTheCount) {
  Diagnostics d;
  const auto spec = galil_style(d);
  ASSERT_TRUE(spec) << d.to_text();
  // PAA=..;BGA: two commands by the separator, each a bare prompt.
  const CommandSpec& move = *spec->find("move_absolute");
  EXPECT_EQ(move.prompts(), 2u);
  EXPECT_EQ(move.reply->source(), ":");
  EXPECT_FALSE(move.reply_has_text());
  const CommandSpec& both = *spec->find("move_and_read");
  EXPECT_EQ(both.prompts(), 2u);
  EXPECT_EQ(both.reply->source(), ":{position:int}\r\n");
  EXPECT_TRUE(both.reply_has_text());
  EXPECT_EQ(spec->find("stop")->prompts(), 1u);
  EXPECT_EQ(spec->find("motor_off")->prompts(), 1u);
  // A capture in a later part is marked where that part is written.
  const auto mark = both.capture_mark(reply_field_of(*spec, "move_and_read", "position"));
  EXPECT_EQ(mark.line, 45);
  EXPECT_EQ(mark.column, 20);
}

TEST(ProtocolFileFormat, AnExplicitCountPutsBarePromptsBeforeTheReply) {
  Diagnostics d;
  const auto spec = load_protocol_text(
      with(kGood, "alignment:",
           "  two:\n    send: \"{addr}PA{t:int}\"\n    reply: \"{addr}PA{t:int}\"\n"
           "    prompts: 3\nalignment:"),
      "count.yaml", d);
  ASSERT_TRUE(spec) << d.to_text();
  const CommandSpec& two = *spec->find("two");
  EXPECT_EQ(two.prompts(), 3u);
  EXPECT_EQ(two.reply->source(), "\r\n\r\n{addr}PA{t:int}");
}

// A reply prefix (Parker's '*') comes before each part with text, not before a bare prompt.
TEST(ProtocolFileFormat, EachPartWithTextHasTheReplyPrefix) {
  Diagnostics d;
  const auto spec = load_protocol_text(
      with(with(kGood, "address:",
                "framing: {reply_terminator: \"\\r\\n> \", reply_prefix: \"*\", "
                "command_separator: \";\"}\naddress:"),
           "alignment:",
           "  go_and_read:\n    send: \"{addr}GO;{addr}TPC\"\n    reply: \"{addr}TPC{p:int}\"\n"
           "alignment:"),
      "prefix.yaml", d);
  ASSERT_TRUE(spec) << d.to_text();
  const CommandSpec& c = *spec->find("go_and_read");
  EXPECT_EQ(c.reply->source(), "\r\n> *{addr}TPC{p:int}");
  const auto r = interpret_reply(*spec, c, "1GO;1TPC\r", "\r\n> *1TPC-5\r\n> ", "1");
  ASSERT_EQ(r.reply.status, Reply::Status::ok) << r.reply.text;
  EXPECT_EQ(r.reply.values, std::vector<int64_t>{-5});
  EXPECT_EQ(interpret_reply(*spec, c, "1GO;1TPC\r", "*\r\n> *1TPC-5\r\n> ", "1").reply.status,
            Reply::Status::garbled);
  const auto mark = c.capture_mark(*c.reply->named_fields().front());
  EXPECT_EQ(mark.line, 14);
  EXPECT_EQ(mark.column, 22);
}

// Each of the format's load errors, at its file:line:column (the broken/ files hold one each).
std::string error_of(const std::string& text) {
  Diagnostics d;
  EXPECT_FALSE(load_protocol_text(text, "f.yaml", d));
  return only_error(d, "f.yaml");
}

std::string with_command(const std::string& command, const std::string& top = "") {
  return with(with(kGood, "alignment:", command + "alignment:"), "commands:", top + "commands:");
}

TEST(ProtocolFileFormat, NumberDeclarationsAreCheckedAgainstTheirField) {
  const std::string position = "  position:\n    send: \"{addr}TP\"\n    reply: ";
  EXPECT_EQ(error_of(with_command(position + "\"{addr}TP{p:int}\"\n    numbers: {q: {}}\n")),
            "14:15: command position: numbers names capture 'q', which its reply '{addr}TP{p:int}' "
            "does not have (captures: p)");
  EXPECT_NE(error_of(with_command(position + "\"{addr}TP{p:int}\"\n    numbers: {p: {sign: "
                                             "minus, spin: up}}\n"))
                .find("14:32: command position numbers p: unknown key 'spin'"),
            std::string::npos);
  EXPECT_EQ(
      error_of(with_command(position + "\"{addr}TP{p:int}\"\n    numbers: {p: {pad: spaces}}\n")),
      "14:24: command position numbers p pad: spaces fills a fixed width, and {p:int} has "
      "none: give width: N");
  EXPECT_EQ(error_of(with_command(position + "\"{addr}TP{p:int}\"\n    numbers: {p: {width: 0, "
                                             "pad: zeros}}\n")),
            "14:26: command position numbers p width: 0 is out of range 1..32");
  EXPECT_EQ(error_of(with_command(position + "\"{addr}TP{p:int}\"\n    numbers: {p: {form: "
                                             "decimal}}\n")),
            "14:25: command position numbers p form: decimal: {p:int} counts whole units; a "
            "number with decimals is a decimal(S) field (decimal(0) rounds it to a whole count)");
  // The file's numbers take sign and pad only: a width is one capture's.
  EXPECT_NE(error_of(with_command("", "numbers: {sign: minus, width: 4}\n")).find("width"),
            std::string::npos);
  EXPECT_NE(error_of(with_command("", "numbers: {pad: none}\n")).find("is one of zeros, spaces"),
            std::string::npos);
}

TEST(ProtocolFileFormat, AFileLevelFormatAppliesToErrorReplies) {
  Diagnostics d;
  const auto spec = load_protocol_text(
      with(kGood, "commands:",
           "numbers: {sign: plus_or_minus}\nerror_reply: {pattern: \"E{n:int}\", code: n}\n"
           "commands:"),
      "e.yaml", d);
  ASSERT_TRUE(spec) << d.to_text();
  const auto& f = *spec->error_reply->pieces()[1].field;
  ASSERT_TRUE(f.number);
  EXPECT_EQ(f.number->sign, NumberFormat::Sign::plus_or_minus);
  const auto refused = interpret_reply(*spec, *spec->find("state"), "1TS\r", "E+5\r\n", "1");
  EXPECT_EQ(refused.reply.device_code, 5);
  // An error reply printed otherwise is no refusal: the reply is garbled.
  EXPECT_EQ(interpret_reply(*spec, *spec->find("state"), "1TS\r", "E5\r\n", "1").reply.status,
            Reply::Status::garbled);
}

TEST(ProtocolFileFormat, ARefusalQueryMustBeAnErrorQueryOfAFileWithCodelessRefusals) {
  const std::string framing = "framing: {reply_terminator: \":\", error_terminator: \"?\"}\n";
  EXPECT_EQ(error_of(with_command("", framing + "refusal_query: state\n")),
            "4:16: refusal_query: state must be a query of the device's last error: a reply, an "
            "error check whose capture is the code (error: {capture, ok, text}), no parameters "
            "and no confirmation");
  EXPECT_EQ(error_of(with_command("", "refusal_query: error\n")),
            "3:16: refusal_query: this file has no refusal without a code to explain (a "
            "framing.error_terminator, or an error_reply without code)");
  Diagnostics d;
  EXPECT_TRUE(load_protocol_text(with_command("", framing + "refusal_query: error\n"), "q.yaml", d))
      << d.to_text();
  Diagnostics codeless;
  const auto spec = load_protocol_text(
      with_command("", "error_reply: {pattern: \"NAK {m:text}\", text: m}\nrefusal_query: error\n"),
      "n.yaml", codeless);
  ASSERT_TRUE(spec) << codeless.to_text();
  // An error reply without a code is explained by the query's error check: its code, and the
  // meaning the errors table or the query's text gives.
  const auto refusal = interpret_reply(*spec, *spec->find("state"), "1TS\r", "NAK busy\r\n", "1");
  ASSERT_TRUE(refusal.refusal_without_code);
  const CommandSpec& query = *spec->find("error");
  const auto answer = interpret_reply(*spec, query, "1TE\r", "1TEC\r\n", "1");
  const auto explained = explain_refusal(*spec, query, refusal.reply, answer);
  EXPECT_EQ(explained.status, Reply::Status::device_error);
  EXPECT_EQ(explained.device_code, 'C');
  EXPECT_EQ(explained.text, "state refused: NAK busy (busy); error reports error C");
  const auto clean = interpret_reply(*spec, query, "1TE\r", "1TE@\r\n", "1");
  EXPECT_EQ(explain_refusal(*spec, query, refusal.reply, clean).device_code, kRefusalUnexplained);
  // A refusal with a code of its own needs no query.
  Diagnostics coded;
  const auto with_code = load_protocol_text(
      with_command("", "error_reply: {pattern: \"E{n:int}\", code: n}\n"), "c.yaml", coded);
  ASSERT_TRUE(with_code) << coded.to_text();
  EXPECT_FALSE(interpret_reply(*with_code, *with_code->find("state"), "1TS\r", "E5\r\n", "1")
                   .refusal_without_code);
}

TEST(ProtocolFileFormat, PromptsAndTheirListAreCheckedAgainstTheLine) {
  const std::string framing = "framing: {reply_terminator: \":\", command_separator: \";\"}\n";
  EXPECT_EQ(error_of(with_command("  move:\n    send: \"PA{t:int};BG\"\n    replies: [\"\", "
                                  "\"\", \"\"]\n",
                                  framing)),
            "14:14: command move: 'PA{t:int};BG' is a line of 2 commands (separated by ';'), each "
            "answered by its prompt, so its reply has 2 parts; replies gives 3");
  EXPECT_EQ(error_of(with_command("  move:\n    send: \"PA{t:int};BG\"\n    reply: \"\"\n    "
                                  "prompts: 17\n",
                                  framing)),
            "15:14: command move prompts: 17 is out of range 1..16");
  EXPECT_EQ(error_of(with_command("", "framing: {command_separator: \"\"}\n")),
            "3:30: framing: command_separator is the text between two commands of a line, e.g. "
            "';'");
  // An explicit count is the count, whatever the line holds.
  Diagnostics d;
  const auto spec = load_protocol_text(
      with_command("  move:\n    send: \"PA{t:int};BG\"\n    reply: \"\"\n    prompts: 1\n",
                   framing),
      "one.yaml", d);
  ASSERT_TRUE(spec) << d.to_text();
  EXPECT_EQ(spec->find("move")->prompts(), 1u);
}

}  // namespace
}  // namespace fieldgate::protocol_file
