#include "gateway/image/node_turn.hpp"

#include <boost/asio/as_tuple.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>

namespace fieldgate {

namespace asio = boost::asio;

HeldTurn::HeldTurn(std::shared_ptr<NodeTurnState> state)
    : state_(std::move(state)), previous_release_(state_->released) {
  state_->taken = true;
}

HeldTurn::~HeldTurn() {
  state_->taken = false;
  state_->released = std::chrono::steady_clock::now();
  if (!state_->waiting.empty()) {
    state_->waiting.front()->cancel();
    state_->waiting.pop_front();
  }
}

asio::awaitable<std::shared_ptr<HeldTurn>> take_turn(std::shared_ptr<NodeTurnState> state) {
  const auto executor = co_await asio::this_coro::executor;
  while (state->taken) {
    auto wake = std::make_shared<asio::steady_timer>(executor,
                                                     std::chrono::steady_clock::time_point::max());
    state->waiting.push_back(wake);
    co_await wake->async_wait(asio::as_tuple(asio::use_awaitable));
  }
  co_return std::make_shared<HeldTurn>(std::move(state));
}

}  // namespace fieldgate
