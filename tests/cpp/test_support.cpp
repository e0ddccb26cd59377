#include "test_support.h"

#include <filesystem>

namespace myoskin::test {

std::string sharedPath(const std::string& relative) {
  const char* env = std::getenv("MYOSKIN_SHARED_DIR");
  std::string root = env && *env ? env : MYOSKIN_SHARED_DIR;
  return root + "/" + relative;
}

bool exists(const std::string& path) { return std::filesystem::exists(path); }

}  // namespace myoskin::test
