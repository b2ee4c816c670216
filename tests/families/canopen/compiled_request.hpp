#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "drivers/canopen/canopen_request.hpp"
#include "drivers/protocol_family.hpp"

namespace fieldgate::test {

// A command as the gateway sends one from a model's template: compiled against the node's model
// (a failure to compile fails the test), with its placeholders' values in template order.
inline Request compiled_request(const std::string& text, const Model* model,
                                std::vector<int64_t> arguments = {}, bool bus_wide = false) {
  std::string error;
  std::shared_ptr<const CompiledCommand> compiled;
  if (const auto command = CommandTemplate::compile(text, error))
    compiled = canopen::compile_operation(*command, model, error);
  if (!compiled) ADD_FAILURE() << "'" << text << "' does not compile: " << error;
  return Request{text,     Request::Expect::ack, NumberFormat::decimal, bus_wide,
                 compiled, std::move(arguments)};
}

}  // namespace fieldgate::test
