#include "drivers/protocol_family.hpp"

// The explicit list of families (a static registrar would be dropped by the static linker).
// Each family folder defines FIELDGATE_FAMILY_<NAME> and a make_<name>_family() function.

namespace fieldgate {

#ifdef FIELDGATE_FAMILY_COPLEY_ASCII
FamilyPtr make_copley_ascii_family();
#endif
#ifdef FIELDGATE_FAMILY_IMS_PARTY_LINE
FamilyPtr make_ims_party_line_family();
#endif
#ifdef FIELDGATE_FAMILY_CENTENT_CN0170
FamilyPtr make_centent_cn0170_family();
#endif
#ifdef FIELDGATE_FAMILY_TECHNO_C
FamilyPtr make_techno_c_family();
#endif
#ifdef FIELDGATE_FAMILY_WHEDCO_CMC
FamilyPtr make_whedco_cmc_family();
#endif
#ifdef FIELDGATE_FAMILY_CANOPEN
FamilyPtr make_canopen_family();
#endif

namespace {

struct FamilyEntry {
  const char* name;
  FamilyPtr (*make)();
};

constexpr FamilyEntry kFamilies[] = {
#ifdef FIELDGATE_FAMILY_COPLEY_ASCII
    {"copley-ascii", make_copley_ascii_family},
#endif
#ifdef FIELDGATE_FAMILY_IMS_PARTY_LINE
    {"ims-party-line", make_ims_party_line_family},
#endif
#ifdef FIELDGATE_FAMILY_CENTENT_CN0170
    {"centent-cn0170", make_centent_cn0170_family},
#endif
#ifdef FIELDGATE_FAMILY_TECHNO_C
    {"techno-c", make_techno_c_family},
#endif
#ifdef FIELDGATE_FAMILY_WHEDCO_CMC
    {"whedco-cmc", make_whedco_cmc_family},
#endif
#ifdef FIELDGATE_FAMILY_CANOPEN
    {"canopen", make_canopen_family},
#endif
};

}  // namespace

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
