#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>

namespace fieldgate::sparkplug {

// What a Sparkplug host application sees of a group: every edge node and device, born or dead,
// with its metrics decoded (data that names metrics by alias is resolved with the birth's
// names). Fed with the messages of spBv1.0/GROUP/# and spBv1.0/STATE/#; no I/O.
class FleetView {
 public:
  struct MetricState {
    std::string value;     // as text: a number, true/false, the string, or "null"
    std::string datatype;  // Int32, String, ...
    uint64_t timestamp_ms = 0;
  };
  struct Device {
    bool born = false;
    uint64_t changed_ms = 0;  // the last birth or death
    uint64_t messages = 0;
    std::map<std::string, MetricState> metrics;
    std::map<uint64_t, std::string> aliases;
  };
  struct EdgeNode {
    bool born = false;
    std::optional<uint64_t> bd_seq;  // of the session its last NBIRTH began
    std::optional<uint64_t> seq;     // the last message's
    uint64_t changed_ms = 0;
    uint64_t messages = 0;
    uint64_t seq_gaps = 0;  // a message whose seq did not follow the one before
    std::map<std::string, MetricState> metrics;
    std::map<uint64_t, std::string> aliases;
    std::map<std::string, Device> devices;
  };

  // Takes one message; returns it as a person reads it: one line (type, edge node, device,
  // seq, and for a death what it ended), then one indented line per metric.
  std::string take(std::string_view topic, std::string_view payload, uint64_t now_ms);

  const std::map<std::string, EdgeNode>& edge_nodes() const { return nodes_; }
  // Primary host applications by id, with their last STATE payload (JSON text).
  const std::map<std::string, std::string>& hosts() const { return hosts_; }
  uint64_t malformed() const { return malformed_; }

 private:
  std::map<std::string, EdgeNode> nodes_;
  std::map<std::string, std::string> hosts_;
  uint64_t malformed_ = 0;
};

}  // namespace fieldgate::sparkplug
