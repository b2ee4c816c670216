// The CANopen simulator's device logic with frames in memory and injected time: SDO transfers
// and aborts, NMT and error control, EMCY, TPDO1, the CiA 402 state machine, profile position
// and homing. Frames are written in cansend/candump text.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <utility>
#include <vector>

#include "sim_bus.hpp"

namespace fieldgate::sim::canopen {
namespace {

using namespace std::chrono_literals;

// The device tests' bus: node 2 (or the given nodes). These tests were written against a node
// producing a 1000 ms heartbeat from power-up, not the CiA 301 default of none.
class Bus : public SimBus {
 public:
  explicit Bus(std::vector<std::uint8_t> ids = {2})
      : SimBus(with_heartbeat_ms(1000), std::move(ids)) {}
};

std::string abort_frame(const std::string& mux, std::uint32_t code) {
  return fmt::format("582#80{}{:08X}", mux, __builtin_bswap32(code));
}

// --- SDO upload ------------------------------------------------------------------------------

TEST(SdoUpload, ExpeditedDeviceType) {
  Bus bus;
  EXPECT_EQ(bus.sdo("4000100000000000"), "582#4300100092010200");
}

TEST(SdoUpload, ExpeditedSizesFollowTheObject) {
  Bus bus;
  EXPECT_EQ(bus.sdo("4001100000000000"), "582#4F01100000000000");  // u8 error register
  EXPECT_EQ(bus.sdo("4017100000000000"), "582#4B171000E8030000");  // u16 heartbeat 1000 ms
  EXPECT_EQ(bus.sdo("4018100000000000"), "582#4F18100004000000");  // identity sub 0
  EXPECT_EQ(bus.upload(0x1018, 4), 0x51000002u);                   // serial number
  EXPECT_EQ(bus.upload(0x1014, 0), 0x82u);                         // COB-ID EMCY
}

TEST(SdoUpload, SegmentedDeviceNameTranscript) {
  Bus bus;
  // "fieldgate sim CiA 402 drive": 27 bytes in 4 segments, toggle 0,1,0,1.
  EXPECT_EQ(bus.sdo("4008100000000000"), "582#410810001B000000");
  EXPECT_EQ(bus.sdo("6000000000000000"), "582#006669656C646761");  // "fieldga"
  EXPECT_EQ(bus.sdo("7000000000000000"), "582#1074652073696D20");  // "te sim "
  EXPECT_EQ(bus.sdo("6000000000000000"), "582#0043694120343032");  // "CiA 402"
  EXPECT_EQ(bus.sdo("7000000000000000"), "582#1320647269766500");  // " drive", n=1, c=1
  // The transfer is over: another segment request has nothing to continue.
  EXPECT_EQ(bus.sdo("6000000000000000"), abort_frame("000000", 0x05040001));
}

TEST(SdoUpload, SegmentedStrings) {
  Bus bus;
  EXPECT_EQ(bus.segmented_upload(0x1008, 0), "fieldgate sim CiA 402 drive");
  EXPECT_EQ(bus.segmented_upload(0x100A, 0), "fieldgate-sim-canopen 0.1");
  EXPECT_EQ(bus.segmented_upload(0x2000, 0), "axis 2");
  EXPECT_EQ(bus.sdo("4009100000000000"), "582#4709100073696D00")  // "sim": expedited, n=1
      << "strings of 4 bytes or less are expedited";
}

TEST(SdoUpload, ToggleErrorAborts) {
  Bus bus;
  EXPECT_EQ(bus.sdo("4008100000000000"), "582#410810001B000000");
  EXPECT_EQ(bus.sdo("6000000000000000"), "582#006669656C646761");
  EXPECT_EQ(bus.sdo("6000000000000000"), abort_frame("081000", 0x05030000));
  // Back to idle: a fresh upload works.
  EXPECT_EQ(bus.segmented_upload(0x1008, 0), "fieldgate sim CiA 402 drive");
}

TEST(SdoUpload, ClientAbortEndsTransferSilently) {
  Bus bus;
  EXPECT_EQ(bus.sdo("4008100000000000"), "582#410810001B000000");
  EXPECT_EQ(bus.sdo("8008100000000408"), "");
  EXPECT_EQ(bus.sdo("6000000000000000"), abort_frame("000000", 0x05040001));
}

TEST(SdoUpload, ServerTimesOutStalledTransfer) {
  Bus bus;
  EXPECT_EQ(bus.sdo("4008100000000000"), "582#410810001B000000");
  bus.take();
  bus.advance(900ms);
  EXPECT_TRUE(bus.take(0x582).empty());
  bus.advance(200ms);
  EXPECT_EQ(bus.take(0x582), std::vector<std::string>{abort_frame("081000", 0x05040000)});
}

// --- SDO download ----------------------------------------------------------------------------

TEST(SdoDownload, ExpeditedWithAndWithoutSize) {
  Bus bus;
  EXPECT_EQ(bus.sdo("2B171000F4010000"), "582#6017100000000000");
  EXPECT_EQ(bus.upload(0x1017, 0), 500u);
  // Size not indicated (0x22): the object's own size is taken.
  EXPECT_EQ(bus.sdo("2217100064000000"), "582#6017100000000000");
  EXPECT_EQ(bus.upload(0x1017, 0), 100u);
  EXPECT_EQ(bus.download(0x607A, 0, static_cast<std::uint32_t>(-1234), 4), "582#607A600000000000");
  EXPECT_EQ(static_cast<std::int32_t>(bus.upload(0x607A, 0)), -1234);
}

TEST(SdoDownload, SegmentedTranscript) {
  Bus bus;
  // "hello world, CANopen" (20 bytes) into the user label 0x2000.
  EXPECT_EQ(bus.sdo("2100200014000000"), "582#6000200000000000");
  EXPECT_EQ(bus.sdo("0068656C6C6F2077"), "582#2000000000000000");  // "hello w", t=0
  EXPECT_EQ(bus.sdo("106F726C642C2043"), "582#3000000000000000");  // "orld, C", t=1
  EXPECT_EQ(bus.sdo("03414E6F70656E00"), "582#2000000000000000");  // "ANopen", n=1, c=1
  EXPECT_EQ(bus.segmented_upload(0x2000, 0), "hello world, CANopen");
}

TEST(SdoDownload, SegmentedWithoutSizeAndIntoFixedSizeObject) {
  Bus bus;
  EXPECT_EQ(bus.sdo("2000200000000000"), "582#6000200000000000");
  EXPECT_EQ(bus.sdo("0761786973000000"), "582#2000000000000000");  // "axis", n=3, c=1
  EXPECT_EQ(bus.sdo("4000200000000000"), "582#4300200061786973") << "4 bytes: expedited";
  // A client may send a 4-byte value segmented.
  EXPECT_EQ(bus.sdo("217A600004000000"), "582#607A600000000000");
  EXPECT_EQ(bus.sdo("0740420F00000000"), "582#2000000000000000");  // 1000000, n=3, c=1
  EXPECT_EQ(bus.upload(0x607A, 0), 1000000u);
}

TEST(SdoDownload, ToggleErrorAborts) {
  Bus bus;
  EXPECT_EQ(bus.sdo("2100200014000000"), "582#6000200000000000");
  EXPECT_EQ(bus.sdo("0068656C6C6F2077"), "582#2000000000000000");
  EXPECT_EQ(bus.sdo("006F726C642C2043"), abort_frame("002000", 0x05030000));
  EXPECT_EQ(bus.segmented_upload(0x2000, 0), "axis 2") << "nothing was written";
}

TEST(SdoDownload, LengthErrorsAbort) {
  Bus bus;
  EXPECT_EQ(bus.sdo("2317100001000000"), abort_frame("171000", 0x06070010));  // 4 into u16
  EXPECT_EQ(bus.sdo("2F17100001000000"), abort_frame("171000", 0x06070010));  // 1 into u16
  EXPECT_EQ(bus.sdo("2100200041000000"), abort_frame("002000", 0x06070010));  // 65 > 64
  EXPECT_EQ(bus.sdo("217A600005000000"), abort_frame("7A6000", 0x06070010));  // 5 into i32
  // More segments than the indicated size.
  EXPECT_EQ(bus.sdo("2100200002000000"), "582#6000200000000000");
  EXPECT_EQ(bus.sdo("0068656C6C6F2077"), abort_frame("002000", 0x06070010));
  // Fewer.
  EXPECT_EQ(bus.sdo("2100200009000000"), "582#6000200000000000");
  EXPECT_EQ(bus.sdo("0D61620000000000"), abort_frame("002000", 0x06070010));
  EXPECT_EQ(bus.upload(0x1017, 0), 1000u);
}

// --- SDO aborts --------------------------------------------------------------------------------

TEST(SdoAbortCodes, EveryAbortTheServerGives) {
  Bus bus;
  EXPECT_EQ(bus.sdo("4034120000000000"), abort_frame("341200", 0x06020000));  // no object
  EXPECT_EQ(bus.sdo("4018100500000000"), abort_frame("181005", 0x06090011));  // no subindex
  EXPECT_EQ(bus.sdo("4000180400000000"), abort_frame("001804", 0x06090011));  // reserved sub 4
  EXPECT_EQ(bus.sdo("2300100001000000"), abort_frame("001000", 0x06010002));  // const
  EXPECT_EQ(bus.sdo("2B41600000000000"), abort_frame("416000", 0x06010002));  // statusword ro
  EXPECT_EQ(bus.sdo("210810001B000000"), abort_frame("081000", 0x06010002));  // const string
  EXPECT_EQ(bus.sdo("4001200000000000"), abort_frame("012000", 0x06010001));  // write-only
  EXPECT_EQ(bus.sdo("2317100001000000"), abort_frame("171000", 0x06070010));  // length
  EXPECT_EQ(bus.sdo("A000100000000000"), abort_frame("001000", 0x05040001));  // block upload
  EXPECT_EQ(bus.sdo("C000100000000000"), abort_frame("001000", 0x05040001));  // block download
  EXPECT_EQ(bus.sdo("E000100000000000"), abort_frame("001000", 0x05040001));  // ccs 7
  EXPECT_EQ(bus.sdo("6000000000000000"), abort_frame("000000", 0x05040001));  // no transfer
  EXPECT_EQ(bus.sdo("0000000000000000"), abort_frame("000000", 0x05040001));  // no transfer
  EXPECT_EQ(bus.sdo("2F60600003000000"), abort_frame("606000", 0x06090030));  // mode 3
  EXPECT_EQ(bus.sdo("2381600000000000"), abort_frame("816000", 0x06090032));  // velocity 0
  EXPECT_EQ(bus.sdo("2F03100001000000"), abort_frame("031000", 0x06090030));  // 0x1003 := 1
  // Toggle errors: SdoUpload.ToggleErrorAborts, SdoDownload.ToggleErrorAborts.
}

TEST(SdoAbortCodes, InitiateDuringSegmentedTransferIsRejected) {
  Bus bus;
  EXPECT_EQ(bus.sdo("4008100000000000"), "582#410810001B000000");
  EXPECT_EQ(bus.sdo("4000100000000000"), abort_frame("081000", 0x05040001));
  EXPECT_EQ(bus.sdo("4000100000000000"), "582#4300100092010200");
}

TEST(SdoAbortCodes, ShortFramesAreIgnored) {
  Bus bus;
  EXPECT_EQ(bus.sdo("40001000"), "");
  EXPECT_EQ(bus.sdo("4000100000000000"), "582#4300100092010200");
}

// --- NMT and error control ---------------------------------------------------------------------

TEST(Nmt, BootUpThenHeartbeatWithState) {
  Bus bus;
  EXPECT_EQ(bus.take(), std::vector<std::string>{"702#00"});
  bus.advance(999ms);
  EXPECT_TRUE(bus.take(0x702).empty());
  bus.advance(1ms);
  EXPECT_EQ(bus.take(0x702), std::vector<std::string>{"702#7F"});
  bus.send("000#0102");
  bus.advance(1000ms);
  EXPECT_EQ(bus.take(0x702), std::vector<std::string>{"702#05"});
  bus.send("000#0202");
  bus.advance(1000ms);
  EXPECT_EQ(bus.take(0x702), std::vector<std::string>{"702#04"});
  bus.send("000#8002");
  bus.advance(1000ms);
  EXPECT_EQ(bus.take(0x702), std::vector<std::string>{"702#7F"});
}

TEST(Nmt, HeartbeatPeriodFollows1017) {
  Bus bus;
  bus.take();
  EXPECT_EQ(bus.download(0x1017, 0, 100, 2), "582#6017100000000000");
  bus.advance(1000ms);
  EXPECT_EQ(bus.take(0x702).size(), 10u);
  EXPECT_EQ(bus.download(0x1017, 0, 0, 2), "582#6017100000000000");
  bus.advance(5000ms);
  EXPECT_TRUE(bus.take(0x702).empty());
}

TEST(Nmt, BroadcastAndAddressedCommands) {
  Bus bus({2, 3});
  EXPECT_EQ(bus.take(), (std::vector<std::string>{"702#00", "703#00"}));
  bus.send("000#0100");
  EXPECT_EQ(bus.node(2).nmt_state(), NmtState::operational);
  EXPECT_EQ(bus.node(3).nmt_state(), NmtState::operational);
  bus.send("000#0203");
  EXPECT_EQ(bus.node(2).nmt_state(), NmtState::operational);
  EXPECT_EQ(bus.node(3).nmt_state(), NmtState::stopped);
  // Stopped: no SDO.
  EXPECT_EQ(bus.sdo("4000100000000000", 3), "");
  EXPECT_EQ(bus.sdo("4000100000000000", 2), "582#4300100092010200");
  bus.send("000#0103");
  EXPECT_EQ(bus.sdo("4000100000000000", 3), "583#4300100092010200");
  bus.send("000#8000");
  EXPECT_EQ(bus.node(2).nmt_state(), NmtState::pre_operational);
  EXPECT_EQ(bus.node(3).nmt_state(), NmtState::pre_operational);
}

TEST(Nmt, ResetNodeAndResetCommunication) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  EXPECT_EQ(bus.download(0x1017, 0, 250, 2), "582#6017100000000000");
  bus.take();
  bus.send("000#8202");  // reset communication: 0x1017 back to default, drive untouched
  EXPECT_EQ(bus.take(), std::vector<std::string>{"702#00"});
  EXPECT_EQ(bus.upload(0x1017, 0), 1000u);
  EXPECT_EQ(bus.node().drive().state(), DriveState::operation_enabled);
  EXPECT_EQ(bus.download(0x1017, 0, 250, 2), "582#6017100000000000");
  bus.send("000#8100");  // reset node (broadcast): the drive restarts too
  EXPECT_EQ(bus.take(), std::vector<std::string>{"702#00"});
  EXPECT_EQ(bus.upload(0x1017, 0), 1000u);
  EXPECT_EQ(bus.statusword(), 0x0000) << "not ready to switch on right after reset";
  bus.advance(20ms);
  EXPECT_EQ(bus.statusword(), 0x0650);
}

TEST(Nmt, NodeGuardingToggles) {
  Bus bus;
  bus.take();
  bus.send("702#R");
  bus.send("702#R");
  bus.send("000#0102");
  bus.send("702#R");
  EXPECT_EQ(bus.take(0x702), (std::vector<std::string>{"702#7F", "702#FF", "702#05"}));
}

TEST(Nmt, PowerOffIsSilentPowerOnBootsAgain) {
  Bus bus({2, 3});
  bus.take();
  EXPECT_TRUE(bus.net().execute("power-off 2", bus.now()).ok);
  bus.advance(3000ms);
  EXPECT_EQ(bus.take(0x702).size(), 0u);
  EXPECT_EQ(bus.take(0x703).size(), 3u);
  EXPECT_EQ(bus.sdo("4000100000000000"), "");
  EXPECT_TRUE(bus.net().execute("power-on 2", bus.now()).ok);
  EXPECT_EQ(bus.take(0x702), std::vector<std::string>{"702#00"});
  EXPECT_EQ(bus.sdo("4000100000000000"), "582#4300100092010200");
}

// --- EMCY --------------------------------------------------------------------------------------

TEST(Emcy, FaultThenFaultReset) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  bus.take();
  const auto r = bus.net().execute("fault 2 0x2310", bus.now());
  EXPECT_TRUE(r.ok) << r.message;
  EXPECT_EQ(bus.take(0x82), std::vector<std::string>{"082#1023030000000000"});
  EXPECT_EQ(bus.node().drive().state(), DriveState::fault);
  EXPECT_EQ(bus.statusword(), 0x0618);
  EXPECT_EQ(bus.upload(0x1001, 0), 0x03u);
  EXPECT_EQ(bus.upload(0x603F, 0), 0x2310u);
  EXPECT_EQ(bus.upload(0x1003, 0), 1u);
  EXPECT_EQ(bus.upload(0x1003, 1), 0x2310u);
  // Enable commands do nothing in Fault; only the rising edge of bit 7 resets it.
  bus.controlword(0x0F);
  EXPECT_EQ(bus.node().drive().state(), DriveState::fault);
  bus.controlword(0x8F);
  EXPECT_EQ(bus.take(0x82), std::vector<std::string>{"082#0000000000000000"});
  EXPECT_EQ(bus.statusword(), 0x0650);
  EXPECT_EQ(bus.upload(0x1001, 0), 0u);
  EXPECT_EQ(bus.upload(0x1003, 0), 1u) << "the history keeps the error";
  EXPECT_EQ(bus.download(0x1003, 0, 0, 1), "582#6003100000000000");
  EXPECT_EQ(bus.upload(0x1003, 0), 0u);
}

TEST(Emcy, FaultInjectedThroughWriteOnlyObject) {
  Bus bus;
  bus.take();
  EXPECT_EQ(bus.download(kFaultInjectIndex, 0, 0x4210, 2), "582#6001200000000000");
  EXPECT_EQ(bus.take(0x82), std::vector<std::string>{"082#1042090000000000"});
  bus.send("000#0202");
  EXPECT_TRUE(bus.net().execute("fault 2 0xFF01", bus.now()).ok);
  EXPECT_TRUE(bus.take(0x82).empty()) << "no EMCY in Stopped";
}

// --- CiA 402 state machine ---------------------------------------------------------------------

TEST(StateMachine, PowerUpSequence) {
  Bus bus;
  EXPECT_EQ(bus.statusword(), 0x0000);
  bus.advance(20ms);
  EXPECT_EQ(bus.statusword(), 0x0650);  // switch on disabled
  bus.controlword(0x0F);                // enable operation is no transition from here
  EXPECT_EQ(bus.statusword(), 0x0650);
  bus.controlword(0x06);
  EXPECT_EQ(bus.statusword(), 0x0631);  // ready to switch on
  bus.controlword(0x07);
  EXPECT_EQ(bus.statusword(), 0x0633);  // switched on
  bus.controlword(0x0F);
  EXPECT_EQ(bus.statusword(), 0x0637);  // operation enabled
  bus.controlword(0x07);
  EXPECT_EQ(bus.statusword(), 0x0633);  // disable operation
  bus.controlword(0x06);
  EXPECT_EQ(bus.statusword(), 0x0631);  // shutdown
  bus.controlword(0x0F);
  EXPECT_EQ(bus.statusword(), 0x0637);  // switch on + enable operation (3 and 4)
  bus.controlword(0x00);
  EXPECT_EQ(bus.statusword(), 0x0650);  // disable voltage
  EXPECT_EQ(bus.upload(0x6040, 0), 0u);
}

TEST(StateMachine, QuickStop) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  bus.controlword(0x02);  // option code 2: quick stop ramp, then switch on disabled
  EXPECT_EQ(bus.statusword(), 0x0650);
  EXPECT_EQ(bus.download(0x605A, 0, 6, 2), "582#605A600000000000");
  bus.controlword(0x06);
  bus.controlword(0x0F);
  bus.controlword(0x0B);  // option code 6: stay in quick stop active
  EXPECT_EQ(bus.node().drive().state(), DriveState::quick_stop_active);
  EXPECT_EQ(bus.statusword(), 0x0617);
  bus.controlword(0x0F);
  EXPECT_EQ(bus.statusword(), 0x0637);
  EXPECT_EQ(bus.download(0x605A, 0, 3, 2), abort_frame("5A6000", 0x06090030));
}

TEST(StateMachine, FaultDuringMoveRampsDownFirst) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  bus.download(0x607A, 0, 100000, 4);
  bus.controlword(0x1F);
  bus.advance(1500ms);
  EXPECT_EQ(bus.upload(0x606C, 0), 10000u);
  bus.net().execute("fault 2 0x7300", bus.now());
  EXPECT_EQ(bus.node().drive().state(), DriveState::fault_reaction_active);
  EXPECT_EQ(bus.statusword() & 0x4F, 0x0F);
  bus.advance(60ms);  // 10000 counts/s at the quick stop deceleration 200000: 50 ms
  EXPECT_EQ(bus.node().drive().state(), DriveState::fault);
  EXPECT_EQ(bus.upload(0x606C, 0), 0u);
}

// --- Profile position mode ---------------------------------------------------------------------

TEST(ProfilePosition, TrapezoidalMoveWithHandshake) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  EXPECT_EQ(bus.upload(0x6061, 0), 1u);
  EXPECT_EQ(bus.download(0x607A, 0, 10000, 4), "582#607A600000000000");
  bus.controlword(0x1F);  // new setpoint, absolute
  EXPECT_EQ(bus.statusword(), 0x1237) << "setpoint acknowledged, target not reached";
  bus.controlword(0x0F);
  EXPECT_EQ(bus.statusword(), 0x0237);
  // 10000 counts at 10000 counts/s, 50000 counts/s² both ways: 0.2 s ramps, 1.2 s in all.
  bus.advance(200ms);
  EXPECT_NEAR(bus.position(), 1000, 15);
  bus.advance(400ms);
  EXPECT_NEAR(bus.position(), 5000, 15);
  EXPECT_EQ(bus.upload(0x606C, 0), 10000u);
  bus.advance(500ms);
  EXPECT_NEAR(bus.position(), 9750, 15);
  EXPECT_EQ(bus.statusword() & 0x0400, 0);
  bus.advance(120ms);
  EXPECT_EQ(bus.position(), 10000);
  EXPECT_EQ(bus.upload(0x606C, 0), 0u);
  EXPECT_EQ(bus.statusword(), 0x0637);
}

TEST(ProfilePosition, RelativeCountsFromPrecedingTarget) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  bus.new_setpoint(1000);
  bus.new_setpoint(500, 0x7F);  // relative, change immediately
  bus.advance(2s);
  EXPECT_EQ(bus.position(), 1500);
}

TEST(ProfilePosition, BufferedSetpointFollowsAndFullBufferIsNotAcknowledged) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  bus.new_setpoint(2000);
  bus.advance(100ms);
  bus.new_setpoint(4000);  // bit 5 clear: buffered behind the running move
  EXPECT_EQ(bus.statusword() & 0x1000, 0x1000) << "acknowledge stays while the buffer is full";
  bus.new_setpoint(9999);  // buffer full: ignored
  bus.advance(3s);
  EXPECT_EQ(bus.position(), 4000);
  EXPECT_EQ(bus.statusword(), 0x0637);
}

TEST(ProfilePosition, ChangeImmediatelyReverses) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  bus.new_setpoint(10000);
  bus.advance(600ms);
  bus.new_setpoint(2000, 0x3F);
  bus.advance(300ms);
  EXPECT_GT(bus.position(), 5000) << "braking past the new target first";
  bus.advance(2s);
  EXPECT_EQ(bus.position(), 2000);
  EXPECT_EQ(bus.statusword(), 0x0637);
}

TEST(ProfilePosition, HaltStopsAndReleaseResumes) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  bus.new_setpoint(10000);
  bus.advance(500ms);
  bus.controlword(0x010F);
  bus.advance(300ms);
  const auto halted_at = bus.position();
  EXPECT_LT(halted_at, 10000);
  EXPECT_EQ(bus.statusword() & 0x0400, 0x0400) << "target reached = stopped by halt";
  bus.controlword(0x0F);
  bus.advance(2s);
  EXPECT_EQ(bus.position(), 10000);
}

TEST(ProfilePosition, SetpointIgnoredUnlessOperationEnabled) {
  Bus bus;
  bus.advance(50ms);
  bus.download(0x6060, 0, 1, 1);
  bus.controlword(0x06);
  bus.download(0x607A, 0, 10000, 4);
  bus.controlword(0x16);
  bus.advance(1s);
  EXPECT_EQ(bus.position(), 0);
  EXPECT_EQ(bus.statusword() & 0x1000, 0);
}

// --- Homing mode -------------------------------------------------------------------------------

TEST(Homing, CurrentPositionMethod) {
  Bus bus;
  bus.enable(Drive402::kModeHoming);
  EXPECT_EQ(bus.statusword() & 0x3400, 0x0400) << "not started";
  EXPECT_EQ(bus.download(0x607C, 0, 1234, 4), "582#607C600000000000");
  EXPECT_EQ(bus.download(0x6098, 0, 35, 1), "582#6098600000000000");
  bus.controlword(0x1F);
  EXPECT_EQ(bus.statusword() & 0x3400, 0x1400) << "attained and reached";
  EXPECT_EQ(bus.position(), 1234);
}

TEST(Homing, SwitchSearchTakesTime) {
  Bus bus;
  bus.enable(Drive402::kModeHoming);
  bus.download(0x607C, 0, 0, 4);
  bus.start_homing(17);
  EXPECT_EQ(bus.statusword() & 0x3400, 0x0000) << "in progress";
  bus.advance(100ms);
  EXPECT_LT(bus.position(), 0);
  bus.advance(1s);
  EXPECT_EQ(bus.statusword() & 0x3400, 0x1400);
  EXPECT_EQ(bus.position(), 0);
  // Absolute moves now count from the home position.
  bus.download(0x6060, 0, 1, 1);
  bus.download(0x607A, 0, 300, 4);
  bus.controlword(0x0F);
  bus.controlword(0x1F);
  bus.advance(1s);
  EXPECT_EQ(bus.position(), 300);
}

TEST(Homing, InterruptedAndError) {
  Bus bus;
  bus.enable(Drive402::kModeHoming);
  bus.start_homing(17);
  bus.advance(50ms);
  bus.controlword(0x0F);  // bit 4 falling: interrupt
  EXPECT_EQ(bus.statusword() & 0x3400, 0x0000) << "interrupted, still decelerating";
  bus.advance(500ms);
  EXPECT_EQ(bus.statusword() & 0x3400, 0x0400);
  bus.start_homing(0);
  EXPECT_EQ(bus.statusword() & 0x3400, 0x2400) << "homing error, velocity 0";
}

TEST(Homing, HaltStandsBeforeTargetReached) {
  Bus bus;
  bus.enable(Drive402::kModeHoming);
  bus.start_homing(17);
  bus.advance(100ms);
  bus.controlword(0x011F);  // halt
  EXPECT_EQ(bus.statusword() & 0x3400, 0x0000) << "interrupted, still decelerating";
  const auto braking_from = bus.position();
  bus.advance(500ms);
  EXPECT_EQ(bus.statusword() & 0x3400, 0x0400) << "interrupted, standing";
  EXPECT_LT(bus.position(), braking_from) << "the axis decelerated, it did not stop dead";
  const auto stood_at = bus.position();
  bus.advance(200ms);
  EXPECT_EQ(bus.position(), stood_at);
}

// --- TPDO1 -------------------------------------------------------------------------------------

TEST(Tpdo, OnEnteringOperationalOnChangeAndByEventTimer) {
  Bus bus;
  bus.advance(50ms);
  bus.take();
  bus.send("000#0102");
  EXPECT_EQ(bus.take(0x182), std::vector<std::string>{"182#500600000000"});
  bus.advance(250ms);
  EXPECT_EQ(bus.take(0x182).size(), 2u) << "event timer 100 ms";
  bus.controlword(0x06);
  EXPECT_EQ(bus.take(0x182), std::vector<std::string>{"182#310600000000"});
  bus.send("000#8002");
  bus.controlword(0x07);
  bus.advance(1s);
  EXPECT_TRUE(bus.take(0x182).empty()) << "no PDOs in pre-operational";
}

TEST(Tpdo, InhibitTimeLimitsRateWhileMoving) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  bus.send("000#0102");
  bus.new_setpoint(10000);
  bus.take();
  bus.advance(500ms);
  const auto pdos = bus.take(0x182);
  EXPECT_GE(pdos.size(), 45u);
  EXPECT_LE(pdos.size(), 51u);
  const auto last = parse_frame(pdos.back());
  EXPECT_EQ(from_le<std::int32_t>(std::span(last->data).subspan(2, 4)), bus.position());
}

TEST(Tpdo, SlowMoveNeverAsksForAWakeUpInThePast) {
  Bus bus;
  bus.enable(Drive402::kModeProfilePosition);
  bus.send("000#0102");
  bus.download(0x6081, 0, 3, 4);  // 3 counts/s: the position changes every ~300 ms
  bus.download(0x607A, 0, 10, 4);
  bus.controlword(0x1F);
  for (int i = 0; i < 200; ++i) {
    bus.advance(7ms);
    ASSERT_GT(bus.net().next_deadline(), bus.now());
  }
  bus.advance(5s);
  EXPECT_EQ(bus.position(), 10);
}

// --- Control commands and options ----------------------------------------------------------------

TEST(Control, Commands) {
  Bus bus({2, 3});
  EXPECT_TRUE(bus.net().execute("quit", bus.now()).quit);
  EXPECT_FALSE(bus.net().execute("power-off 9", bus.now()).ok);
  EXPECT_FALSE(bus.net().execute("power-off 200", bus.now()).ok);
  EXPECT_FALSE(bus.net().execute("fault 2", bus.now()).ok);
  EXPECT_FALSE(bus.net().execute("fault 2 0", bus.now()).ok);
  EXPECT_FALSE(bus.net().execute("jump 2", bus.now()).ok);
  EXPECT_TRUE(bus.net().execute("", bus.now()).ok);
  const auto status = bus.net().execute("status 3", bus.now());
  EXPECT_TRUE(status.ok);
  EXPECT_NE(status.message.find("node 3 on nmt=pre-operational"), std::string::npos)
      << status.message;
}

TEST(Control, NodeIdLists) {
  EXPECT_EQ(parse_node_ids("2,3"), (std::vector<std::uint8_t>{2, 3}));
  EXPECT_EQ(parse_node_ids("5,1-3"), (std::vector<std::uint8_t>{1, 2, 3, 5}));
  EXPECT_EQ(parse_node_ids("127"), std::vector<std::uint8_t>{127});
  EXPECT_THROW(parse_node_ids("0"), std::invalid_argument);
  EXPECT_THROW(parse_node_ids("128"), std::invalid_argument);
  EXPECT_THROW(parse_node_ids("2,2"), std::invalid_argument);
  EXPECT_THROW(parse_node_ids("2,"), std::invalid_argument);
  EXPECT_THROW(parse_node_ids("x"), std::invalid_argument);
}

TEST(Frames, CandumpText) {
  EXPECT_EQ(to_string(CanFrame::make(0x602, {0x40, 0x00, 0x10})), "602#400010");
  EXPECT_EQ(to_string(CanFrame::remote(0x702)), "702#R");
  EXPECT_EQ(parse_frame("602#40.00.10"), CanFrame::make(0x602, {0x40, 0x00, 0x10}));
  EXPECT_FALSE(parse_frame("800#00"));
  EXPECT_FALSE(parse_frame("602#123"));
}

}  // namespace
}  // namespace fieldgate::sim::canopen
