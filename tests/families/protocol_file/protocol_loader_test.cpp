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

}  // namespace
}  // namespace fieldgate::protocol_file
