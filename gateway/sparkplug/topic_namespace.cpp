#include "gateway/sparkplug/topic_namespace.hpp"

#include <fmt/format.h>

namespace fieldgate::sparkplug {

std::string_view to_string(MessageType type) {
  switch (type) {
    case MessageType::nbirth:
      return "NBIRTH";
    case MessageType::ndeath:
      return "NDEATH";
    case MessageType::dbirth:
      return "DBIRTH";
    case MessageType::ddeath:
      return "DDEATH";
    case MessageType::ndata:
      return "NDATA";
    case MessageType::ddata:
      return "DDATA";
    case MessageType::ncmd:
      return "NCMD";
    case MessageType::dcmd:
      return "DCMD";
  }
  return "?";
}

std::string TopicNamespace::node_topic(MessageType type) const {
  return fmt::format("{}/{}/{}/{}", kNamespace, group_, to_string(type), edge_);
}

std::string TopicNamespace::device_topic(MessageType type, std::string_view device_id) const {
  return fmt::format("{}/{}/{}/{}/{}", kNamespace, group_, to_string(type), edge_, device_id);
}

std::string TopicNamespace::dcmd_filter() const {
  return fmt::format("{}/{}/DCMD/{}/+", kNamespace, group_, edge_);
}

std::string TopicNamespace::state_topic(std::string_view host_id) {
  return fmt::format("{}/STATE/{}", kNamespace, host_id);
}

std::optional<TopicNamespace::Command> TopicNamespace::parse_command(std::string_view topic) const {
  const std::string node_prefix = node_topic(MessageType::ncmd);
  if (topic == node_prefix) return Command{MessageType::ncmd, {}};
  const std::string device_prefix = fmt::format("{}/{}/DCMD/{}/", kNamespace, group_, edge_);
  if (topic.starts_with(device_prefix)) {
    const auto device = topic.substr(device_prefix.size());
    if (!device.empty() && device.find('/') == std::string_view::npos)
      return Command{MessageType::dcmd, std::string(device)};
  }
  return std::nullopt;
}

}  // namespace fieldgate::sparkplug
