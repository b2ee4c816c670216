#include "mapping/model.hpp"

namespace fieldgate {

namespace {
template <typename T>
const T* find_named(const std::vector<T>& items, const std::string& name) {
  for (const auto& item : items)
    if (item.name == name) return &item;
  return nullptr;
}
}  // namespace

const BitDef* PointDef::find_bit(const std::string& bit_name) const {
  return find_named(bits, bit_name);
}
const PointDef* Model::find_point(const std::string& n) const {
  return find_named(points, n);
}
const SetpointDef* Model::find_setpoint(const std::string& n) const {
  return find_named(setpoints, n);
}
const ActionDef* Model::find_action(const std::string& n) const {
  return find_named(actions, n);
}
const PollClassDef* Model::find_poll_class(const std::string& n) const {
  return find_named(poll_classes, n);
}
const ProfileAxisDef* Model::find_profile_axis(const std::string& n) const {
  return find_named(profile_axes, n);
}
const ActionDef* Model::find_action(uint16_t code) const {
  for (const auto& a : actions)
    if (a.code == code) return &a;
  return nullptr;
}

}  // namespace fieldgate
