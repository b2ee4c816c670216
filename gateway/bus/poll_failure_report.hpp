#pragma once

#include <chrono>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/image/process_image.hpp"
#include "gateway/lifecycle/log.hpp"
#include "mapping/model.hpp"

namespace fieldgate {

// The failed polls of one node, for the log: the first failure is told at once, later ones at
// most once per kInterval, each line with the count since the line before and, per point
// concerned, its failed polls in a row and in all, and whether that made it stale (0x0B).
class PollFailureReport {
 public:
  static constexpr std::chrono::minutes kInterval{1};

  struct Line {
    log::Level level;  // warning once a point concerned is stale, else notice
    std::string text;
  };

  // A poll feeding `points` (model point indexes) failed; `why` says how (the reply's text).
  void failed(const std::vector<int>& points, std::string_view why);
  // The line to write at `now`, if failures wait to be told and the last line is old enough.
  std::optional<Line> due(std::string_view bus, std::string_view node, const NodeImage& image,
                          const Model& model, SteadyTime now);

 private:
  uint64_t untold_ = 0;              // failed polls since the last line
  std::vector<std::size_t> points_;  // concerned since the last line, in the order first seen
  std::string last_why_;
  std::optional<SteadyTime> told_;
};

}  // namespace fieldgate
