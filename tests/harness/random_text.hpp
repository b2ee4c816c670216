#pragma once

// Random texts for the robustness tests: strings of an alphabet's characters, of a length drawn
// from a range, from a seeded generator (so a failure repeats).

#include <cstddef>
#include <random>
#include <string>
#include <utility>

namespace fieldgate::test {

class RandomText {
 public:
  RandomText(unsigned seed, std::string alphabet, int min_length, int max_length)
      : random_(seed),
        alphabet_(std::move(alphabet)),
        pick_(0, alphabet_.size() - 1),
        length_(min_length, max_length) {}

  std::string next() {
    std::string text;
    for (int n = length_(random_); n > 0; --n) text += alphabet_[pick_(random_)];
    return text;
  }

 private:
  std::mt19937 random_;
  std::string alphabet_;
  std::uniform_int_distribution<std::size_t> pick_;
  std::uniform_int_distribution<int> length_;
};

}  // namespace fieldgate::test
