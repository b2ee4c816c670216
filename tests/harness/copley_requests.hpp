#pragma once

// What a Copley gateway amplifier at the far end of an in-memory line hears: the bytes written
// to it, split into CR-terminated requests, each with its CAN node prefix ("3 ") taken apart
// from the command. Shared by the in-process serial bus tests that play that amplifier.

#include <string>
#include <string_view>
#include <vector>

namespace fieldgate::test {

struct CopleyRequest {
  std::string line;     // as written, without the CR
  std::string prefix;   // "3 " for node 3 behind the amplifier; empty for the amplifier itself
  std::string command;  // the line without its prefix
};

class CopleyRequests {
 public:
  // Every request `bytes` completes, in the order written; a partial line waits for its CR.
  std::vector<CopleyRequest> take(std::string_view bytes) {
    pending_ += bytes;
    std::vector<CopleyRequest> complete;
    for (auto cr = pending_.find('\r'); cr != std::string::npos; cr = pending_.find('\r')) {
      CopleyRequest r;
      r.line = pending_.substr(0, cr);
      pending_.erase(0, cr + 1);
      r.command = r.line;
      if (r.line.size() > 2 && r.line[0] >= '1' && r.line[0] <= '9' && r.line[1] == ' ') {
        r.prefix = r.line.substr(0, 2);
        r.command = r.line.substr(2);
      }
      complete.push_back(std::move(r));
    }
    return complete;
  }

 private:
  std::string pending_;
};

}  // namespace fieldgate::test
