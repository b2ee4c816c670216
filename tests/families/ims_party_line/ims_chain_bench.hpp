#pragma once

#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/use_future.hpp>

#include <chrono>
#include <cstdint>
#include <future>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "drivers/ims_party_line/ims_family.hpp"
#include "tests/families/ims_party_line/chain_transport.hpp"

namespace fieldgate::test {

// An axis of the party line by its name, and the requests a model sends it.
inline NodeAddress unit(char name) {
  return {std::string(1, name), static_cast<unsigned char>(name), 0};
}
inline Request read(const char* c) {
  return {c, Request::Expect::values, NumberFormat::decimal};
}
inline Request write(const char* c) {
  return {c, Request::Expect::ack, NumberFormat::decimal};
}

// The IMS family on a Link to a simulated party line in process: attach() (re)builds the chain,
// transact() runs one request to completion on the bench's io_context.
class ImsChainBench {
 protected:
  explicit ImsChainBench(LinkTiming timing) : timing_(timing) {}

  void attach(sim::ims::PartyLineOptions options) {
    link_.reset();
    transport_ = std::make_unique<ChainTransport>(io_, std::move(options));
    link_ = std::make_unique<Link>(*transport_);
  }

  template <typename T>
  T run(asio::awaitable<T> work) {
    using namespace std::chrono_literals;
    auto future = asio::co_spawn(io_, std::move(work), asio::use_future);
    io_.restart();
    while (future.wait_for(0s) != std::future_status::ready) io_.run_one_for(10ms);
    return future.get();
  }

  Reply transact(char name, const Request& r) {
    return run(family_.transact(*link_, unit(name), r, timing_));
  }

  // Places B at -2500 and C at 777 (A stays at 0) and checks that each axis answers Z with its own.
  void expect_each_axis_reads_its_position() {
    control("position", {"B", "-2500"});
    control("position", {"C", "777"});
    EXPECT_EQ(transact('A', read("Z")).values, std::vector<int64_t>{0});
    EXPECT_EQ(transact('B', read("Z")).values, std::vector<int64_t>{-2500});
    EXPECT_EQ(transact('C', read("Z")).values, std::vector<int64_t>{777});
  }

  sim::ims::PartyLine& chain() { return transport_->chain(); }
  std::string control(const std::string& verb, std::vector<std::string> args) {
    return chain().control(verb, args, sim::SimClock::now()).value_or("?");
  }

  asio::io_context io_;
  std::unique_ptr<ChainTransport> transport_;
  std::unique_ptr<Link> link_;
  ImsPartyLineFamily family_;
  LinkTiming timing_;
};

}  // namespace fieldgate::test
