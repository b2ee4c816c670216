#pragma once

#include <cstddef>
#include <deque>
#include <memory>

namespace fieldgate {

// The configurations a bus that reconfigures in place keeps alive: the first, which owns its
// family and what the family bound then, and the last few, which a transaction still under way
// may read. Older ones are let go, so that a site that changes a node's settings on every reload
// does not keep every configuration it ever ran. A node bound from a later configuration keeps
// that one itself (the bus's node runtime).
class RetainedConfigs {
 public:
  explicit RetainedConfigs(std::shared_ptr<const void> first) : first_(std::move(first)) {}

  void push(std::shared_ptr<const void> latest) {
    recent_.push_back(std::move(latest));
    while (recent_.size() > kRecent) recent_.pop_front();
  }
  std::size_t size() const { return 1 + recent_.size(); }

 private:
  // A transaction lasts seconds and a reload is a person's act: three reloads within one
  // transaction are not expected.
  static constexpr std::size_t kRecent = 3;
  std::shared_ptr<const void> first_;
  std::deque<std::shared_ptr<const void>> recent_;
};

}  // namespace fieldgate
