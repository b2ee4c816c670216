// The gateway configuration and model loaders on arbitrary text: every problem must become a
// diagnostic, never a crash, a hang or an uncaught exception. The first byte picks which.
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "fuzz/fuzz_input.hpp"
#include "gateway/config/config_loader.hpp"
#include "mapping/model_loader.hpp"

namespace {

namespace fs = std::filesystem;

// A scratch directory per process holding the config; models come from the source tree.
const fs::path& scratch() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("fieldgate-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fieldgate::fuzz::Input input(data, size);
  const bool model = input.byte() & 1;
  const std::string text(input.rest());
  fieldgate::Diagnostics diagnostics;
  if (model) {
    (void)fieldgate::load_model_text(text, "fuzz.yaml", diagnostics);
    return 0;
  }
  const fs::path path = scratch() / "fieldgate.yaml";
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << "models: " FIELDGATE_MODELS_DIR "\n" << text;
  }
  (void)fieldgate::load_gateway_config(path.string(), diagnostics);
  return 0;
}
