// Shared by the libFuzzer targets (tests/fuzz/fuzz_*.cpp): every target feeds untrusted bytes to one reader or
// stage of the core. The contract it checks: the core returns a valid result or throws InputError with a
// message; anything else (another exception, a crash, a sanitizer report, a leak, a hang) is a finding.
#pragma once
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <algorithm>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>

#include "myoskin/errors.h"

namespace myoskin::fuzz {

// A private scratch folder per fuzzer process (the loaders read files; a glTF may name sibling files, which
// then resolve inside this empty folder only).
inline const std::filesystem::path& scratchDir() {
  static const std::filesystem::path dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    std::filesystem::path d = std::filesystem::path(tmp && *tmp ? tmp : "/tmp") /
                              ("myoskin-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

// Writes the bytes to scratchDir()/name and returns the path.
inline std::string writeScratch(const std::string& name, const uint8_t* data, size_t size) {
  const std::string path = (scratchDir() / name).string();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) {
    std::fprintf(stderr, "fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
  return path;
}

// A broken invariant of a result the core accepted: report and abort (libFuzzer saves the input).
[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz: invariant broken: %s\n", what.c_str());
  std::abort();
}

// Runs `body`; InputError is the expected refusal (its message must say something), anything else aborts.
template <typename F>
void expectInputErrorOnly(F&& body) {
  try {
    body();
  } catch (const InputError& e) {
    if (std::string(e.what()).size() < 5) fail(std::string("InputError without a reason: '") + e.what() + "'");
    static const bool verbose = std::getenv("MYOSKIN_FUZZ_VERBOSE") != nullptr;  // see why inputs are refused
    if (verbose) std::fprintf(stderr, "refused: %s\n", e.what());
  } catch (const std::exception& e) {
    fail(std::string("escaped as a non-InputError exception: ") + e.what());
  } catch (...) {
    fail("escaped as a non-standard exception");
  }
}

template <typename M>
void requireFinite(const M& m, const std::string& what) {
  if (!m.allFinite()) fail(what + " has a NaN or infinite value");
}

}  // namespace myoskin::fuzz

namespace myoskin::fuzz {

// Reads fixed-size little-endian values from the front of the input (zeros once it runs out).
class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  template <typename T>
  T take() {
    T value{};
    const size_t n = std::min(sizeof(T), size_ - pos_);
    std::memcpy(&value, data_ + pos_, n);
    pos_ += n;
    return value;
  }
  size_t remaining() const { return size_ - pos_; }

 private:
  const uint8_t* data_;
  size_t size_, pos_ = 0;
};

}  // namespace myoskin::fuzz
