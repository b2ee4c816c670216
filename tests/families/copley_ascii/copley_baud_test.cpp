// The §4.1 baud procedure of the Copley family against a transport that behaves like an
// amplifier on a real UART: it hears and answers only when host and amplifier run at the same
// rate, and its `ok` to a rate change comes at the new rate.
#include <gtest/gtest.h>

#include <boost/asio/co_spawn.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/this_coro.hpp>
#include <boost/asio/use_awaitable.hpp>
#include <boost/asio/use_future.hpp>

#include <charconv>
#include <cstring>
#include <deque>

#include "drivers/copley_ascii/copley_family.hpp"

namespace fieldgate {
namespace {

class AmplifierOnUart final : public ByteTransport {
 public:
  // wants_axis: a multi-axis amplifier that answers e 33 to a command without an axis letter.
  AmplifierOnUart(unsigned host_baud, unsigned amp_baud, bool wants_axis = false)
      : host_(host_baud), amp_(amp_baud), wants_axis_(wants_axis) {}

  asio::awaitable<std::error_code> open() override { co_return std::error_code{}; }
  void close() override {}
  bool is_open() const override { return true; }
  asio::awaitable<std::error_code> write(std::string_view bytes) override {
    if (host_ != amp_) co_return std::error_code{};  // framing errors: the amplifier hears noise
    line_ += bytes;
    if (line_.back() != '\r') co_return std::error_code{};
    std::string command = line_.substr(0, line_.size() - 1);
    line_.clear();
    commands.push_back(command);
    if (wants_axis_) {
      if (command.rfind(".a ", 0) != 0) {
        reply("e 33", amp_);
        co_return std::error_code{};
      }
      command = command.substr(3);
    }
    if (command == "g r0x90") {
      reply("v " + std::to_string(amp_), amp_);
    } else if (command.rfind("s r0x90 ", 0) == 0) {
      unsigned rate = 0;
      std::from_chars(command.data() + 8, command.data() + command.size(), rate);
      amp_ = rate;
      reply("ok", rate);  // sent at the new rate
    } else {
      reply("ok", amp_);
    }
    co_return std::error_code{};
  }
  asio::awaitable<std::pair<std::error_code, std::size_t>> read_some(
      asio::mutable_buffer buffer) override {
    const auto n = read_available(buffer);
    if (n > 0) co_return std::pair{std::error_code{}, n};
    // Nothing the host can decode: wait until cancelled by the caller's timer.
    asio::steady_timer forever(co_await asio::this_coro::executor, std::chrono::hours(1));
    co_await forever.async_wait(asio::use_awaitable);
    co_return std::pair{std::error_code{}, std::size_t{0}};
  }
  std::size_t read_available(asio::mutable_buffer buffer) override {
    while (!pending_.empty() && pending_.front().second != host_) pending_.pop_front();  // noise
    if (pending_.empty()) return 0;
    const std::string text = pending_.front().first;
    pending_.pop_front();
    std::memcpy(buffer.data(), text.data(), std::min(buffer.size(), text.size()));
    return std::min(buffer.size(), text.size());
  }
  void discard_input() override { pending_.clear(); }
  std::string describe() const override { return "fake UART"; }
  double char_time_us() const override { return 0; }
  std::error_code set_baud(unsigned baud) override {
    host_ = baud;
    return {};
  }
  unsigned baud() const override { return host_; }

  unsigned amplifier_baud() const { return amp_; }
  std::vector<std::string> commands;

 private:
  void reply(const std::string& text, unsigned rate) { pending_.push_back({text + "\r", rate}); }
  unsigned host_, amp_;
  bool wants_axis_;
  std::string line_;
  std::deque<std::pair<std::string, unsigned>> pending_;
};

std::vector<std::string> open_link(AmplifierOnUart& uart) {
  asio::io_context io;
  Link link(uart);
  CopleyFamily family;
  LinkTiming timing{std::chrono::milliseconds(20), std::chrono::milliseconds(5)};
  auto done = asio::co_spawn(io, family.on_link_open(link, timing), asio::use_future);
  io.run();
  done.get();
  std::vector<std::string> texts;
  for (auto& note : link.take_notes()) texts.push_back(std::move(note.text));
  return texts;
}

TEST(CopleyBaud, SwitchesAnAmplifierAtItsPowerUpRate) {
  AmplifierOnUart uart(115200, 9600);
  const auto notes = open_link(uart);
  EXPECT_EQ(uart.amplifier_baud(), 115200u);
  EXPECT_EQ(uart.baud(), 115200u);
  // The plain probe at 115200 goes unheard; so does the axis form that follows it.
  EXPECT_EQ(uart.commands, (std::vector<std::string>{"g r0x90", "s r0x90 115200"}));
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_EQ(notes[0], "Copley gateway amplifier switched from 9600 to 115200 baud");
}

TEST(CopleyBaud, LeavesAnAmplifierAlreadyAtTheConfiguredRate) {
  AmplifierOnUart uart(115200, 115200);
  EXPECT_TRUE(open_link(uart).empty());
  EXPECT_EQ(uart.commands, std::vector<std::string>{"g r0x90"});
}

TEST(CopleyBaud, ReportsASilentLineAndKeepsTheConfiguredRate) {
  AmplifierOnUart uart(115200, 38400);  // neither rate works
  const auto notes = open_link(uart);
  EXPECT_EQ(uart.baud(), 115200u);
  EXPECT_TRUE(uart.commands.empty());
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("does not answer at 115200 baud (no reply) nor at its power-up rate "
                          "9600 (no reply)"),
            std::string::npos)
      << notes[0];
}

// Issue 12 item 7: a 2-axis amplifier that wants an axis letter answers the plain probe with
// e 33. That is an answer: at the configured rate nothing is switched and nothing is logged.
TEST(CopleyBaud, AMultiAxisAmplifierAlreadyAtTheConfiguredRateIsLeftAlone) {
  AmplifierOnUart uart(115200, 115200, true);
  EXPECT_TRUE(open_link(uart).empty());
  EXPECT_EQ(uart.baud(), 115200u);
  EXPECT_EQ(uart.commands, (std::vector<std::string>{"g r0x90", ".a g r0x90"}));
}

TEST(CopleyBaud, AMultiAxisAmplifierAtItsPowerUpRateIsSwitchedWithTheAxisForm) {
  AmplifierOnUart uart(115200, 9600, true);
  const auto notes = open_link(uart);
  EXPECT_EQ(uart.amplifier_baud(), 115200u);
  EXPECT_EQ(uart.baud(), 115200u);
  EXPECT_EQ(uart.commands,
            (std::vector<std::string>{"g r0x90", ".a g r0x90", ".a s r0x90 115200"}));
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("switched from 9600 to 115200"), std::string::npos) << notes[0];
}

TEST(CopleyBaud, NothingToDoAt9600) {
  AmplifierOnUart uart(9600, 9600);
  EXPECT_TRUE(open_link(uart).empty());
  EXPECT_TRUE(uart.commands.empty());
}

}  // namespace
}  // namespace fieldgate
