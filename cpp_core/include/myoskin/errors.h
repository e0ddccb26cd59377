// Exceptions thrown by the core. The Python layer maps InputError to ValueError and
// MyoskinError to RuntimeError; the CLI prints what() on one line and exits non-zero.
#pragma once
#include <stdexcept>
#include <string>

namespace myoskin {

// Any failure of the core that is not the caller's input.
struct MyoskinError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// The input is unusable (missing file, wrong format, NaN, non-manifold, ...). what() says why.
struct InputError : MyoskinError {
  using MyoskinError::MyoskinError;
};

}  // namespace myoskin
