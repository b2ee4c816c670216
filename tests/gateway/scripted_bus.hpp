#pragma once

// A bus for tests of what sits above the buses (the control service, the register map, the
// action runner): it records each command and the node number it went to, and answers it at once
// with the next scripted reply. A reload may renumber its nodes or take one away (reload()).

#include <boost/asio/awaitable.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gateway/bus/bus.hpp"
#include "gateway/bus/wire_trace.hpp"

namespace fieldgate::test {

// Answers every command at once with the next scripted reply (ok when none is left).
class ScriptedBus : public Bus {
 public:
  std::vector<std::string> sent;
  std::vector<int> sent_to;
  std::vector<Reply> replies;
  std::function<void(const std::string&)> on_command;  // called as each command goes out

  ScriptedBus() = default;
  explicit ScriptedBus(std::vector<std::shared_ptr<NodeImage>> images)
      : images_(std::move(images)) {}
  void reload(std::vector<std::shared_ptr<NodeImage>> images) {
    images_ = std::move(images);
    ++numbering_;
  }

  boost::asio::awaitable<void> run() override { co_return; }
  void stop() override {}
  boost::asio::awaitable<Reply> submit(int node, Request request, CommandOptions options) override {
    sent.push_back(request.command);
    sent_to.push_back(node);
    if (options.on_sent) options.on_sent();
    if (on_command) on_command(request.command);
    Reply reply;
    reply.status = Reply::Status::ok;
    if (!replies.empty()) {
      reply = replies.front();
      replies.erase(replies.begin());
    }
    co_return reply;
  }
  const BusConfig& config() const override { return config_; }
  const BusCounters& counters() const override { return counters_; }
  WireTrace& trace() override { return trace_; }
  const NodeConfig& node_config(int) const override { return node_; }
  std::vector<std::shared_ptr<NodeImage>> node_images() const override { return images_; }
  void rebind(int, NodeUpdated) override {}
  int first_node_index() const override { return 0; }

 private:
  std::vector<std::shared_ptr<NodeImage>> images_;
  BusConfig config_;
  BusCounters counters_;
  WireTrace trace_{"test"};
  NodeConfig node_;
};

}  // namespace fieldgate::test
