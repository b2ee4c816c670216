// The SDO client with frames in memory and injected time: no socket, no sleep. Frames are
// written in candump text, as candump -L logs them.
#include <gtest/gtest.h>

#include "drivers/canopen/sdo_client.hpp"
#include "object_dictionary.hpp"
#include "sdo_server.hpp"

namespace fieldgate::canopen {
namespace {

using namespace std::chrono_literals;

const TimePoint t0{std::chrono::seconds(1000)};

CanFrame frame(std::string_view text) {
  auto f = parse_frame(text);
  EXPECT_TRUE(f) << text;
  return f.value_or(CanFrame{});
}

std::string sent(const SdoStep& step) {
  return step.send ? to_string(*step.send) : "";
}

std::vector<uint8_t> bytes(std::string_view s) {
  return {s.begin(), s.end()};
}

std::string text(const std::vector<uint8_t>& v) {
  return {v.begin(), v.end()};
}

// The step ended the transfer with `status` and abort `code`; its text names the abort's
// meaning, where one is given.
void expect_ended(const SdoStep& step, SdoResult::Status status, uint32_t code,
                  std::string_view meaning = {}) {
  ASSERT_TRUE(step.done);
  EXPECT_EQ(step.done->status, status);
  EXPECT_EQ(step.done->abort_code, code);
  if (!meaning.empty()) {
    EXPECT_NE(step.done->text.find(meaning), std::string::npos) << step.done->text;
  }
}

// --- expedited and segmented, both directions ----------------------------------------------

TEST(SdoClient, ExpeditedUpload) {
  SdoClient c(2, 100ms);
  auto s = c.upload(0x1000, 0, t0);
  EXPECT_EQ(sent(s), "602#4000100000000000");
  EXPECT_FALSE(s.done);
  EXPECT_EQ(c.deadline(), t0 + 100ms);
  s = c.on_frame(frame("582#4300100092010200"), t0 + 1ms);
  EXPECT_EQ(sent(s), "");
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->status, SdoResult::Status::ok);
  EXPECT_EQ(s.done->data, (std::vector<uint8_t>{0x92, 0x01, 0x02, 0x00}));
  EXPECT_TRUE(c.idle());
  EXPECT_FALSE(c.deadline());
}

TEST(SdoClient, ExpeditedUploadSizes) {
  // n = 4 - size in bits 3..2 when s is set; 0x42 gives no size (4 bytes).
  const std::pair<const char*, std::size_t> cases[] = {{"582#4F41600018000000", 1},
                                                       {"582#4B41600018060000", 2},
                                                       {"582#4741600018060000", 3},
                                                       {"582#4241600018060000", 4}};
  for (const auto& [reply, size] : cases) {
    SdoClient c(2);
    c.upload(0x6041, 0, t0);
    auto s = c.on_frame(frame(reply), t0);
    ASSERT_TRUE(s.done) << reply;
    EXPECT_EQ(s.done->data.size(), size) << reply;
    EXPECT_EQ(s.done->data[0], 0x18) << reply;
  }
}

TEST(SdoClient, SegmentedUpload) {
  SdoClient c(3, 100ms);
  EXPECT_EQ(sent(c.upload(0x1008, 0, t0)), "603#4008100000000000");
  auto s = c.on_frame(frame("583#410810001B000000"), t0 + 1ms);  // 27 bytes announced
  EXPECT_EQ(sent(s), "603#6000000000000000");
  EXPECT_EQ(c.deadline(), t0 + 101ms);  // the timeout restarts with every request
  s = c.on_frame(frame("583#006669656C646761"), t0 + 2ms);  // "fieldga", toggle 0
  EXPECT_EQ(sent(s), "603#7000000000000000");
  s = c.on_frame(frame("583#1074652073696D20"), t0 + 3ms);  // "te sim ", toggle 1
  EXPECT_EQ(sent(s), "603#6000000000000000");
  s = c.on_frame(frame("583#0043694120343032"), t0 + 4ms);  // "CiA 402"
  EXPECT_EQ(sent(s), "603#7000000000000000");
  s = c.on_frame(frame("583#1320647269766500"), t0 + 5ms);  // " drive": n = 1, last
  EXPECT_EQ(sent(s), "");
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->status, SdoResult::Status::ok);
  EXPECT_EQ(text(s.done->data), "fieldgate sim CiA 402 drive");
}

TEST(SdoClient, SegmentedUploadWithoutSize) {
  SdoClient c(3);
  c.upload(0x1008, 0, t0);
  EXPECT_EQ(sent(c.on_frame(frame("583#4008100000000000"), t0)), "603#6000000000000000");
  auto s = c.on_frame(frame("583#0761786973000000"), t0);  // "axis": n = 3, last
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->status, SdoResult::Status::ok);
  EXPECT_EQ(text(s.done->data), "axis");
}

TEST(SdoClient, ExpeditedDownload) {
  SdoClient c(2);
  EXPECT_EQ(sent(c.download(0x1017, 0, {0xF4, 0x01}, t0)), "602#2B171000F4010000");
  auto s = c.on_frame(frame("582#6017100000000000"), t0);
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->status, SdoResult::Status::ok);
  EXPECT_EQ(sent(c.download(0x607A, 0, {0xD0, 0x07, 0, 0}, t0)), "602#237A6000D0070000");
  EXPECT_TRUE(c.on_frame(frame("582#607A600000000000"), t0).done);
  EXPECT_EQ(sent(c.download(0x6060, 0, {0x01}, t0)), "602#2F60600001000000");
  EXPECT_TRUE(c.on_frame(frame("582#6060600000000000"), t0).done);
  EXPECT_EQ(sent(c.download(0x2000, 0, {0x61, 0x62, 0x63}, t0)), "602#2700200061626300");
}

TEST(SdoClient, SegmentedDownload) {
  SdoClient c(2);
  // 18 bytes: 7 + 7 + 4
  auto s = c.download(0x2000, 0, bytes("fieldgate axis two"), t0);
  EXPECT_EQ(sent(s), "602#2100200012000000");
  s = c.on_frame(frame("582#6000200000000000"), t0);
  EXPECT_EQ(sent(s), "602#006669656C646761");  // "fieldga", toggle 0
  s = c.on_frame(frame("582#2000000000000000"), t0);
  EXPECT_EQ(sent(s), "602#1074652061786973");  // "te axis", toggle 1
  s = c.on_frame(frame("582#3000000000000000"), t0);
  EXPECT_EQ(sent(s), "602#072074776F000000");  // " two", n = 3, last
  EXPECT_FALSE(s.done);
  s = c.on_frame(frame("582#2000000000000000"), t0);
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->status, SdoResult::Status::ok);
  EXPECT_TRUE(c.idle());
}

TEST(SdoClient, EmptyDownloadIsOneEmptySegment) {
  SdoClient c(2);
  EXPECT_EQ(sent(c.download(0x2000, 0, {}, t0)), "602#2100200000000000");
  EXPECT_EQ(sent(c.on_frame(frame("582#6000200000000000"), t0)), "602#0F00000000000000");
  EXPECT_TRUE(c.on_frame(frame("582#2000000000000000"), t0).done);
}

// --- every abort path ----------------------------------------------------------------------

TEST(SdoClient, ServerAbortsUploadInitiate) {
  SdoClient c(2);
  c.upload(0x1234, 0, t0);
  auto s = c.on_frame(frame("582#8034120000000206"), t0);
  EXPECT_EQ(sent(s), "");  // nothing back to an abort
  ASSERT_NO_FATAL_FAILURE(expect_ended(s, SdoResult::Status::server_abort, 0x06020000u,
                                       "object does not exist in the object dictionary"));
  EXPECT_NE(s.done->text.find("0x06020000"), std::string::npos) << s.done->text;
}

TEST(SdoClient, ServerAbortsDownloadInitiate) {
  SdoClient c(2);
  c.download(0x1000, 0, {1, 2, 3, 4}, t0);
  auto s = c.on_frame(frame("582#8000100002000106"), t0);
  expect_ended(s, SdoResult::Status::server_abort, 0x06010002u,
               "attempt to write a read only object");
}

TEST(SdoClient, ServerAbortsUploadSegment) {
  SdoClient c(3);
  c.upload(0x1008, 0, t0);
  c.on_frame(frame("583#410810001B000000"), t0);
  auto s = c.on_frame(frame("583#8008100000000405"), t0);  // 0x05040000 timed out
  expect_ended(s, SdoResult::Status::server_abort, 0x05040000u, "SDO protocol timed out");
}

TEST(SdoClient, ServerAbortsDownloadSegment) {
  SdoClient c(2);
  c.download(0x2000, 0, bytes("too long for the label"), t0);
  c.on_frame(frame("582#6000200000000000"), t0);
  auto s = c.on_frame(frame("582#8000200010000706"), t0);  // 0x06070010 length
  expect_ended(s, SdoResult::Status::server_abort, 0x06070010u,
               "length of service parameter does not match");
}

TEST(SdoClient, AbortForAnotherObjectIsIgnored) {
  SdoClient c(2);
  c.upload(0x6041, 0, t0);
  auto s = c.on_frame(frame("582#8034120000000206"), t0);  // stale abort for 0x1234
  EXPECT_FALSE(s.done);
  EXPECT_EQ(c.ignored_frames(), 1u);
  EXPECT_TRUE(c.on_frame(frame("582#4B41600050020000"), t0).done);
}

TEST(SdoClient, UnknownCommandSpecifierIsAborted) {
  SdoClient c(2);
  c.upload(0x6041, 0, t0);
  auto s = c.on_frame(frame("582#6041600000000000"), t0);  // a download response
  EXPECT_EQ(sent(s), "602#8041600001000405");              // abort 0x05040001
  ASSERT_NO_FATAL_FAILURE(expect_ended(s, SdoResult::Status::client_abort, 0x05040001u));

  c.download(0x6040, 0, {6, 0}, t0);
  s = c.on_frame(frame("582#4B40600006000000"), t0);  // an upload response
  EXPECT_EQ(sent(s), "602#8040600001000405");
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->status, SdoResult::Status::client_abort);

  c.upload(0x1008, 0, t0);
  c.on_frame(frame("582#410810001B000000"), t0);
  s = c.on_frame(frame("582#2000000000000000"), t0);  // download segment response
  EXPECT_EQ(sent(s), "602#8008100001000405");
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->status, SdoResult::Status::client_abort);

  c.download(0x2000, 0, bytes("fieldgate"), t0);
  c.on_frame(frame("582#6000200000000000"), t0);
  s = c.on_frame(frame("582#4300200000000000"), t0);
  EXPECT_EQ(sent(s), "602#8000200001000405");
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->status, SdoResult::Status::client_abort);
}

TEST(SdoClient, UploadToggleErrorIsAborted) {
  SdoClient c(3);
  c.upload(0x1008, 0, t0);
  c.on_frame(frame("583#410810001B000000"), t0);
  auto s = c.on_frame(frame("583#106669656C646761"), t0);  // toggle 1 where 0 is due
  EXPECT_EQ(sent(s), "603#8008100000000305");              // 0x05030000
  expect_ended(s, SdoResult::Status::client_abort, 0x05030000u, "toggle bit");
}

TEST(SdoClient, DownloadToggleErrorIsAborted) {
  SdoClient c(2);
  c.download(0x2000, 0, bytes("fieldgate axis two"), t0);
  c.on_frame(frame("582#6000200000000000"), t0);
  auto s = c.on_frame(frame("582#3000000000000000"), t0);  // toggle 1 where 0 is due
  EXPECT_EQ(sent(s), "602#8000200000000305");
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->abort_code, 0x05030000u);
}

TEST(SdoClient, UploadLongerThanAnnouncedIsAborted) {
  SdoClient c(3);
  c.upload(0x1008, 0, t0);
  c.on_frame(frame("583#4108100003000000"), t0);           // 3 bytes announced
  auto s = c.on_frame(frame("583#006669656C646761"), t0);  // 7 arrive
  EXPECT_EQ(sent(s), "603#8008100012000706");              // 0x06070012 too high
  expect_ended(s, SdoResult::Status::client_abort, 0x06070012u);
}

TEST(SdoClient, UploadShorterThanAnnouncedFails) {
  SdoClient c(3);
  c.upload(0x1008, 0, t0);
  c.on_frame(frame("583#410810000A000000"), t0);           // 10 announced
  auto s = c.on_frame(frame("583#016669656C646761"), t0);  // 7 and last
  EXPECT_EQ(sent(s), "");  // the server has finished; nobody to abort
  expect_ended(s, SdoResult::Status::client_abort, 0x06070013u);
}

TEST(SdoClient, HugeUploadIsAborted) {
  SdoClient c(3);
  c.upload(0x2000, 0, t0);
  auto s = c.on_frame(frame("583#4100200000000001"), t0);  // 16 MiB announced
  EXPECT_EQ(sent(s), "603#8000200005000405");              // 0x05040005 out of memory
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->abort_code, 0x05040005u);
}

TEST(SdoClient, LocalAbort) {
  SdoClient c(2);
  EXPECT_EQ(sent(c.abort(0x08000000)), "");  // idle: nothing to abort
  c.upload(0x6041, 0, t0);
  auto s = c.abort(0x08000000);
  EXPECT_EQ(sent(s), "602#8041600000000008");  // 0x08000000 general error
  EXPECT_TRUE(c.idle());
}

TEST(SdoClient, SecondTransferWhileBusyIsRefused) {
  SdoClient c(2);
  c.upload(0x6041, 0, t0);
  auto s = c.upload(0x6064, 0, t0);
  EXPECT_EQ(sent(s), "");
  ASSERT_TRUE(s.done);
  EXPECT_EQ(s.done->status, SdoResult::Status::client_abort);
  EXPECT_EQ(c.state_name(), std::string("upload initiate"));  // the first goes on
}

// --- timeouts with injected time -------------------------------------------------------------

TEST(SdoClient, TimeoutInEveryState) {
  struct Case {
    const char* name;
    std::function<void(SdoClient&)> start;
    const char* abort;
  };
  const Case cases[] = {
      {"upload initiate", [](SdoClient& c) { c.upload(0x6041, 0, t0); }, "602#8041600000000405"},
      {"upload segment",
       [](SdoClient& c) {
         c.upload(0x1008, 0, t0);
         c.on_frame(frame("582#410810001B000000"), t0);
       },
       "602#8008100000000405"},
      {"download initiate",
       [](SdoClient& c) {
         c.download(0x6040, 0, {6, 0}, t0);
       },
       "602#8040600000000405"},
      {"download segment",
       [](SdoClient& c) {
         c.download(0x2000, 0, bytes("fieldgate axis"), t0);
         c.on_frame(frame("582#6000200000000000"), t0);
       },
       "602#8000200000000405"},
  };
  for (const auto& k : cases) {
    SCOPED_TRACE(k.name);
    SdoClient c(2, 50ms);
    k.start(c);
    EXPECT_EQ(c.state_name(), std::string(k.name));
    EXPECT_EQ(c.deadline(), t0 + 50ms) << k.name;
    auto s = c.on_time(t0 + 49ms);
    EXPECT_FALSE(s.send || s.done) << k.name;
    s = c.on_time(t0 + 50ms);
    EXPECT_EQ(sent(s), k.abort) << k.name;  // the server hears 0x05040000
    ASSERT_NO_FATAL_FAILURE(
        expect_ended(s, SdoResult::Status::timeout, 0x05040000u, "within 50 ms"));
    EXPECT_TRUE(c.idle()) << k.name;
  }
}

TEST(SdoClient, LateAnswerAfterTimeoutIsIgnored) {
  SdoClient c(2, 50ms);
  c.upload(0x6041, 0, t0);
  c.on_time(t0 + 60ms);
  auto s = c.on_frame(frame("582#4B41600050020000"), t0 + 70ms);
  EXPECT_FALSE(s.send || s.done);
  EXPECT_EQ(c.ignored_frames(), 1u);
  // A late answer for another object does not end the next transfer either.
  c.upload(0x6064, 0, t0 + 80ms);
  EXPECT_FALSE(c.on_frame(frame("582#4B41600050020000"), t0 + 81ms).done);
  auto done = c.on_frame(frame("582#4364600000100000"), t0 + 82ms).done;
  ASSERT_TRUE(done);
  EXPECT_EQ(done->data, (std::vector<uint8_t>{0, 0x10, 0, 0}));
}

TEST(SdoClient, ShortFramesAndOtherNodesAreIgnored) {
  SdoClient c(2);
  c.upload(0x6041, 0, t0);
  EXPECT_FALSE(c.on_frame(frame("582#4B416000"), t0).done);          // DLC 4
  EXPECT_FALSE(c.on_frame(frame("583#4B41600050020000"), t0).done);  // node 3's
  EXPECT_FALSE(c.on_frame(frame("702#05"), t0).done);                // heartbeat
  EXPECT_TRUE(c.on_frame(frame("582#4B41600050020000"), t0).done);
}

// --- two nodes overlapping -------------------------------------------------------------------

TEST(SdoClient, TwoNodesOverlap) {
  SdoClient a(2), b(3);
  // Both requests go out before either answer comes back; answers arrive crossed.
  EXPECT_EQ(sent(a.upload(0x1008, 0, t0)), "602#4008100000000000");
  EXPECT_EQ(sent(b.download(0x6040, 0, {0x06, 0x00}, t0)), "603#2B40600006000000");
  const char* wire[] = {"583#6040600000000000", "582#4108100009000000", "582#006669656C646761",
                        "582#1B74650000000000"};
  std::optional<SdoResult> ra, rb;
  std::vector<std::string> out;
  for (const char* f : wire) {
    for (SdoClient* c : {&a, &b}) {
      auto s = c->on_frame(frame(f), t0);
      if (s.send) out.push_back(to_string(*s.send));
      if (s.done) (c == &a ? ra : rb) = s.done;
    }
  }
  ASSERT_TRUE(ra && rb);
  EXPECT_EQ(rb->status, SdoResult::Status::ok);
  EXPECT_EQ(text(ra->data), "fieldgate");
  EXPECT_EQ(out, (std::vector<std::string>{"602#6000000000000000", "602#7000000000000000"}));
  EXPECT_EQ(a.ignored_frames() + b.ignored_frames(), 0u);
}

// --- against the simulator's SDO server, in memory -------------------------------------------

TEST(SdoClient, RoundTripsWithTheSimulatorsServer) {
  namespace simco = fieldgate::sim::canopen;
  simco::ObjectDictionary od;
  std::string label = "axis 2";
  od.add_string(0x2000, 0, "user label", label, 64);
  uint16_t heartbeat = 1000;
  od.add_value<uint16_t>(0x1017, 0, "heartbeat", simco::Access::rw, heartbeat);
  simco::SdoServer server(od);
  SdoClient client(2);

  const auto run = [&](SdoStep s) {
    for (int i = 0; i < 100 && !s.done; ++i) {
      if (!s.send) break;
      const auto reply = server.on_request(s.send->data, t0);
      if (!reply) break;
      CanFrame f;
      f.id = cob::sdo_tx + 2;
      f.len = 8;
      f.data = *reply;
      s = client.on_frame(f, t0);
    }
    return s.done;
  };
  const std::string long_label = "a label longer than one segment, and than two";
  auto r = run(client.download(0x2000, 0, bytes(long_label), t0));
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, SdoResult::Status::ok);
  EXPECT_EQ(label, long_label);
  r = run(client.upload(0x2000, 0, t0));
  ASSERT_TRUE(r);
  EXPECT_EQ(text(r->data), long_label);
  r = run(client.download(0x1017, 0, {0xC8, 0x00}, t0));
  EXPECT_EQ(r->status, SdoResult::Status::ok);
  EXPECT_EQ(heartbeat, 200);
  r = run(client.upload(0x1017, 1, t0));
  EXPECT_EQ(r->status, SdoResult::Status::server_abort);
  EXPECT_EQ(r->abort_code, 0x06090011u);
}

}  // namespace
}  // namespace fieldgate::canopen
