#include "drivers/copley_ascii/copley_family.hpp"
#include "drivers/protocol_family.hpp"

namespace fieldgate {

// The explicit list of families; a static registrar would be dropped by the static linker.
FamilyPtr make_family(std::string_view name) {
  if (name == "copley-ascii") return std::make_shared<CopleyFamily>();
  return nullptr;
}

std::vector<std::string> family_names() {
  return {"copley-ascii"};
}

}  // namespace fieldgate
