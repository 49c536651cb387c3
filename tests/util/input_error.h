#pragma once
// The message of the InputError a call throws, for tests that check what an error names.

#include <string>
#include <utility>

#include "common/core/error.h"

namespace pf::testing {

// What `f()` throws as InputError, or "(no error)" when it returns.
template <typename F>
std::string InputErrorOf(F&& f) {
  try {
    std::forward<F>(f)();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace pf::testing
