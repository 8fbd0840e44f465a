#pragma once
/// \file option_error.hpp
/// A front end's command-line option that cannot work (`stroma serve --budget-margin-ms 2` on
/// a 1 ms period, `stroma render --fps 0`): the server's and the renderer's own error, apart
/// from the scene files' InputError (tissue/input_error.hpp, FILE:LINE: FIELD). `what()` is
/// "OPTION: MESSAGE"; the CLI prints it and exits 2, as for any bad input.

#include <stdexcept>
#include <string>

namespace stroma {

class OptionError : public std::runtime_error {
 public:
  OptionError(std::string option, const std::string& message)
      : std::runtime_error(option + ": " + message), option_(std::move(option)) {}
  /// The option as typed on the command line, e.g. "--fps".
  const std::string& option() const { return option_; }

 private:
  std::string option_;
};

}  // namespace stroma
