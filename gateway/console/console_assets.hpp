#pragma once

#include <string_view>

namespace fieldgate {

// The console's pages, scripts and styles, compiled into the binary from gateway/console/assets
// (no network and no files at run time).
struct ConsoleAsset {
  std::string_view path;  // "/console.js"; "/" is index.html
  std::string_view content_type;
  std::string_view body;
};

// nullptr for a path that is not an asset.
const ConsoleAsset* find_console_asset(std::string_view path);

}  // namespace fieldgate
