// tissue/inflate: the bounded inflation both compressed-data readers use — output bounded by
// what is asked, never allocated up front, corrupt and truncated streams told apart, the end
// marker's checksum verified when asked, and a stream longer than announced refused when exact.

#include <gtest/gtest.h>
#include <zlib.h>

#include <random>
#include <string>

#include "io/inflate.hpp"

using namespace stroma;

namespace {

std::string deflated(const std::string& in, bool gzip) {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, 6, Z_DEFLATED, gzip ? 16 + MAX_WBITS : MAX_WBITS, 8, Z_DEFAULT_STRATEGY), Z_OK);
  std::string out(deflateBound(&z, uLong(in.size())) + 64, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = uInt(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = uInt(out.size());
  EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

/// 300 KB that compress (runs) but not trivially (random run lengths): more than the first
/// 64 KB buffer, so the output has to grow.
std::string payload() {
  std::mt19937 rng(7);
  std::string s;
  while (s.size() < 300000) s.append(size_t(1 + rng() % 50), char('a' + rng() % 26));
  return s;
}

}  // namespace

TEST(Inflate, ZlibAndGzipInflateToTheirContentAndEnd) {
  const std::string in = payload();
  for (bool gzip : {false, true}) {
    std::string out = "prefix";
    const InflateOutcome r = inflate_bounded(deflated(in, gzip), in.size(), InflateTail::exact, out);
    EXPECT_TRUE(r.error.empty()) << r.error;
    EXPECT_TRUE(r.ended);
    EXPECT_EQ(r.produced, in.size());
    EXPECT_EQ(out, "prefix" + in);  // appended, the prefix kept
  }
}

TEST(Inflate, StopsAtWhatIsAskedAndChecksTheTailOnlyWhenAsked) {
  const std::string in = payload(), z = deflated(in, true);
  std::string out;
  InflateOutcome r = inflate_bounded(z, 1000, InflateTail::unchecked, out);
  EXPECT_TRUE(r.error.empty());
  EXPECT_FALSE(r.ended);
  EXPECT_EQ(out, in.substr(0, 1000));
  // verified: reads on to the end marker (checksum good), keeps 1,000 bytes.
  out.clear();
  r = inflate_bounded(z, 1000, InflateTail::verified, out);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_TRUE(r.ended);
  EXPECT_EQ(out.size(), 1000u);
  // exact: more than announced is an error.
  out.clear();
  r = inflate_bounded(z, 1000, InflateTail::exact, out);
  EXPECT_NE(r.error.find("more bytes than announced"), std::string::npos) << r.error;
}

TEST(Inflate, TruncationAndCorruptionAreToldApart) {
  const std::string in = payload(), z = deflated(in, true);
  std::string out;
  // Input cut in the middle: no error, fewer bytes (the caller says "truncated").
  InflateOutcome r = inflate_bounded(z.substr(0, z.size() / 2), in.size(), InflateTail::verified, out);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_GT(r.produced, 0u);
  EXPECT_LT(r.produced, in.size());
  EXPECT_FALSE(r.ended);
  // Cut inside the 8-byte gzip trailer: all the data, but no verified end.
  out.clear();
  r = inflate_bounded(z.substr(0, z.size() - 3), in.size(), InflateTail::verified, out);
  EXPECT_EQ(r.produced, in.size());
  EXPECT_NE(r.error.find("stops before its end"), std::string::npos) << r.error;
  // A wrong checksum (last trailer bytes hold the size; the CRC is before it).
  std::string bad = z;
  bad[bad.size() - 6] = char(bad[bad.size() - 6] ^ 0x5a);
  out.clear();
  r = inflate_bounded(bad, in.size(), InflateTail::verified, out);
  EXPECT_NE(r.error.find("corrupt"), std::string::npos) << r.error;
  // Garbage from the start.
  out.clear();
  r = inflate_bounded(std::string(100, '\x7f'), 1000, InflateTail::unchecked, out);
  EXPECT_NE(r.error.find("corrupt"), std::string::npos) << r.error;
  EXPECT_EQ(r.produced, 0u);
}

TEST(Inflate, AHugeAnnouncedSizeCostsOnlyWhatInflates) {
  // A 100-byte stream whose container claims a terabyte: the output is what the stream holds.
  const std::string in(100, 'x');
  std::string out;
  const InflateOutcome r = inflate_bounded(deflated(in, false), size_t{1} << 40, InflateTail::verified, out);
  EXPECT_TRUE(r.error.empty()) << r.error;
  EXPECT_TRUE(r.ended);
  EXPECT_EQ(out, in);
  EXPECT_LT(out.capacity(), size_t{1} << 20);
}
