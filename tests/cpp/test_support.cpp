#include "test_support.h"

#include <filesystem>

#include "myoskin/errors.h"

namespace myoskin::test {

std::string sharedPath(const std::string& relative) {
  const char* env = std::getenv("MYOSKIN_SHARED_DIR");
  std::string root = env && *env ? env : MYOSKIN_SHARED_DIR;
  return root + "/" + relative;
}

bool exists(const std::string& path) { return std::filesystem::exists(path); }

std::string inputErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace myoskin::test
