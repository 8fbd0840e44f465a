#pragma once
/// \file input_error_message.hpp
/// message_of: what a load step says when it refuses its input, for the tests of error paths.

#include <functional>
#include <string>

#include "tissue/input_error.hpp"

namespace stroma::test_support {

/// The message of the InputError that `f` throws, or "(no error)" when it throws none, so that an
/// expectation on the message fails visibly when nothing was refused. Other exceptions propagate.
inline std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace stroma::test_support
