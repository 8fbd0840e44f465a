#pragma once
/// \file inflate.hpp
/// Bounded zlib/gzip inflation shared by the readers of compressed data (VTU DataArray blocks,
/// gzip/zlib label images). One implementation, fuzzed through both readers.

#include <cstddef>
#include <string>
#include <string_view>

namespace stroma {

/// What inflate_bounded did. Invariants: `produced` ≤ the `want` asked for; `ended` only when
/// zlib reached the stream's end marker and verified its checksum.
struct InflateOutcome {
  size_t produced = 0;  ///< bytes appended to the output
  bool ended = false;   ///< the end marker (checksum verified) was reached
  std::string error;    ///< empty, or why the stream is unusable, in words for a message
};

/// How inflate_bounded treats the stream after `want` bytes.
enum class InflateTail {
  unchecked,  ///< stop at `want` bytes; the rest of the stream is not read
  /// go on to the end marker, discarding, so the checksum is verified: a stream cut inside its
  /// trailer or with a bad checksum is an error; a stream longer than `want` by more than 64 MB
  /// is left unread (containers that pad their data)
  verified,
  /// as `verified`, and any byte past `want` is an error (the container announced the exact size)
  exact,
};

/// Inflates the zlib or gzip stream (auto-detected from its header) in `src`, appending at most
/// `want` bytes to `out`. The output grows with what really inflates, never to `want` up front,
/// so a small hostile stream whose container claims gigabytes costs only what it inflates to.
/// Running out of input before `want` bytes is not an error: `produced < want` lets the caller
/// say "truncated" with its own context. Corrupt data is an error. Never throws for bad data.
InflateOutcome inflate_bounded(std::string_view src, size_t want, InflateTail tail, std::string& out);

}  // namespace stroma
