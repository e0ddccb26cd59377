#include "myoskin/memory_budget.h"
#include <sys/resource.h>
#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include "myoskin/errors.h"

namespace myoskin {

namespace {

constexpr std::uint64_t kUnknown = std::numeric_limits<std::uint64_t>::max();
constexpr std::uint64_t kMiB = 1024ull * 1024ull;

// A "Key:   N kB" line of a /proc file, in bytes (kUnknown when absent).
std::uint64_t procField(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line))
    if (line.compare(0, key.size(), key) == 0 && line.size() > key.size() && line[key.size()] == ':') {
      std::istringstream fields(line.substr(key.size() + 1));
      std::uint64_t kib = 0;
      if (fields >> kib) return kib * 1024ull;
    }
  return kUnknown;
}

// The first number in a file (a cgroup's memory.max, memory.current); kUnknown for "max" or no file.
std::uint64_t fileNumber(const std::string& path) {
  std::ifstream in(path);
  std::string word;
  if (!(in >> word) || word.empty() || !std::isdigit(static_cast<unsigned char>(word[0]))) return kUnknown;
  return std::strtoull(word.c_str(), nullptr, 10);
}

// This process's cgroup v2 directory under /sys/fs/cgroup ("" when not on cgroup v2).
std::string cgroupDirectory() {
  std::ifstream in("/proc/self/cgroup");
  std::string line;
  while (std::getline(in, line))
    if (line.compare(0, 3, "0::") == 0) return "/sys/fs/cgroup" + line.substr(3);
  return "";
}

// MYOSKIN_MEMORY_LIMIT in bytes ("4G", "512M", "1048576"); kUnknown when unset; InputError when malformed.
std::uint64_t environmentLimit() {
  const char* text = std::getenv("MYOSKIN_MEMORY_LIMIT");
  if (!text || !*text) return kUnknown;
  char* end = nullptr;
  const double value = std::strtod(text, &end);
  std::uint64_t scale = 1;
  if (end && *end) {
    switch (std::toupper(static_cast<unsigned char>(*end))) {
      case 'K': scale = 1024ull; break;
      case 'M': scale = kMiB; break;
      case 'G': scale = 1024ull * kMiB; break;
      default: scale = 0;
    }
    ++end;
    if (*end == 'i' || *end == 'I') ++end;
    if (*end == 'b' || *end == 'B') ++end;
  }
  if (!(value > 0.0) || value > 1e18 || scale == 0 || (end && *end))
    throw InputError(std::string("MYOSKIN_MEMORY_LIMIT='") + text + "' is not a size (e.g. 4G, 512M or bytes)");
  return static_cast<std::uint64_t>(value * static_cast<double>(scale));
}

std::uint64_t minus(std::uint64_t limit, std::uint64_t used) {
  if (limit == kUnknown) return kUnknown;
  return used == kUnknown || used >= limit ? (used == kUnknown ? limit : 0) : limit - used;
}

}  // namespace

std::uint64_t availableMemoryBytes() {
  std::uint64_t available = procField("/proc/meminfo", "MemAvailable");
  const std::string group = cgroupDirectory();
  if (!group.empty())
    available = std::min(available, minus(fileNumber(group + "/memory.max"), fileNumber(group + "/memory.current")));
  rlimit address{};
  if (getrlimit(RLIMIT_AS, &address) == 0 && address.rlim_cur != RLIM_INFINITY)
    available = std::min(available, minus(address.rlim_cur, procField("/proc/self/status", "VmSize")));
  available = std::min(available, minus(environmentLimit(), procField("/proc/self/status", "VmRSS")));
  return available;
}

void requireMemory(std::uint64_t bytes, const std::string& what) {
  const std::uint64_t available = availableMemoryBytes();
  if (bytes <= available) return;
  throw InputError(what + " needs about " + std::to_string((bytes + kMiB - 1) / kMiB) + " MiB of memory, " +
                   std::to_string(available / kMiB) +
                   " MiB are available (free memory, the cgroup's memory.max, ulimit -v, MYOSKIN_MEMORY_LIMIT): "
                   "use a smaller skin (decimate it) or a machine with more memory");
}

std::uint64_t extractionMemoryEstimate(std::int64_t vertices) {
  return 32 * kMiB + static_cast<std::uint64_t>(std::max<std::int64_t>(vertices, 0)) * 850ull;
}

std::uint64_t hybridWeightsMemoryEstimate(std::int64_t vertices, std::int64_t muscles) {
  const auto v = static_cast<std::uint64_t>(std::max<std::int64_t>(vertices, 0));
  const auto m = static_cast<std::uint64_t>(std::max<std::int64_t>(muscles, 0));
  return 16 * kMiB + v * (300ull + 2ull * m);
}

std::uint64_t skinnerMemoryEstimate(std::int64_t vertices, std::int64_t influences) {
  const auto v = static_cast<std::uint64_t>(std::max<std::int64_t>(vertices, 0));
  const auto k = static_cast<std::uint64_t>(std::max<std::int64_t>(influences, 1));
  return 8 * kMiB + v * (48ull + 16ull * k);
}

}  // namespace myoskin
