// Helpers shared by the fuzz targets: a check that survives -DNDEBUG, and a way to cut one
// input into a few parts (a split point, a mode byte) without a structured-input library.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#define FUZZ_CHECK(condition)       \
  do {                              \
    if (!(condition)) std::abort(); \
  } while (0)

namespace fieldgate::fuzz {

class Input {
 public:
  Input(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  // The next byte, or 0 once the input is used up.
  std::uint8_t byte() {
    if (size_ == 0) return 0;
    --size_;
    return *data_++;
  }
  std::string_view rest() const { return {reinterpret_cast<const char*>(data_), size_}; }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
};

// Feeds `text` to a frame splitter (length of the first complete frame, 0 while incomplete) as
// a link would, calling on_frame for each frame; checks the splitter never claims more bytes
// than it was given.
template <class Split, class OnFrame>
void split_frames(std::string_view text, Split split, OnFrame on_frame) {
  while (!text.empty()) {
    const std::size_t n = split(text);
    FUZZ_CHECK(n <= text.size());
    if (n == 0) break;
    on_frame(text.substr(0, n));
    text.remove_prefix(n);
  }
}

}  // namespace fieldgate::fuzz
