#pragma once
/// \file test_labels.hpp
/// Where a test is defined, what kind it is — instead of lists of names kept elsewhere. A long or
/// timing test says so in its first line; the sanitizer builds (STROMA_SANITIZED: ASan + UBSan,
/// TSan) skip it with the reason (ctest shows it as skipped), the release suite runs it. Tests
/// that are not gtest cases carry the same as ctest LABELS where tests/CMakeLists.txt adds them
/// (`long`: left out of the sanitizer stage with `ctest -LE long`).

#include <gtest/gtest.h>

#if defined(STROMA_SANITIZED)
/// A whole-scene physics run of 20–460 s under the sanitizers whose code shorter tests exercise there.
#define STROMA_LONG_TEST() GTEST_SKIP() << "long: run by the release suite, not under the sanitizers"
/// Measures µs timing, which the sanitizers' slowdown makes meaningless.
#define STROMA_TIMING_TEST() GTEST_SKIP() << "timing: run by the release suite, not under the sanitizers"
#else
#define STROMA_LONG_TEST() static_cast<void>(0)
#define STROMA_TIMING_TEST() static_cast<void>(0)
#endif
