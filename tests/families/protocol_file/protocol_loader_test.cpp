// Protocol files as fieldgate check reads them: every shipped file loads, and a broken one is
// refused at the file:line:column of what is wrong, with what is wrong.
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>

#include "drivers/protocol_file/protocol_loader.hpp"

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

struct Broken {
  const char* what;
  std::string text;
  int line;
  int column;
  const char* says;
};

void PrintTo(const Broken& b, std::ostream* os) {
  *os << b.what;
}

class BrokenProtocolFile : public ::testing::TestWithParam<Broken> {};

TEST_P(BrokenProtocolFile, IsRefusedWhereItIsBroken) {
  const Broken& b = GetParam();
  Diagnostics d;
  EXPECT_FALSE(load_protocol_text(b.text, "broken.yaml", d));
  ASSERT_FALSE(d.ok());
  const auto& first = d.errors().front();
  EXPECT_TRUE(first.mark.file.ends_with("/broken.yaml")) << first.mark.file;
  EXPECT_EQ(first.mark.line, b.line) << d.to_text();
  EXPECT_EQ(first.mark.column, b.column) << d.to_text();
  EXPECT_NE(first.message.find(b.says), std::string::npos) << d.to_text();
}

INSTANTIATE_TEST_SUITE_P(
    TenWays, BrokenProtocolFile,
    ::testing::Values(
        Broken{"unknown_capture_type",
               with(kGood, R"("{addr}TS{s:hex(2)}")", R"("{addr}TS{s:float}")"), 6, 21,
               "unknown field type 'float'"},
        Broken{"pattern_that_can_never_match",
               with(kGood, R"("{addr}TS{s:hex(2)}")", R"("{addr}TS{a:int}{b:int}")"), 6, 21,
               "could never match"},
        Broken{"command_without_its_reply", with(kGood, "    reply: \"{addr}TS{s:hex(2)}\"\n", ""),
               5, 5, "'reply' is missing"},
        Broken{"silent_command_nothing_confirms",
               with(kGood, R"(reply: "{addr}TS{s:hex(2)}")", "reply: none"), 5, 5,
               "nothing would prove it took the command"},
        Broken{"confirmation_by_an_unknown_command",
               with(kGood, R"(reply: "{addr}TS{s:hex(2)}")", "reply: none\n    confirm: read_eror"),
               7, 14, "no command 'read_eror'"},
        Broken{"error_capture_the_reply_lacks", with(kGood, "capture: c,", "capture: code,"), 10,
               22, "capture 'code'"},
        Broken{
            "flag_of_a_missing_capture",
            with(kGood, "    reply: \"{addr}TS{s:hex(2)}\"\n",
                 "    reply: \"{addr}TS{s:hex(2)}\"\n    flags: {moving: {capture: st, bit: 0}}\n"),
            7, 31, "capture 'st'"},
        Broken{"alignment_of_one_query", with(kGood, "[state, error]", "[state]"), 11, 12,
               "at least two"},
        Broken{"alignment_steps_alike",
               with(kGood, R"(reply: "{addr}TS{s:hex(2)}")", R"(reply: "{addr}TE{s:char}")"), 11,
               20, "a late answer to one would pass for the other"},
        Broken{"read_back_in_another_scale",
               with(kGood, "alignment:",
                    "  move:\n    send: \"{addr}PA{target:decimal(4)}\"\n    reply: none\n"
                    "    confirm: [{command: target, capture: t, equals: target}]\n"
                    "  target:\n    send: \"{addr}PA?\"\n    reply: \"{addr}PA{t:decimal(2)}\"\n"
                    "alignment:"),
               14, 15, "would never compare equal"},
        Broken{"unknown_key", with(kGood, "address:", "framing: {terminator: \"\\r\"}\naddress:"),
               2, 11, "terminator"},
        Broken{"address_range_upside_down", with(kGood, "[1, 9]", "[9, 1]"), 2, 18,
               "lowest address"}));

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

}  // namespace
}  // namespace fieldgate::protocol_file
