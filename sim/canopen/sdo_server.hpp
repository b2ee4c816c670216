// CiA 301 SDO server of one node: expedited and segmented upload and download. No I/O and no
// clock of its own: requests come in with the time they arrived, responses go out as return
// values, and on_time() turns a stalled segmented transfer into an abort.
#pragma once

#include "can_frame.hpp"
#include "object_dictionary.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <span>

namespace fieldgate::sim::canopen {

using SdoPayload = std::array<std::uint8_t, 8>;

SdoPayload sdo_abort_payload(std::uint16_t index, std::uint8_t sub, SdoAbort code);

class SdoServer {
 public:
  explicit SdoServer(ObjectDictionary& od,
                     std::chrono::milliseconds timeout = std::chrono::milliseconds(1000))
      : od_(od), timeout_(timeout) {}

  std::optional<SdoPayload> on_request(const SdoPayload& request, TimePoint now);
  std::optional<SdoPayload> on_time(TimePoint now);
  std::optional<TimePoint> deadline() const;
  void reset();

  const char* state_name() const { return state_->name; }
  bool idle() const { return state_ == &kIdle; }

 private:
  struct Result;
  struct State {
    const char* name;
    Result (SdoServer::*on_recv)(const SdoPayload& request, TimePoint now);
  };
  struct Result {
    const State* next;
    std::optional<SdoPayload> reply;
  };

  static const State kIdle;
  static const State kDownloadSegments;
  static const State kUploadSegments;

  Result idle_recv(const SdoPayload& request, TimePoint now);
  Result download_segment_recv(const SdoPayload& request, TimePoint now);
  Result upload_segment_recv(const SdoPayload& request, TimePoint now);

  Result initiate_download(const SdoPayload& request, TimePoint now);
  Result initiate_upload(const SdoPayload& request, TimePoint now);
  Result abort(SdoAbort code) const;
  // A segment request of the transfer in progress that ends it instead: the client's abort, or
  // another command specifier than `expected`, or the toggle bit out of step.
  std::optional<Result> segment_refused(const SdoPayload& request, std::uint8_t expected) const;

  ObjectDictionary& od_;
  std::chrono::milliseconds timeout_;
  const State* state_ = &kIdle;

  // The segmented transfer in progress.
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  bool toggle_ = false;
  bool size_known_ = false;
  std::size_t size_ = 0;
  std::size_t max_size_ = 0;
  std::size_t offset_ = 0;
  Bytes buffer_;
  TimePoint deadline_{};
};

}  // namespace fieldgate::sim::canopen
