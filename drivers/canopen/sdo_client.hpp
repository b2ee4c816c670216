// CiA 301 SDO client of one node: expedited and segmented upload and download. No I/O and no
// clock of its own, like Lely's csdo: a transfer starts with upload()/download(), every response
// frame goes to on_frame(), time moves only through on_time(), and each event returns what to
// send and, at the end, the result. One transfer at a time; the bus runs one client per node,
// so transfers to different nodes overlap.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/canopen/canopen_codec.hpp"
#include "drivers/canopen/canopen_time.hpp"
#include "drivers/transport/can_frame.hpp"

namespace fieldgate::canopen {

struct SdoResult {
  enum class Status {
    ok,
    server_abort,  // the server aborted: abort_code says why
    client_abort,  // we aborted (protocol error, toggle, length): abort_code is what we sent
    timeout,       // no response in time; we sent abort 0x05040000
  };
  Status status = Status::ok;
  uint32_t abort_code = 0;
  std::vector<uint8_t> data;  // uploaded bytes
  std::string text;           // the reason, for anything but ok
};

// What the caller does after an event: send the frame (if any), then, if done is set, the
// transfer has ended with that result.
struct SdoStep {
  std::optional<CanFrame> send;
  std::optional<SdoResult> done;
};

class SdoClient {
 public:
  static constexpr std::size_t kMaxUpload = 65536;

  explicit SdoClient(uint8_t node,
                     std::chrono::microseconds timeout = std::chrono::milliseconds(100));

  uint8_t node() const { return node_; }
  // Time allowed for each response (initiate and every segment).
  void set_timeout(std::chrono::microseconds timeout) { timeout_ = timeout; }

  SdoStep upload(uint16_t index, uint8_t sub, TimePoint now);
  SdoStep download(uint16_t index, uint8_t sub, std::vector<uint8_t> data, TimePoint now);
  // A frame from the node's SDO server (COB-ID 0x580 + node).
  SdoStep on_frame(const CanFrame& frame, TimePoint now);
  SdoStep on_time(TimePoint now);
  // Gives up the running transfer, telling the server (e.g. the bus is stopping).
  SdoStep abort(uint32_t code);

  std::optional<TimePoint> deadline() const;
  bool idle() const { return state_ == &kIdle; }
  const char* state_name() const { return state_->name; }
  // Responses that belonged to no transfer (late answers to a transfer that timed out).
  uint64_t ignored_frames() const { return ignored_; }

 private:
  struct State {
    const char* name;
    SdoStep (SdoClient::*on_recv)(const SdoPayload& response, TimePoint now);
  };
  static const State kIdle;
  static const State kUploadInitiate;
  static const State kUploadSegment;
  static const State kDownloadInitiate;
  static const State kDownloadSegment;

  SdoStep idle_recv(const SdoPayload& response, TimePoint now);
  SdoStep upload_initiate_recv(const SdoPayload& response, TimePoint now);
  SdoStep upload_segment_recv(const SdoPayload& response, TimePoint now);
  SdoStep download_initiate_recv(const SdoPayload& response, TimePoint now);
  SdoStep download_segment_recv(const SdoPayload& response, TimePoint now);

  bool same_object(const SdoPayload& response) const;
  std::optional<SdoStep> screen(const SdoPayload& response, uint8_t expected,
                                std::string_view request, TimePoint now);
  SdoStep toggle_mismatch();
  SdoStep busy() const;
  void begin(uint16_t index, uint8_t sub, std::vector<uint8_t> data);
  SdoStep request(const State& next, const SdoPayload& payload, TimePoint now);
  SdoStep next_download_segment(TimePoint now);
  SdoStep finish_ok();
  // Every way a transfer fails: the result and, where the server still holds the transfer
  // open, the abort that tells it.
  enum class Tell { server, nobody };
  static SdoResult failure(SdoResult::Status status, uint32_t code, std::string text);
  SdoStep end(SdoResult::Status status, uint32_t code, std::string text, Tell tell);
  SdoStep server_abort(const SdoPayload& response);
  SdoStep client_abort(uint32_t code, std::string why);
  SdoStep finish(SdoResult result, std::optional<CanFrame> send = std::nullopt);

  uint8_t node_;
  std::chrono::microseconds timeout_;
  const State* state_ = &kIdle;
  TimePoint deadline_{};
  uint64_t ignored_ = 0;

  // The transfer in progress.
  uint16_t index_ = 0;
  uint8_t sub_ = 0;
  bool toggle_ = false;
  std::optional<uint32_t> size_;  // announced by the server (upload)
  std::vector<uint8_t> data_;     // received (upload) or to send (download)
  std::size_t offset_ = 0;        // download: bytes sent so far
};

}  // namespace fieldgate::canopen
