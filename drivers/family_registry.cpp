#include "drivers/protocol_family.hpp"

// The families are listed in family_list.inc, which drivers/CMakeLists.txt generates from the
// family folders (README.md "Adding a family"): an explicit table, because a static registrar
// would be dropped by the static linker.

namespace fieldgate {

namespace {

struct FamilyEntry {
  const char* name;
  FamilyPtr (*make)();
};

}  // namespace

#include "family_list.inc"

FamilyPtr make_family(std::string_view name) {
  for (const auto& f : kFamilies)
    if (name == f.name) return f.make();
  return nullptr;
}

std::vector<std::string> family_names() {
  std::vector<std::string> names;
  for (const auto& f : kFamilies) names.emplace_back(f.name);
  return names;
}

}  // namespace fieldgate
