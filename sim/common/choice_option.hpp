#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <utility>
#include <vector>

namespace fieldgate::sim {

// The names a command-line option takes and the value each one stands for.
template <class Value>
using Choices = std::vector<std::pair<std::string, Value>>;

// Adds `name`, an option that takes one of the names of `choices` (--help lists them, any other
// is refused) and sets `target` to the value that name stands for; without the option `target`
// keeps its value. A family's main.cpp lists each name once, with its meaning.
template <class Value>
CLI::Option* add_choice(CLI::App& app, std::string name, Value& target, Choices<Value> choices,
                        std::string help) {
  std::vector<std::string> names;
  for (const auto& choice : choices) names.push_back(choice.first);
  const auto take = [&target, choices = std::move(choices)](const std::string& named) {
    for (const auto& choice : choices) {
      if (choice.first == named) target = choice.second;
    }
  };
  return app.add_option_function<std::string>(std::move(name), take, std::move(help))
      ->check(CLI::IsMember(std::move(names)));
}

}  // namespace fieldgate::sim
