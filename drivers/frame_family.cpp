#include "drivers/frame_family.hpp"

#include <fmt/format.h>

namespace fieldgate {

asio::awaitable<Reply> FrameFamily::transact(Link&, const NodeAddress&, const Request& request,
                                             const LinkTiming&) {
  Reply r;
  r.status = Reply::Status::link_down;
  r.text = fmt::format("'{}': the {} family runs on a CAN bus (can: {{interface: ...}})",
                       request.command, name());
  co_return r;
}

}  // namespace fieldgate
