#pragma once
/// \file input_error.hpp
/// The one exception type for bad input found at load time (mesh files, scenario files,
/// material parameters). It carries where the problem is (file, line, field) so the message a
/// user sees points at the exact spot to fix. The 1 kHz loop never throws: it uses status codes.

#include <stdexcept>
#include <string>

namespace stroma {

/// Bad input detected while loading or compiling. `what()` is the full, user-facing message:
/// "FILE:LINE: FIELD: MESSAGE" (parts that are unknown are omitted).
class InputError : public std::runtime_error {
 public:
  InputError(std::string file, int line, std::string field, std::string message)
      : std::runtime_error(format(file, line, field, message)),
        file_(std::move(file)), line_(line), field_(std::move(field)), message_(std::move(message)) {}

  const std::string& file() const { return file_; }
  /// 1-based line number, or 0 when not known.
  int line() const { return line_; }
  const std::string& field() const { return field_; }
  const std::string& message() const { return message_; }

 private:
  static std::string format(const std::string& file, int line, const std::string& field,
                            const std::string& message) {
    std::string s;
    if (!file.empty()) {
      s += file;
      if (line > 0) {
        s += ':';
        s += std::to_string(line);
      }
      s += ": ";
    }
    if (!field.empty()) {
      s += field;
      s += ": ";
    }
    s += message;
    return s;
  }
  std::string file_;
  int line_;
  std::string field_;
  std::string message_;
};

}  // namespace stroma
