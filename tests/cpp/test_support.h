// Helpers shared by the C++ tests: where the shared characters are, and skipping when they are absent.
#pragma once
#include <gtest/gtest.h>

#include <functional>
#include <string>

namespace myoskin::test {

// Absolute path of a file under ../shared (e.g. "characters/makehuman_neutral/makehuman_neutral.glb").
std::string sharedPath(const std::string& relative);
// True if the file exists.
bool exists(const std::string& path);
// The message of the InputError that f throws, or "" when it throws none.
std::string inputErrorOf(const std::function<void()>& f);

}  // namespace myoskin::test

// Skips the current test with a clear message when a shared file is missing.
#define MYOSKIN_REQUIRE_SHARED(path)                                                            \
  do {                                                                                          \
    if (!::myoskin::test::exists(path))                                                         \
      GTEST_SKIP() << "needs " << (path) << " (the ../shared folder beside the repository)";    \
  } while (0)
