#pragma once

#include <chrono>
#include <cstddef>

#include "gateway/image/process_image.hpp"
#include "mapping/model.hpp"

namespace fieldgate {

// Whether a point's value may be served as current: it has a value, and, if its bus polls it,
// neither did its last polls all fail (node.freshness.failed_polls in a row) nor is it older
// than its age bound. A point the bus does not poll (write-only, kept by the gateway, read once)
// is fresh once it has a value, and so is every point of a node whose line an action holds
// (nothing can be polled until the motion's handshake; the values read are the last ones).
bool point_is_fresh(const NodeImage& node, const Model& model, std::size_t point_index,
                    SteadyTime now);

// How old a polled point's value may be: node.freshness.periods of its poll period (or of the
// time the bus took between its last two values, where the line stretches the periods), at least
// node.freshness.at_least; zero when it has no bound (not polled, or periods 0).
std::chrono::microseconds point_age_bound(const NodeImage& node, const Model& model,
                                          std::size_t point_index);

}  // namespace fieldgate
