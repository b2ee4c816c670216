#include "gateway/bus/bus.hpp"

namespace fieldgate {

std::optional<int> Bus::number_of(const NodeImage& image) const {
  const auto images = node_images();
  for (std::size_t i = 0; i < images.size(); ++i)
    if (images[i].get() == &image) return first_node_index() + static_cast<int>(i);
  return std::nullopt;
}

}  // namespace fieldgate
