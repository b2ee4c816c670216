#pragma once

#include <string_view>
#include <vector>

namespace fieldgate::sim {

// The parts of `text` between `separator`s, empty ones included ("" gives one empty part): the
// lists of the command lines ("0,3,5", "4:XY,5:W") and instructions within a line ("V=10;G").
// The parts view `text`.
std::vector<std::string_view> split(std::string_view text, char separator);

}  // namespace fieldgate::sim
