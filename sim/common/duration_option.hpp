#pragma once

#include <CLI/CLI.hpp>
#include <chrono>
#include <string>
#include <utility>

namespace fieldgate::sim {

// Adds `name`, an option that takes a whole non-negative count of the duration's units
// (--boot-ms 250) and sets `target` to it; without the option `target` keeps its value.
template <class Rep, class Period>
CLI::Option* add_duration(CLI::App& app, std::string name,
                          std::chrono::duration<Rep, Period>& target, std::string help) {
  const auto take = [&target](const Rep& count) {
    target = std::chrono::duration<Rep, Period>(count);
  };
  return app.add_option_function<Rep>(std::move(name), take, std::move(help))
      ->check(CLI::NonNegativeNumber);
}

}  // namespace fieldgate::sim
