#pragma once

#include <boost/asio/awaitable.hpp>
#include <boost/asio/steady_timer.hpp>

#include <chrono>
#include <deque>
#include <memory>
#include <utility>
#include <vector>

namespace fieldgate {

// Whose action steps a node's line carries: one action at a time, so that the steps of two
// actions for one node (two axes commanded in the same PLC scan) never interleave. Polls still
// go between steps; only another action's steps wait, in the order they asked.
struct NodeTurnState {
  bool taken = false;
  std::deque<std::shared_ptr<boost::asio::steady_timer>> waiting;
  // When the last holder let go: a value polled before then may predate that action's effect.
  std::chrono::steady_clock::time_point released{};
};

// A taken turn; letting go of the last reference hands the turn to the next in line.
class HeldTurn {
 public:
  explicit HeldTurn(std::shared_ptr<NodeTurnState> state);
  ~HeldTurn();
  HeldTurn(const HeldTurn&) = delete;
  HeldTurn& operator=(const HeldTurn&) = delete;

  // When the holder before this one let go.
  std::chrono::steady_clock::time_point previous_release() const { return previous_release_; }

 private:
  std::shared_ptr<NodeTurnState> state_;
  std::chrono::steady_clock::time_point previous_release_;
};

// Waits until the node's turn is free and takes it.
boost::asio::awaitable<std::shared_ptr<HeldTurn>> take_turn(std::shared_ptr<NodeTurnState> state);

// What an action runs with, fixed when its command is accepted: a later write of a setpoint (or
// another axis's command) changes none of it.
struct ActionArguments {
  std::vector<int64_t> setpoints;  // by model setpoint index
  // Setpoints taken from a polled point once the action has the node's turn (another axis's
  // position, for a move that names every axis), read after the previous holder let go.
  std::vector<std::pair<std::size_t, std::size_t>> hold;  // setpoint index, point index
  // The node's turn, already taken by the caller (which wrote points in it); else taken here.
  std::shared_ptr<HeldTurn> turn;
};

}  // namespace fieldgate
