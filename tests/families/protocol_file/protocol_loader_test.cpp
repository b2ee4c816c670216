// Protocol files as fieldgate check reads them: every shipped file loads, and a broken one is
// refused at the file:line:column of what is wrong, with what is wrong.
#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

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

}  // namespace
}  // namespace fieldgate::protocol_file
