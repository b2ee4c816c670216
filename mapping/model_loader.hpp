#pragma once

#include <map>
#include <string>
#include <vector>

#include "mapping/diagnostics.hpp"
#include "mapping/model.hpp"

namespace fieldgate {

// Loads one model file. Structural errors (unknown keys, wrong types, dangling references
// between points, setpoints and actions) are reported with file:line:column; the family's own
// checks (request syntax, data types) run later, when the family is known.
ModelPtr load_model_file(const std::string& path, Diagnostics& diagnostics);
ModelPtr load_model_text(const std::string& text, const std::string& name_for_errors,
                         Diagnostics& diagnostics);

// Every *.yaml model in the given directories, by model name. A name defined twice is an error
// naming both files.
class ModelLibrary {
 public:
  void load_directory(const std::string& directory, Diagnostics& diagnostics);
  void add(ModelPtr model, Diagnostics& diagnostics);
  ModelPtr find(const std::string& name) const;
  std::vector<std::string> names() const;
  // The library's own copy of the model, for its family to compile the command templates into
  // while the configuration loads, before anything runs on it (Family::compile_commands).
  Model* for_compiling(const std::string& name);

 private:
  std::map<std::string, std::shared_ptr<Model>> models_;
};

}  // namespace fieldgate
