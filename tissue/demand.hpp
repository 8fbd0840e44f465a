#pragma once
/// \file demand.hpp
/// STROMA_DEMAND(condition, message): an invariant check, as Drake's DRAKE_DEMAND — on in debug
/// builds and in the sanitizer builds (STROMA_SANITIZED: the CI's ASan + UBSan and TSan
/// stages), compiled out in Release. A failed demand prints the condition, where, and the
/// message (a std::string or C string, evaluated only on failure) and aborts: a broken invariant
/// is a bug in the engine, never bad input (input is checked at load: InputError).

#include <cstdio>
#include <cstdlib>
#include <string>

namespace stroma {

[[noreturn]] inline void demand_failed(const char* condition, const std::string& message, const char* file, int line) {
  std::fprintf(stderr, "%s:%d: STROMA_DEMAND(%s) failed: %s\n", file, line, condition, message.c_str());
  std::abort();
}

}  // namespace stroma

#if !defined(NDEBUG) || defined(STROMA_SANITIZED)
#define STROMA_DEMANDS_ON 1
#define STROMA_DEMAND(condition, message) \
  ((condition) ? static_cast<void>(0) : ::stroma::demand_failed(#condition, (message), __FILE__, __LINE__))
#else
#define STROMA_DEMANDS_ON 0
#define STROMA_DEMAND(condition, message) static_cast<void>(0)
#endif
