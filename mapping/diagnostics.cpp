#include "mapping/diagnostics.hpp"

#include <fmt/format.h>

namespace fieldgate {

std::string to_string(const SourceMark& mark) {
  if (mark.line == 0) return mark.file;
  return fmt::format("{}:{}:{}", mark.file, mark.line, mark.column);
}

void Diagnostics::error(const SourceMark& mark, std::string message) {
  errors_.push_back({mark, std::move(message)});
}

void Diagnostics::append(const Diagnostics& other) {
  errors_.insert(errors_.end(), other.errors_.begin(), other.errors_.end());
}

std::string Diagnostics::to_text() const {
  std::string text;
  for (const auto& e : errors_)
    text += fmt::format("{}: error: {}\n", to_string(e.mark), e.message);
  return text;
}

}  // namespace fieldgate
