/// \file inflate.cpp
/// inflate_bounded on zlib's streaming API: input and output fed in chunks zlib's 32-bit counters
/// can take, the output doubled from 64 KB as it fills.

#include "io/inflate.hpp"

#include <zlib.h>

#include <algorithm>

namespace stroma {

namespace {

constexpr size_t kMaxChunk = size_t{1} << 30;        // below zlib's uInt limit
constexpr size_t kTailLimit = size_t{1} << 26;       // bytes discarded while seeking the end marker

std::string corrupt(const z_stream& z) {
  return std::string("corrupt compressed data (") + (z.msg ? z.msg : "zlib error") + ")";
}

}  // namespace

InflateOutcome inflate_bounded(std::string_view src, size_t want, InflateTail tail, std::string& out) {
  InflateOutcome r;
  z_stream z{};
  if (inflateInit2(&z, 32 + MAX_WBITS) != Z_OK) {  // 32: accept a zlib or a gzip header
    r.error = "zlib could not start";
    return r;
  }
  const size_t base = out.size();
  size_t in_pos = 0;
  int rc = Z_OK;
  // One inflate call into `room` bytes at `dst`; returns the bytes it wrote.
  auto step = [&](char* dst, size_t room) {
    const size_t in_chunk = std::min(src.size() - in_pos, kMaxChunk);
    const size_t out_chunk = std::min(room, kMaxChunk);
    z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(src.data() + in_pos));
    z.avail_in = static_cast<uInt>(in_chunk);
    z.next_out = reinterpret_cast<Bytef*>(dst);
    z.avail_out = static_cast<uInt>(out_chunk);
    rc = inflate(&z, Z_NO_FLUSH);
    in_pos += in_chunk - z.avail_in;
    return out_chunk - z.avail_out;
  };
  size_t cap = std::min<size_t>(want, size_t{1} << 16);
  out.resize(base + cap);
  while (r.produced < want) {
    if (r.produced == cap) {
      cap = std::min(want, 2 * cap);
      out.resize(base + cap);
    }
    r.produced += step(out.data() + base + r.produced, cap - r.produced);
    if (rc == Z_STREAM_END) break;
    if (rc == Z_BUF_ERROR && in_pos >= src.size()) break;  // input ended early: the caller's "truncated"
    if (rc != Z_OK) {
      r.error = corrupt(z);
      break;
    }
  }
  out.resize(base + r.produced);
  r.ended = rc == Z_STREAM_END;
  if (tail != InflateTail::unchecked && r.error.empty() && r.produced == want && !r.ended) {
    char scratch[1 << 14];
    size_t extra = 0;
    while (true) {
      extra += step(scratch, sizeof scratch);
      if (tail == InflateTail::exact && extra > 0) {
        r.error = "the compressed data inflates to more bytes than announced";
        break;
      }
      if (rc == Z_STREAM_END) {
        r.ended = true;
        break;
      }
      if (rc == Z_BUF_ERROR && in_pos >= src.size()) {
        r.error = "truncated: the compressed stream stops before its end (checksum) marker";
        break;
      }
      if (rc != Z_OK) {
        r.error = corrupt(z);
        break;
      }
      if (extra > kTailLimit) break;  // more data than announced: the rest is not read
    }
  }
  inflateEnd(&z);
  return r;
}

}  // namespace stroma
