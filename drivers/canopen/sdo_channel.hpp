// One node's SDO transfers on a frame port: the client's steps sent, its responses handed over
// by the bus's reader, its deadlines waited on. One transfer at a time per node; every node has
// its own channel, so transfers to different nodes overlap on the wire.
#pragma once

#include <boost/asio/awaitable.hpp>
#include <boost/asio/steady_timer.hpp>

#include <optional>
#include <string_view>

#include "drivers/canopen/canopen_request.hpp"
#include "drivers/canopen/sdo_client.hpp"
#include "drivers/frame_family.hpp"

namespace fieldgate::canopen {

// How a transfer came out, as the wire trace names it on the frame that ends it.
std::string_view trace_outcome(SdoResult::Status status);
// The reply of a finished transfer: the server's abort is a device error with its code, our own
// abort a garbled reply, no response a timeout.
Reply reply_of(const SdoResult& result);
// The reply of a finished upload of `object`: its value (an integer object) or its bytes (in
// text and values, for string points, which slice the bytes themselves); garbled where the
// bytes do not hold the type.
Reply upload_reply(const ObjectAddress& object, const SdoResult& result);

class SdoChannel {
 public:
  // `wake` is the timer the node's worker waits on: a response cancels it, and so must the bus
  // when the link goes down or it stops, so that a waiting transfer gives up.
  SdoChannel(uint8_t node, std::chrono::microseconds timeout, asio::steady_timer& wake);

  // A frame from the node's SDO server (COB-ID 0x580 + node). Returns its outcome for the wire
  // trace: "late" where no transfer was running, the result where it ended one.
  std::string_view on_response(const CanFrame& frame, TimePoint now);
  // One transfer from its first step to its result; nullopt when the port went down. Every
  // response's arrival time is written to `finished_at` (the transfer reads no clock where a
  // frame told the time).
  asio::awaitable<std::optional<SdoResult>> run(SdoStep first, FramePort& port,
                                                TimePoint& finished_at);

  SdoClient& client() { return client_; }

 private:
  SdoClient client_;
  asio::steady_timer& wake_;
  std::optional<SdoStep> step_;  // delivered by the reader, taken by run()
  TimePoint step_time_{};        // when step_ was delivered
};

}  // namespace fieldgate::canopen
