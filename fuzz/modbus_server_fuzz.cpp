// The Modbus TCP server's input path: MBAP framing of a byte stream cut at fuzzer-chosen
// points, PDU parsing, dispatch to a request handler and response encoding.
#include <algorithm>
#include <cstring>
#include <stdexcept>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/detached.hpp>
#include <boost/asio/io_context.hpp>

#include "fuzz/fuzz_input.hpp"
#include "gateway/modbus/mbap.hpp"
#include "gateway/modbus/request_handler.hpp"

namespace {

using namespace fieldgate::modbus;

// Answers everything below address 100 with values, above it with an exception.
class Handler : public RequestHandler {
 public:
  ReadBitsResult read_bits(std::uint8_t, BitTable, std::uint16_t address,
                           std::uint16_t count) override {
    if (address >= 100) return ExceptionCode::illegal_data_address;
    return std::vector<bool>(count, true);
  }
  ReadRegistersResult read_registers(std::uint8_t, RegisterTable, std::uint16_t address,
                                     std::uint16_t count) override {
    if (address >= 100) return ExceptionCode::gateway_target_failed;
    return std::vector<std::uint16_t>(count, address);
  }
  asio::awaitable<WriteResult> write_registers(std::uint8_t, std::uint16_t address,
                                               std::span<const std::uint16_t>) override {
    if (address >= 100) co_return ExceptionCode::server_device_failure;
    co_return WriteResult::success();
  }
  asio::awaitable<WriteResult> write_coils(std::uint8_t, std::uint16_t address,
                                           std::vector<bool>) override {
    if (address == 7) throw std::runtime_error("handler failure");
    co_return WriteResult::success();
  }
  DeviceIdentificationResult device_identification(std::uint8_t unit) override {
    if (unit == 0) return ExceptionCode::gateway_path_unavailable;
    return DeviceIdentification{{0, std::string(unit, 'v')}, {1, "p"}, {2, "1.0"}, {6, "app"}};
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fieldgate::fuzz::Input input(data, size);
  const std::size_t chunk = 1 + input.byte() % 64;  // how the stream arrives
  const std::string_view stream = input.rest();

  asio::io_context io;
  Handler handler;
  MbapFramer framer;
  std::size_t offset = 0;
  bool open = true;
  while (open && offset < stream.size()) {
    const auto space = framer.free_space();
    FUZZ_CHECK(!space.empty());
    const std::size_t n = std::min({chunk, space.size(), stream.size() - offset});
    std::memcpy(space.data(), stream.data() + offset, n);
    framer.commit(n);
    offset += n;
    MbapFramer::Frame frame;
    MbapFramer::Status status;
    while ((status = framer.next(frame)) == MbapFramer::Status::frame) {
      FUZZ_CHECK(!frame.pdu.empty() && frame.pdu.size() <= max_pdu_size);
      std::vector<std::uint8_t> response;
      asio::co_spawn(io, dispatch(handler, frame.header.unit_id, frame.pdu),
                     [&response](std::exception_ptr e, std::vector<std::uint8_t> r) {
                       FUZZ_CHECK(!e);
                       response = std::move(r);
                     });
      io.run();
      io.restart();
      FUZZ_CHECK(!response.empty() && response.size() <= max_pdu_size);
      FUZZ_CHECK((response[0] & 0x7F) == (frame.pdu[0] & 0x7F));
      std::vector<std::uint8_t> adu;
      encode_adu(frame.header.transaction_id, frame.header.unit_id, response, adu);
      FUZZ_CHECK(adu.size() <= max_adu_size);
    }
    open = status == MbapFramer::Status::need_more;
  }
  return 0;
}
