#pragma once

#include <string>
#include <vector>

namespace fieldgate {

// Where a configuration item came from; line and column are 1-based as editors show them.
struct SourceMark {
  std::string file;
  int line = 0;
  int column = 0;
};

std::string to_string(const SourceMark& mark);

struct Diagnostic {
  SourceMark mark;
  std::string message;
};

// Collects every configuration error of one load so a user sees them all at once.
class Diagnostics {
 public:
  void error(const SourceMark& mark, std::string message);
  bool ok() const { return errors_.empty(); }
  const std::vector<Diagnostic>& errors() const { return errors_; }
  void append(const Diagnostics& other);
  // One line per error: "file:line:column: message".
  std::string to_text() const;

 private:
  std::vector<Diagnostic> errors_;
};

}  // namespace fieldgate
