// The CANopen SDO client's state table fed arbitrary frames and clock ticks during uploads and
// downloads, plus the heartbeat and emergency parsers and the candump text parser.
#include "drivers/canopen/sdo_client.hpp"
#include "fuzz/fuzz_input.hpp"

namespace {

using namespace fieldgate::canopen;
using fieldgate::CanFrame;
using fieldgate::parse_frame;

void check_step(const SdoStep& step, const SdoClient& client) {
  if (step.send) FUZZ_CHECK(step.send->len <= 8);
  if (step.done && step.done->status == SdoResult::Status::ok) {
    FUZZ_CHECK(step.done->data.size() <= SdoClient::kMaxUpload);
  }
  (void)client.state_name();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fieldgate::fuzz::Input input(data, size);
  const std::uint8_t node = 1 + input.byte() % 127;
  SdoClient client(node, std::chrono::milliseconds(100));
  auto now = TimePoint{} + std::chrono::seconds(1);
  for (int events = 0; events < 512 && !input.rest().empty(); ++events) {
    const std::uint8_t op = input.byte();
    SdoStep step;
    switch (op % 8) {
      case 0:
        step = client.upload(static_cast<std::uint16_t>(input.byte() << 8 | input.byte()),
                             input.byte(), now);
        break;
      case 1: {
        std::vector<std::uint8_t> bytes(input.byte() % 24);
        for (auto& b : bytes) b = input.byte();
        step = client.download(0x2000, input.byte(), std::move(bytes), now);
        break;
      }
      case 2:
        now += std::chrono::milliseconds(input.byte());
        step = client.on_time(now);
        break;
      case 3:
        step = client.abort(0x08000000);
        break;
      default: {
        // Mostly frames from the node's SDO server, sometimes from anywhere.
        CanFrame frame;
        frame.id = (op & 0x10) ? (input.byte() << 8 | input.byte()) & 0x7FF : cob::sdo_tx + node;
        frame.len = input.byte() % 10;  // 9 is invalid on purpose
        frame.rtr = op & 0x20;
        frame.error = op & 0x40;
        for (auto& b : frame.data) b = input.byte();
        if (frame.len > 8) frame.len = 8;
        step = client.on_frame(frame, now);
        (void)parse_heartbeat(frame);
        (void)parse_emergency(frame);
      }
    }
    check_step(step, client);
  }
  (void)parse_frame(input.rest());
  return 0;
}
