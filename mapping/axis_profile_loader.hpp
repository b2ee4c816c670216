#pragma once

#include <yaml-cpp/yaml.h>

#include "mapping/model.hpp"
#include "mapping/yaml_reader.hpp"

namespace fieldgate {

// Reads a model's axis_profile: section (after its points, setpoints and actions) into
// model.profile_axes: per axis, the points behind position, velocity and status bits, the
// setpoints the profile's values feed, and the actions behind each profile command. Every
// command is either mapped or listed under `unsupported`, so none is silently missing.
void parse_axis_profile(YamlReader& reader, const YAML::Node& node, Model& model);

}  // namespace fieldgate
