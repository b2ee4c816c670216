#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace fieldgate::sparkplug {

// Sparkplug B 3.0 topic namespace: spBv1.0/<group_id>/<message_type>/<edge_node_id>[/<device_id>],
// and the primary host application's spBv1.0/STATE/<host_id>.
inline constexpr std::string_view kNamespace = "spBv1.0";

enum class MessageType { nbirth, ndeath, dbirth, ddeath, ndata, ddata, ncmd, dcmd };
std::string_view to_string(MessageType type);

class TopicNamespace {
 public:
  TopicNamespace(std::string group_id, std::string edge_node_id)
      : group_(std::move(group_id)), edge_(std::move(edge_node_id)) {}

  std::string node_topic(MessageType type) const;
  std::string device_topic(MessageType type, std::string_view device_id) const;
  // The subscriptions of an edge node: its NCMD and every device's DCMD.
  std::string ncmd_filter() const { return node_topic(MessageType::ncmd); }
  std::string dcmd_filter() const;
  static std::string state_topic(std::string_view host_id);

  // A command topic addressed to this edge node.
  struct Command {
    MessageType type;  // ncmd or dcmd
    std::string device_id;
  };
  std::optional<Command> parse_command(std::string_view topic) const;

 private:
  std::string group_;
  std::string edge_;
};

}  // namespace fieldgate::sparkplug
