#pragma once

// Checks on texts a test reads back whole (a captured log, a diagnostics report): each expected
// fragment must appear somewhere; a failure names the fragment and shows the whole text.

#include <gtest/gtest.h>

#include <initializer_list>
#include <string_view>

namespace fieldgate::test {

inline void expect_contains(std::string_view text,
                            std::initializer_list<std::string_view> fragments) {
  for (const std::string_view fragment : fragments)
    EXPECT_NE(text.find(fragment), std::string_view::npos) << "missing: " << fragment << "\n"
                                                           << text;
}

}  // namespace fieldgate::test
