#pragma once

#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/protocol_file/protocol_spec.hpp"
#include "mapping/diagnostics.hpp"

namespace fieldgate::protocol_file {

// Reads one protocol file (docs/protocol-files.md). Every error is reported at its
// file:line:column, a field of a template at the column of its '{'; nullptr when any was found.
ProtocolSpecPtr load_protocol_file(const std::string& path, Diagnostics& diagnostics);

// What to add to a YAML syntax error about an unclosed flow list or mapping when its line holds
// a {placeholder} (in a flow collection `{` opens a mapping): the cause and what to do; empty
// when the error is of another kind.
std::string flow_collection_hint(std::string_view yaml_message, std::string_view line);

// Every *.yaml protocol file of the given directories, by protocol name.
class ProtocolLibrary {
 public:
  void load_directory(const std::string& directory, Diagnostics& diagnostics);
  void add(ProtocolSpecPtr spec, Diagnostics& diagnostics);
  ProtocolSpecPtr find(std::string_view name) const;
  std::vector<ProtocolSpecPtr> all() const;

 private:
  std::map<std::string, ProtocolSpecPtr, std::less<>> specs_;
};

}  // namespace fieldgate::protocol_file
