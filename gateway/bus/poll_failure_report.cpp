#include "gateway/bus/poll_failure_report.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace fieldgate {

void PollFailureReport::failed(const std::vector<int>& points, std::string_view why) {
  ++untold_;
  last_why_ = why;
  for (const int p : points) {
    const auto point = static_cast<std::size_t>(p);
    if (std::find(points_.begin(), points_.end(), point) == points_.end()) points_.push_back(point);
  }
}

std::optional<PollFailureReport::Line> PollFailureReport::due(std::string_view bus,
                                                              std::string_view node,
                                                              const NodeImage& image,
                                                              const Model& model, SteadyTime now) {
  if (untold_ == 0 || (told_ && now - *told_ < kInterval)) return std::nullopt;
  const uint32_t stale_after = image.freshness.failed_polls;
  bool any_stale = false;
  std::string points;
  for (const auto p : points_) {
    if (p >= image.points.size() || p >= model.points.size()) continue;
    const PointValue& v = image.points[p];
    const bool stale = stale_after > 0 && v.failed_polls >= stale_after;
    any_stale = any_stale || stale;
    points += fmt::format("{}{} {} in a row, {} in all{}", points.empty() ? "" : "; ",
                          model.points[p].name, v.failed_polls, v.failed_polls_total,
                          stale ? " (stale: answered 0x0B)" : "");
  }
  const std::string since =
      told_ ? fmt::format(" in the last {} s",
                          std::chrono::duration_cast<std::chrono::seconds>(now - *told_).count())
            : std::string{};
  Line line{any_stale ? log::Level::warning : log::Level::notice,
            fmt::format("bus {} node {}: {} failed poll(s){} (last: {}): {}", bus, node, untold_,
                        since, last_why_, points)};
  untold_ = 0;
  points_.clear();
  told_ = now;
  return line;
}

}  // namespace fieldgate
