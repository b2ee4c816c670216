// One CANopen node's requests as the bus runs them: a rendered request parsed (the grammar in
// canopen_request.hpp) and carried out as SDO uploads and downloads on the node's SdoChannel, a
// `wait` step's uploads until the value matches, NMT commands, and the values a transfer brings
// stored into the node's points; also the transfers the supervision asks for (bring-up, a node
// that stays pre-operational, node guarding) and the probe of an offline node. The bus runtime
// hosts it behind RequestHost: it owns the port, the counters, the reply accounting
// (online/offline) and the node's worker that waits.
#pragma once

#include <boost/asio/awaitable.hpp>

#include <cstdint>
#include <optional>
#include <vector>

#include "drivers/canopen/absent_objects.hpp"
#include "drivers/canopen/canopen_request.hpp"
#include "drivers/canopen/node_points.hpp"
#include "drivers/canopen/node_supervision.hpp"
#include "drivers/canopen/sdo_channel.hpp"
#include "drivers/frame_family.hpp"

namespace fieldgate::canopen {

// What a node's requests need of the bus runtime that hosts the node.
class RequestHost : public NodeHost {
 public:
  virtual FramePort& port() = 0;
  // A transfer ended after `seconds`: counted, with its latency.
  virtual void transfer_done(double seconds) = 0;
  // A poll's transfer is tried once more.
  virtual void retrying() = 0;
  // A transfer's reply, for the node's reply accounting (online, offline); `sent`: when its
  // request went out (a timeout of one the node's restart dropped takes it not offline).
  virtual void record(const Reply& reply, TimePoint sent, TimePoint at) = 0;
  // The points take these values (from a read, a confirmed write) at `at`.
  virtual void store(const std::vector<PointUpdate>& updates, TimePoint at) = 0;
  // A confirmed write re-armed the heartbeat consumer.
  virtual void heartbeat_rearmed() = 0;
  // A polled object is absent from the node: its points take these values at `at` and are
  // polled no more (not counted in the data age).
  virtual void object_absent(const std::vector<PointUpdate>& updates, TimePoint at) = 0;
  // An urgent command waits: a running `wait` step gives way to it.
  virtual bool urgent_pending() const = 0;
  // Sleeps until `when`, or until the worker is woken.
  virtual asio::awaitable<void> pause_until(TimePoint when) = 0;
};

class NodeRequests {
 public:
  NodeRequests(uint8_t id, SdoChannel& sdo, NodeSupervision& nmt, const NodePoints& points,
               RequestHost& host);

  // One request (a command), run in the form the family compiled at load with the request's
  // arguments (a request without one is refused unsent); a write's timeout counts as done where
  // the command accepts no reply.
  asio::awaitable<Reply> execute(const Request& request, bool accept_no_reply, TimePoint now);
  // The frame of a request that goes out at once, without a transfer (NMT), or none.
  std::optional<CanFrame> immediate_frame(const Request& request) const;
  // The supervision's duty (NodeSupervision::duty) carried out before commands and polls: the
  // heartbeat producer time 0x1017 written, NMT start sent, the error register of a node that
  // stays pre-operational read (with `retries`) and reported, a node-guarding request sent.
  // False where none is due now. `reachable`: the node is not offline.
  asio::awaitable<bool> run_supervision_duty(bool reachable, int retries);
  // Is an offline node there again? Its device type 0x1000, which every CiA 301 device has,
  // uploaded once.
  asio::awaitable<void> probe(TimePoint now);
  // Transfers start at `now` (the caller's clock reading) and record the time their last frame
  // arrived in finished_at: one clock reading per transfer, which matters where reading the
  // clock is a system call (User-Mode Linux).
  asio::awaitable<Reply> upload(const ObjectAddress& object, int retries, TimePoint now);
  // A command's download: a written 0x1017 is the node's producer time from then on.
  asio::awaitable<Reply> download(const Operation& op, TimePoint now);
  // A poll's upload: an object the node turns out not to have (AbsentObjects) is logged once,
  // its points read 0 (an empty string), and it is not uploaded again until the node boots.
  asio::awaitable<Reply> poll(const ObjectAddress& object, int retries, TimePoint now);
  AbsentObjects& absent_objects() { return absent_; }

  TimePoint finished_at{};  // when the last transfer ended

 private:
  asio::awaitable<Reply> upload(const ObjectAddress& object, int retries, TimePoint now,
                                bool polled);
  asio::awaitable<Reply> download(const Operation& op, TimePoint now, bool by_command);
  // A poll found `object` absent (abort `code`): marked, logged once, its points set.
  Reply object_absent(const ObjectAddress& object, uint32_t code, TimePoint at);
  asio::awaitable<Reply> wait_for(const Operation& op);
  // Bring-up (CiA 302): the heartbeat producer time the consumer expects, written to 0x1017.
  asio::awaitable<void> configure_heartbeat(TimePoint now);
  // A node that stays pre-operational after NMT start: its error register, read and reported.
  asio::awaitable<void> report_pre_operational(int retries, TimePoint now);
  // The node's last abort, for its point, where the server aborted.
  void note_abort(const SdoResult& result);
  // Every point read from `object` takes the value its bytes hold (a confirmed write, a read).
  void store_object(uint16_t index, uint8_t sub, std::span<const uint8_t> bytes, TimePoint at);

  // The request's compiled operation with its arguments filled in.
  static std::optional<Operation> operation_of(const Request& request, std::string& error);

  uint8_t id_;
  SdoChannel& sdo_;
  NodeSupervision& nmt_;
  const NodePoints& points_;
  RequestHost& host_;
  AbsentObjects absent_;
};

}  // namespace fieldgate::canopen
