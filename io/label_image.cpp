/// \file label_image.cpp
/// Label image readers and writers (NRRD, NIfTI-1, MetaImage, INRIMAGE-4). See label_image.hpp.
/// Every reader parses the header into an ImageHeader, checks it (`check_header`), computes the
/// data size from it and only then reads, inflates or allocates — a hostile header cannot make
/// the reader allocate more than the file can fill (`kMaxVoxels` caps it anyway).

#include "io/label_image.hpp"

#include <zlib.h>  // deflate, for the writers

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "io/inflate.hpp"
#include "tissue/input_error.hpp"
#include "io/text_scan.hpp"

namespace stroma {
namespace {

namespace fs = std::filesystem;
using text::clip;
using text::iequals;

constexpr int64_t kMaxVoxels = int64_t{1} << 31;  // 2^31 voxels (1290^3): beyond any segmentation we mesh

enum class VoxelType { u8, i8, u16, i16, u32, i32, f32, f64 };

size_t type_bytes(VoxelType t) {
  switch (t) {
    case VoxelType::u8: case VoxelType::i8: return 1;
    case VoxelType::u16: case VoxelType::i16: return 2;
    case VoxelType::u32: case VoxelType::i32: case VoxelType::f32: return 4;
    case VoxelType::f64: return 8;
  }
  return 1;
}

/// What a header says, in one shape for every format.
struct ImageHeader {
  std::array<int64_t, 3> dims{0, 0, 0};
  std::array<double, 3> spacing{1, 1, 1};  // file units
  std::array<double, 3> origin{0, 0, 0};   // file units
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
  double unit = 1e-3;  // metres per file unit
  VoxelType type = VoxelType::u8;
  bool big_endian = false;
  double slope = 1.0, inter = 0.0;  // value = slope * stored + inter (NIfTI's scl_*)
};

std::string lower_ext(const std::string& path) {
  std::string p = path;
  for (char& c : p) c = text::lower(c);
  for (const char* e : {".nii.gz", ".inr.gz"})
    if (p.size() > std::strlen(e) && p.ends_with(e)) return e;
  const auto dot = p.find_last_of('.');
  const auto slash = p.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  return p.substr(dot);
}

std::string read_file_bytes(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw InputError(path, 0, "", "is a directory, not an image file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "", fmt::format("cannot open: {}", std::strerror(errno)));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(path, 0, "", "read error");
  return std::move(ss).str();
}

bool is_gzip(std::string_view s) { return s.size() >= 2 && uint8_t(s[0]) == 0x1f && uint8_t(s[1]) == 0x8b; }

/// The whole of a possibly gzip-compressed file, inflated only as far as `want` bytes.
std::string maybe_gunzip_prefix(const std::string& path, const std::string& raw, size_t want, bool verify_end = false) {
  if (!is_gzip(raw)) return raw.substr(0, std::min(raw.size(), want));
  std::string out;
  const InflateOutcome r = inflate_bounded(raw, want, verify_end ? InflateTail::verified : InflateTail::unchecked, out);
  if (!r.error.empty()) throw InputError(path, 0, "", r.error);
  return out;
}

void check_header(const std::string& path, ImageHeader& h) {
  for (int a = 0; a < 3; ++a) {
    if (h.dims[a] < 1)
      throw InputError(path, 0, "dimensions", fmt::format("axis {} has {} voxels (must be >= 1)", a, h.dims[a]));
    if (!(std::isfinite(h.spacing[a]) && h.spacing[a] > 0))
      throw InputError(path, 0, "spacing", fmt::format("axis {} has spacing {} (must be > 0)", a, h.spacing[a]));
    if (!std::isfinite(h.origin[a])) throw InputError(path, 0, "origin", "is not finite");
  }
  if (h.dims[0] > kMaxVoxels / h.dims[1] || h.dims[0] * h.dims[1] > kMaxVoxels / h.dims[2])
    throw InputError(path, 0, "dimensions",
                     fmt::format("{} x {} x {} voxels is more than this reader takes (2^31)", h.dims[0], h.dims[1], h.dims[2]));
  // Orthonormal columns: a rotation (with or without a reflection), no shear.
  for (int a = 0; a < 3; ++a)
    for (int b = a; b < 3; ++b) {
      double d = 0;
      for (int r = 0; r < 3; ++r) d += h.direction[3 * r + a] * h.direction[3 * r + b];
      const double want = a == b ? 1.0 : 0.0;
      if (!(std::abs(d - want) < 1e-4))
        throw InputError(path, 0, "direction",
                         a == b ? fmt::format("axis {} direction is not a unit vector (length^2 {})", a, d)
                                : fmt::format("axes {} and {} are not orthogonal (cos {:.4g}): a sheared grid cannot be meshed rigidly", a, b, d));
    }
  if (!(std::isfinite(h.slope) && std::isfinite(h.inter))) throw InputError(path, 0, "scl_slope", "is not finite");
}

/// Converts `count` stored voxels at `data` into labels; refuses a non-integer value.
std::vector<int32_t> decode_voxels(const std::string& path, const ImageHeader& h, const char* data, int64_t count) {
  std::vector<int32_t> out(static_cast<size_t>(count));
  const size_t nb = type_bytes(h.type);
  const bool swap = h.big_endian != (std::endian::native == std::endian::big);
  auto load = [&](int64_t i, auto tag) {
    using T = decltype(tag);
    unsigned char b[8];
    std::memcpy(b, data + size_t(i) * nb, nb);
    if (swap) std::reverse(b, b + nb);
    T v;
    std::memcpy(&v, b, sizeof(T));
    return v;
  };
  const bool scaled = h.slope != 1.0 || h.inter != 0.0;
  for (int64_t i = 0; i < count; ++i) {
    double v = 0;
    switch (h.type) {
      case VoxelType::u8: v = load(i, uint8_t{}); break;
      case VoxelType::i8: v = load(i, int8_t{}); break;
      case VoxelType::u16: v = load(i, uint16_t{}); break;
      case VoxelType::i16: v = load(i, int16_t{}); break;
      case VoxelType::u32: v = load(i, uint32_t{}); break;
      case VoxelType::i32: v = load(i, int32_t{}); break;
      case VoxelType::f32: v = load(i, float{}); break;
      case VoxelType::f64: v = load(i, double{}); break;
    }
    if (scaled) v = h.slope * v + h.inter;
    if (!(v == std::floor(v) && std::abs(v) <= 2147483647.0)) {
      const int64_t k = i / (h.dims[0] * h.dims[1]), j = (i / h.dims[0]) % h.dims[1], x = i % h.dims[0];
      throw InputError(path, 0, "data",
                       fmt::format("voxel ({}, {}, {}) holds {}, not an integer label: a label image (segmentation) is needed, "
                                   "not an intensity image", x, j, k, v));
    }
    out[size_t(i)] = static_cast<int32_t>(v);
  }
  return out;
}

LabelImage finish(const std::string& path, const ImageHeader& h, const LabelImageReadOptions& opt,
                  std::vector<int32_t> labels) {
  LabelImage img;
  img.dims = h.dims;
  const double unit = opt.unit_override > 0 ? opt.unit_override : h.unit;
  for (int a = 0; a < 3; ++a) {
    img.spacing[a] = h.spacing[a] * unit;
    img.origin[a] = h.origin[a] * unit;
  }
  img.direction = h.direction;
  img.labels = std::move(labels);
  img.source = path;
  return img;
}

/// Data of `bytes` bytes at `offset` in `raw` (or truncated: a precise message).
const char* data_at(const std::string& path, const std::string& raw, size_t offset, size_t bytes, const char* what) {
  if (offset > raw.size() || raw.size() - offset < bytes)
    throw InputError(path, 0, "data",
                     fmt::format("truncated: the header announces {} bytes of {} at byte {}, the file has {}", bytes,
                                 what, offset, raw.size() > offset ? raw.size() - offset : 0));
  return raw.data() + offset;
}

size_t data_bytes(const ImageHeader& h) {
  return size_t(h.dims[0] * h.dims[1] * h.dims[2]) * type_bytes(h.type);
}

/// Inflates (zlib or gzip) a compressed data block to exactly the header's size.
std::string inflate_data(const std::string& path, std::string_view block, size_t want) {
  std::string out;
  const InflateOutcome r = inflate_bounded(block, want, InflateTail::verified, out);
  if (!r.error.empty()) throw InputError(path, 0, "data", r.error);
  if (out.size() < want)
    throw InputError(path, 0, "data", fmt::format("truncated: compressed data inflates to {} bytes, the header announces {}", out.size(), want));
  return out;
}

// ------------------------------------------------------------------------------------ text headers

/// Header lines of a text-headed format, up to the data (NRRD: a blank line; MetaImage: the
/// ElementDataFile line; INR: "##}"). `end` is the byte offset after the header.
struct TextLine {
  int number;
  std::string key, value;
};

std::vector<double> parse_numbers(const std::string& path, int line, const std::string& field, std::string_view s,
                                  size_t want) {
  std::vector<double> v;
  std::string tok;
  auto flush = [&] {
    if (tok.empty()) return;
    double d;
    if (!text::parse_number(tok, d)) throw InputError(path, line, field, fmt::format("'{}' is not a number", clip(tok)));
    v.push_back(d);
    tok.clear();
  };
  for (char c : s) {
    if (text::is_space(c) || c == ',' || c == '(' || c == ')') flush();
    else tok += c;
  }
  flush();
  if (want && v.size() != want)
    throw InputError(path, line, field, fmt::format("has {} values, {} expected ('{}')", v.size(), want, clip(s)));
  return v;
}

std::string trim(std::string_view s) { return std::string(text::trim(s)); }

VoxelType nrrd_type(const std::string& path, int line, std::string t) {
  for (char& c : t) c = text::lower(c);
  static const std::map<std::string, VoxelType> k = {
      {"uchar", VoxelType::u8}, {"unsigned char", VoxelType::u8}, {"uint8", VoxelType::u8}, {"uint8_t", VoxelType::u8},
      {"signed char", VoxelType::i8}, {"int8", VoxelType::i8}, {"int8_t", VoxelType::i8},
      {"short", VoxelType::i16}, {"short int", VoxelType::i16}, {"signed short", VoxelType::i16},
      {"signed short int", VoxelType::i16}, {"int16", VoxelType::i16}, {"int16_t", VoxelType::i16},
      {"ushort", VoxelType::u16}, {"unsigned short", VoxelType::u16}, {"unsigned short int", VoxelType::u16},
      {"uint16", VoxelType::u16}, {"uint16_t", VoxelType::u16},
      {"int", VoxelType::i32}, {"signed int", VoxelType::i32}, {"int32", VoxelType::i32}, {"int32_t", VoxelType::i32},
      {"uint", VoxelType::u32}, {"unsigned int", VoxelType::u32}, {"uint32", VoxelType::u32}, {"uint32_t", VoxelType::u32},
      {"float", VoxelType::f32}, {"double", VoxelType::f64}};
  auto it = k.find(t);
  if (it == k.end())
    throw InputError(path, line, "type", fmt::format("'{}' is not a voxel type this reader takes (8/16/32-bit integers, float, double)", clip(t)));
  return it->second;
}

double unit_from_name(const std::string& path, int line, const std::string& field, std::string u) {
  u.erase(std::remove(u.begin(), u.end(), '"'), u.end());
  u = trim(u);
  if (u == "m") return 1.0;
  if (u == "cm") return 1e-2;
  if (u == "mm") return 1e-3;
  if (u == "um" || u == "µm" || u == "micron") return 1e-6;
  throw InputError(path, line, field, fmt::format("unit '{}' is not one of m, cm, mm, um", clip(u)));
}

LabelImage read_nrrd(const std::string& path, const LabelImageReadOptions& opt) {
  const std::string raw = read_file_bytes(path);
  if (!raw.starts_with("NRRD000"))
    throw InputError(path, 1, "magic", fmt::format("'{}' is not a NRRD magic (NRRD0001..NRRD0005)", clip(raw.substr(0, 8))));
  size_t pos = raw.find('\n');
  if (pos == std::string::npos) throw InputError(path, 1, "", "truncated: no header");
  ++pos;
  std::map<std::string, TextLine> f;
  int line = 1;
  bool blank = false;
  while (pos < raw.size()) {
    const size_t nl = raw.find('\n', pos);
    ++line;
    if (nl == std::string::npos) {
      pos = raw.size();
      break;
    }
    std::string_view l(raw.data() + pos, nl - pos);
    pos = nl + 1;
    if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
    if (l.empty()) {
      blank = true;
      break;
    }
    if (l.front() == '#') continue;
    const size_t kv = l.find(":=");
    if (kv != std::string_view::npos) continue;  // key/value pairs: metadata, not geometry
    const size_t colon = l.find(": ");
    if (colon == std::string_view::npos)
      throw InputError(path, line, "", fmt::format("'{}' is not a 'field: value' line", clip(l)));
    std::string key = std::string(l.substr(0, colon));
    for (char& c : key) c = text::lower(c);
    if (f.count(key)) throw InputError(path, line, key, "given twice");
    f[key] = TextLine{line, key, trim(l.substr(colon + 2))};
  }
  auto need = [&](const char* k) -> const TextLine& {
    auto it = f.find(k);
    if (it == f.end()) throw InputError(path, 0, k, "missing (NRRD requires it)");
    return it->second;
  };
  ImageHeader h;
  const TextLine& dim = need("dimension");
  const auto ndim = parse_numbers(path, dim.number, "dimension", dim.value, 1);
  if (!(ndim[0] == 3 || ndim[0] == 4))
    throw InputError(path, dim.number, "dimension", fmt::format("{} axes: a 3-D label image is needed", ndim[0]));
  const TextLine& sizes = need("sizes");
  auto sz = parse_numbers(path, sizes.number, "sizes", sizes.value, size_t(ndim[0]));
  int first = 0;  // a leading axis of size 1 (a channel axis) is allowed
  if (ndim[0] == 4) {
    if (sz[0] != 1)
      throw InputError(path, sizes.number, "sizes", fmt::format("4 axes with {} values per voxel: a label image has one", sz[0]));
    first = 1;
  }
  for (int a = 0; a < 3; ++a) {
    if (!(sz[first + a] >= 1 && sz[first + a] == std::floor(sz[first + a]) && sz[first + a] < 1e9))
      throw InputError(path, sizes.number, "sizes", fmt::format("axis {} size {} is not a positive integer", a, sz[first + a]));
    h.dims[a] = int64_t(sz[first + a]);
  }
  h.type = nrrd_type(path, need("type").number, need("type").value);
  if (type_bytes(h.type) > 1) {
    const TextLine& e = need("endian");
    if (iequals(e.value, "big")) h.big_endian = true;
    else if (!iequals(e.value, "little")) throw InputError(path, e.number, "endian", fmt::format("'{}' is not little or big", clip(e.value)));
  }
  if (auto it = f.find("space directions"); it != f.end()) {
    std::string v = it->second.value;
    if (first) {  // drop the channel axis' "none"
      const size_t n = v.find("none");
      if (n != std::string::npos) v.erase(n, 4);
    }
    const auto d = parse_numbers(path, it->second.number, "space directions", v, 9);
    for (int a = 0; a < 3; ++a) {
      const double len = std::sqrt(d[3 * a] * d[3 * a] + d[3 * a + 1] * d[3 * a + 1] + d[3 * a + 2] * d[3 * a + 2]);
      if (!(len > 0)) throw InputError(path, it->second.number, "space directions", fmt::format("axis {} has a zero vector", a));
      h.spacing[a] = len;
      for (int r = 0; r < 3; ++r) h.direction[3 * r + a] = d[3 * a + r] / len;
    }
  } else if (auto sp = f.find("spacings"); sp != f.end()) {
    auto s = parse_numbers(path, sp->second.number, "spacings", sp->second.value, 0);
    if (s.size() != size_t(ndim[0]) && !(first && s.size() == 3))
      throw InputError(path, sp->second.number, "spacings", fmt::format("has {} values for {} axes", s.size(), ndim[0]));
    for (int a = 0; a < 3; ++a) h.spacing[a] = s[s.size() - 3 + a];
  }
  if (auto it = f.find("space origin"); it != f.end()) {
    const auto o = parse_numbers(path, it->second.number, "space origin", it->second.value, 3);
    h.origin = {o[0], o[1], o[2]};
  }
  if (auto it = f.find("space units"); it != f.end()) {
    std::istringstream ss(it->second.value);
    std::string u;
    ss >> u;
    h.unit = unit_from_name(path, it->second.number, "space units", u);
  }
  check_header(path, h);
  const TextLine& enc = need("encoding");
  std::string encoding = enc.value;
  for (char& c : encoding) c = text::lower(c);
  const bool gz = encoding == "gzip" || encoding == "gz";
  if (!gz && encoding != "raw")
    throw InputError(path, enc.number, "encoding", fmt::format("'{}' is not raw or gzip (ascii, hex, bzip2 are not read)", clip(enc.value)));
  std::string detached;
  const std::string* block = &raw;
  size_t offset = pos;
  auto df = f.find("data file");
  if (df == f.end()) df = f.find("datafile");
  if (df != f.end()) {
    if (df->second.value.starts_with("LIST") || df->second.value.find('%') != std::string::npos)
      throw InputError(path, df->second.number, "data file", "lists of data files are not read: one file only");
    const fs::path p = fs::path(path).parent_path() / df->second.value;
    try {
      detached = read_file_bytes(p.string());
    } catch (const InputError& e) {
      throw InputError(path, df->second.number, "data file", e.what());
    }
    block = &detached;
    offset = 0;
  } else if (!blank) {
    throw InputError(path, line, "", "truncated: the header has no blank line before the data");
  }
  if (auto bs = f.find("byte skip"); bs != f.end()) {
    const auto b = parse_numbers(path, bs->second.number, "byte skip", bs->second.value, 1);
    if (b[0] == -1 && !gz) offset = block->size() >= data_bytes(h) ? block->size() - data_bytes(h) : 0;
    else if (b[0] >= 0 && b[0] == std::floor(b[0]) && b[0] < 1e15) offset += size_t(b[0]);
    else throw InputError(path, bs->second.number, "byte skip", "must be -1 or a byte count >= 0");
  }
  const size_t want = data_bytes(h);
  std::string inflated;
  const char* data;
  if (gz) {
    if (offset > block->size()) throw InputError(path, 0, "data", "truncated: no compressed data after the header");
    inflated = inflate_data(path, std::string_view(*block).substr(offset), want);
    data = inflated.data();
  } else {
    data = data_at(path, *block, offset, want, "voxels");
  }
  return finish(path, h, opt, decode_voxels(path, h, data, h.dims[0] * h.dims[1] * h.dims[2]));
}

// ------------------------------------------------------------------------------------------ NIfTI

template <class T>
T get(const std::string& hdr, size_t off, bool swap) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, hdr.data() + off, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

LabelImage read_nifti(const std::string& path, const LabelImageReadOptions& opt) {
  const std::string raw = read_file_bytes(path);
  std::string hdr = maybe_gunzip_prefix(path, raw, 352);
  if (hdr.size() < 348)
    throw InputError(path, 0, "header", fmt::format("truncated: {} bytes, a NIfTI-1 header has 348", hdr.size()));
  const int32_t sizeof_hdr = get<int32_t>(hdr, 0, false);
  bool swap = false;
  if (sizeof_hdr == 540 || get<int32_t>(hdr, 0, true) == 540)
    throw InputError(path, 0, "sizeof_hdr", "a NIfTI-2 file: only NIfTI-1 is read (save as NIfTI-1)");
  if (sizeof_hdr != 348) {
    if (get<int32_t>(hdr, 0, true) != 348)
      throw InputError(path, 0, "sizeof_hdr", fmt::format("{} (a NIfTI-1 header says 348): not a NIfTI file", sizeof_hdr));
    swap = true;
  }
  const std::string magic = hdr.substr(344, 3);
  if (magic == "ni1") throw InputError(path, 0, "magic", "a two-file NIfTI (.hdr/.img): give the single-file .nii");
  if (magic != "n+1") throw InputError(path, 0, "magic", fmt::format("'{}' is not n+1", clip(magic)));
  ImageHeader h;
  h.big_endian = swap != (std::endian::native == std::endian::big);
  const int16_t nd = get<int16_t>(hdr, 40, swap);
  if (nd < 3 || nd > 7) throw InputError(path, 0, "dim[0]", fmt::format("{} dimensions: a 3-D label image is needed", nd));
  for (int a = 0; a < 3; ++a) h.dims[a] = get<int16_t>(hdr, 42 + 2 * a, swap);
  for (int a = 4; a <= nd; ++a)
    if (get<int16_t>(hdr, 40 + 2 * a, swap) > 1)
      throw InputError(path, 0, fmt::format("dim[{}]", a), fmt::format("{} > 1: a 3-D label image is needed (one volume)", get<int16_t>(hdr, 40 + 2 * a, swap)));
  const int16_t dt = get<int16_t>(hdr, 70, swap);
  switch (dt) {
    case 2: h.type = VoxelType::u8; break;
    case 4: h.type = VoxelType::i16; break;
    case 8: h.type = VoxelType::i32; break;
    case 16: h.type = VoxelType::f32; break;
    case 64: h.type = VoxelType::f64; break;
    case 256: h.type = VoxelType::i8; break;
    case 512: h.type = VoxelType::u16; break;
    case 768: h.type = VoxelType::u32; break;
    default: throw InputError(path, 0, "datatype", fmt::format("{} is not an integer or real scalar type", dt));
  }
  const float qfac_raw = get<float>(hdr, 76, swap);
  for (int a = 0; a < 3; ++a) h.spacing[a] = std::abs(get<float>(hdr, 80 + 4 * a, swap));
  const float vox_offset = get<float>(hdr, 108, swap);
  const float slope = get<float>(hdr, 112, swap), inter = get<float>(hdr, 116, swap);
  if (slope != 0.0f && std::isfinite(slope)) {
    h.slope = slope;
    h.inter = inter;
  }
  switch (uint8_t(hdr[123]) & 0x07) {
    case 1: h.unit = 1.0; break;
    case 3: h.unit = 1e-6; break;
    default: h.unit = 1e-3; break;  // 2 = mm; 0 = unknown, read as mm as viewers do
  }
  const int16_t qform = get<int16_t>(hdr, 252, swap), sform = get<int16_t>(hdr, 254, swap);
  if (sform > 0) {
    double m[3][4];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) m[r][c] = get<float>(hdr, 280 + 16 * r + 4 * c, swap);
    for (int a = 0; a < 3; ++a) {
      const double len = std::sqrt(m[0][a] * m[0][a] + m[1][a] * m[1][a] + m[2][a] * m[2][a]);
      if (!(len > 0)) throw InputError(path, 0, "srow", fmt::format("column {} of the sform is zero", a));
      h.spacing[a] = len;
      for (int r = 0; r < 3; ++r) h.direction[3 * r + a] = m[r][a] / len;
      h.origin[a] = m[a][3];
    }
  } else if (qform > 0) {
    const double b = get<float>(hdr, 256, swap), c = get<float>(hdr, 260, swap), d = get<float>(hdr, 264, swap);
    const double aa = 1.0 - (b * b + c * c + d * d);
    const double a = aa > 0 ? std::sqrt(aa) : 0.0;
    const double R[9] = {a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c),
                         2 * (b * c + a * d), a * a + c * c - b * b - d * d, 2 * (c * d - a * b),
                         2 * (b * d - a * c), 2 * (c * d + a * b), a * a + d * d - c * c - b * b};
    const double qfac = qfac_raw < 0 ? -1.0 : 1.0;
    for (int r = 0; r < 3; ++r)
      for (int col = 0; col < 3; ++col) h.direction[3 * r + col] = R[3 * r + col] * (col == 2 ? qfac : 1.0);
    for (int i = 0; i < 3; ++i) h.origin[i] = get<float>(hdr, 268 + 4 * i, swap);
  }
  check_header(path, h);
  if (!(vox_offset >= 348 && vox_offset < 1e9))
    throw InputError(path, 0, "vox_offset", fmt::format("{} (the data must start at byte 348 or later)", vox_offset));
  const size_t off = size_t(vox_offset), want = data_bytes(h);
  std::string all = maybe_gunzip_prefix(path, raw, off + want, true);
  const char* data = data_at(path, all, off, want, "voxels");
  return finish(path, h, opt, decode_voxels(path, h, data, h.dims[0] * h.dims[1] * h.dims[2]));
}

// -------------------------------------------------------------------------------------- MetaImage

bool meta_bool(const std::string& path, const TextLine& l) {
  if (iequals(l.value, "true") || l.value == "1") return true;
  if (iequals(l.value, "false") || l.value == "0") return false;
  throw InputError(path, l.number, l.key, fmt::format("'{}' is not True or False", clip(l.value)));
}

LabelImage read_metaimage(const std::string& path, const LabelImageReadOptions& opt) {
  const std::string raw = read_file_bytes(path);
  std::map<std::string, TextLine> f;
  size_t pos = 0;
  int line = 0;
  bool ended = false;
  while (pos < raw.size()) {
    const size_t nl = raw.find('\n', pos);
    ++line;
    std::string_view l(raw.data() + pos, (nl == std::string::npos ? raw.size() : nl) - pos);
    pos = nl == std::string::npos ? raw.size() : nl + 1;
    if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
    if (trim(l).empty()) continue;
    const size_t eq = l.find('=');
    if (eq == std::string_view::npos)
      throw InputError(path, line, "", fmt::format("'{}' is not a 'Key = Value' line", clip(l)));
    const std::string key = trim(l.substr(0, eq));
    f[key] = TextLine{line, key, trim(l.substr(eq + 1))};
    if (key == "ElementDataFile") {
      ended = true;
      break;
    }
  }
  if (!ended) throw InputError(path, line, "ElementDataFile", "missing (it must be the header's last line)");
  auto need = [&](const char* k) -> const TextLine& {
    auto it = f.find(k);
    if (it == f.end()) throw InputError(path, 0, k, "missing");
    return it->second;
  };
  auto find_any = [&](std::initializer_list<const char*> ks) -> const TextLine* {
    for (const char* k : ks)
      if (auto it = f.find(k); it != f.end()) return &it->second;
    return nullptr;
  };
  if (auto it = f.find("ObjectType"); it != f.end() && it->second.value != "Image")
    throw InputError(path, it->second.number, "ObjectType", fmt::format("'{}' is not Image", clip(it->second.value)));
  const TextLine& nd = need("NDims");
  if (parse_numbers(path, nd.number, "NDims", nd.value, 1)[0] != 3)
    throw InputError(path, nd.number, "NDims", fmt::format("{}: a 3-D label image is needed", clip(nd.value)));
  ImageHeader h;
  const TextLine& ds = need("DimSize");
  const auto d = parse_numbers(path, ds.number, "DimSize", ds.value, 3);
  for (int a = 0; a < 3; ++a) {
    if (!(d[a] >= 1 && d[a] == std::floor(d[a]) && d[a] < 1e9))
      throw InputError(path, ds.number, "DimSize", fmt::format("axis {} size {} is not a positive integer", a, d[a]));
    h.dims[a] = int64_t(d[a]);
  }
  if (auto* c = find_any({"ElementNumberOfChannels"}); c && parse_numbers(path, c->number, c->key, c->value, 1)[0] != 1)
    throw InputError(path, c->number, c->key, "must be 1: a label image has one value per voxel");
  if (auto* s = find_any({"ElementSpacing", "ElementSize"})) {
    const auto v = parse_numbers(path, s->number, s->key, s->value, 3);
    h.spacing = {v[0], v[1], v[2]};
  }
  if (auto* o = find_any({"Offset", "Position", "Origin"})) {
    const auto v = parse_numbers(path, o->number, o->key, o->value, 3);
    h.origin = {v[0], v[1], v[2]};
  }
  if (auto* m = find_any({"TransformMatrix", "Rotation", "Orientation"})) {
    const auto v = parse_numbers(path, m->number, m->key, m->value, 9);
    // MetaIO stores the matrix column by column: its first three numbers are axis 0's direction.
    for (int a = 0; a < 3; ++a)
      for (int r = 0; r < 3; ++r) h.direction[3 * r + a] = v[3 * a + r];
  }
  const TextLine& et = need("ElementType");
  static const std::map<std::string, VoxelType> types = {
      {"MET_UCHAR", VoxelType::u8}, {"MET_CHAR", VoxelType::i8}, {"MET_USHORT", VoxelType::u16},
      {"MET_SHORT", VoxelType::i16}, {"MET_UINT", VoxelType::u32}, {"MET_INT", VoxelType::i32},
      {"MET_ULONG", VoxelType::u32}, {"MET_LONG", VoxelType::i32}, {"MET_FLOAT", VoxelType::f32},
      {"MET_DOUBLE", VoxelType::f64}};
  auto t = types.find(et.value);
  if (t == types.end()) throw InputError(path, et.number, "ElementType", fmt::format("'{}' is not a scalar MET_ type this reader takes", clip(et.value)));
  h.type = t->second;
  if (auto* b = find_any({"BinaryDataByteOrderMSB", "ElementByteOrderMSB"})) h.big_endian = meta_bool(path, *b);
  bool compressed = false;
  if (auto* c = find_any({"CompressedData"})) compressed = meta_bool(path, *c);
  check_header(path, h);
  const TextLine& edf = need("ElementDataFile");
  std::string detached;
  const std::string* block = &raw;
  size_t offset = pos;
  if (edf.value != "LOCAL" && edf.value != "Local" && edf.value != "local") {
    if (edf.value.starts_with("LIST") || edf.value.find('%') != std::string::npos)
      throw InputError(path, edf.number, "ElementDataFile", "lists of data files are not read: one file only");
    const fs::path p = fs::path(path).parent_path() / edf.value;
    try {
      detached = read_file_bytes(p.string());
    } catch (const InputError& e) {
      throw InputError(path, edf.number, "ElementDataFile", e.what());
    }
    block = &detached;
    offset = 0;
  }
  const size_t want = data_bytes(h);
  std::string inflated;
  const char* data;
  if (compressed) {
    inflated = inflate_data(path, std::string_view(*block).substr(std::min(offset, block->size())), want);
    data = inflated.data();
  } else {
    data = data_at(path, *block, offset, want, "voxels");
  }
  return finish(path, h, opt, decode_voxels(path, h, data, h.dims[0] * h.dims[1] * h.dims[2]));
}

// ---------------------------------------------------------------------------------------- INRIMAGE

LabelImage read_inr(const std::string& path, const LabelImageReadOptions& opt) {
  const std::string raw = read_file_bytes(path);
  std::string head = maybe_gunzip_prefix(path, raw, 256);
  if (!head.starts_with("#INRIMAGE-4#{"))
    throw InputError(path, 1, "magic", fmt::format("'{}' is not #INRIMAGE-4#{{", clip(head.substr(0, 13))));
  // The header is a multiple of 256 bytes ending with "##}\n"; find how long it is.
  head = maybe_gunzip_prefix(path, raw, size_t{1} << 20);
  const size_t end = head.find("##}");
  if (end == std::string::npos)
    throw InputError(path, 0, "header", head.size() < (size_t{1} << 20) ? "truncated: the header has no '##}' end"
                                                                         : "no '##}' end within 1 MB");
  const size_t hlen = (end / 256 + 1) * 256;
  if (head.size() < hlen) throw InputError(path, 0, "header", "truncated inside the header");
  head.resize(hlen);
  ImageHeader h;
  int vdim = 1, pixsize = 0, line = 0;
  std::string type;
  std::istringstream ss(head.substr(0, head.find("##}")));
  std::string l;
  std::map<std::string, int> seen;
  while (std::getline(ss, l)) {
    ++line;
    if (line == 1 || l.empty() || l[0] == '#') continue;
    const size_t eq = l.find('=');
    if (eq == std::string::npos) throw InputError(path, line, "", fmt::format("'{}' is not KEY=VALUE", clip(l)));
    const std::string k = trim(std::string_view(l).substr(0, eq)), v = trim(std::string_view(l).substr(eq + 1));
    seen[k] = line;
    auto num = [&] { return parse_numbers(path, line, k, v, 1)[0]; };
    auto count = [&](int64_t& out) {
      const double x = num();
      if (!(x >= 1 && x == std::floor(x) && x < 1e9)) throw InputError(path, line, k, fmt::format("{} is not a positive integer", x));
      out = int64_t(x);
    };
    if (k == "XDIM") count(h.dims[0]);
    else if (k == "YDIM") count(h.dims[1]);
    else if (k == "ZDIM") count(h.dims[2]);
    else if (k == "VDIM") {
      const double v = num();
      if (!(v >= 1 && v <= 64 && v == std::floor(v))) throw InputError(path, line, k, fmt::format("{} is not a count of 1..64", v));
      vdim = int(v);
    }
    else if (k == "VX") h.spacing[0] = num();
    else if (k == "VY") h.spacing[1] = num();
    else if (k == "VZ") h.spacing[2] = num();
    else if (k == "TX") h.origin[0] = num();
    else if (k == "TY") h.origin[1] = num();
    else if (k == "TZ") h.origin[2] = num();
    else if (k == "TYPE") type = v;
    else if (k == "PIXSIZE") {
      const double b = parse_numbers(path, line, k, v.substr(0, v.find(' ')), 1)[0];
      if (!(b == 8 || b == 16 || b == 32 || b == 64)) throw InputError(path, line, k, fmt::format("{} bits is not 8, 16, 32 or 64", b));
      pixsize = int(b);
    }
    else if (k == "CPU") {
      if (v == "sun" || v == "sgi") h.big_endian = true;
      else if (v != "decm" && v != "pc" && v != "alpha") throw InputError(path, line, k, fmt::format("'{}' is not decm, pc, alpha, sun or sgi", clip(v)));
    }
  }
  for (const char* k : {"XDIM", "YDIM", "ZDIM", "TYPE", "PIXSIZE"})
    if (!seen.count(k)) throw InputError(path, 0, k, "missing");
  if (vdim != 1) throw InputError(path, seen["VDIM"], "VDIM", fmt::format("{}: a label image has one value per voxel", vdim));
  if (type == "unsigned fixed" && pixsize == 8) h.type = VoxelType::u8;
  else if (type == "unsigned fixed" && pixsize == 16) h.type = VoxelType::u16;
  else if (type == "unsigned fixed" && pixsize == 32) h.type = VoxelType::u32;
  else if (type == "signed fixed" && pixsize == 8) h.type = VoxelType::i8;
  else if (type == "signed fixed" && pixsize == 16) h.type = VoxelType::i16;
  else if (type == "signed fixed" && pixsize == 32) h.type = VoxelType::i32;
  else if (type == "float" && pixsize == 32) h.type = VoxelType::f32;
  else if (type == "float" && pixsize == 64) h.type = VoxelType::f64;
  else throw InputError(path, seen["TYPE"], "TYPE", fmt::format("'{}' with PIXSIZE={} bits is not a type this reader takes", clip(type), pixsize));
  check_header(path, h);
  const size_t want = data_bytes(h);
  const std::string all = maybe_gunzip_prefix(path, raw, hlen + want, true);
  const char* data = data_at(path, all, hlen, want, "voxels");
  return finish(path, h, opt, decode_voxels(path, h, data, h.dims[0] * h.dims[1] * h.dims[2]));
}

// ------------------------------------------------------------------------------------------ writers

VoxelType narrowest(const LabelImage& im) {
  int32_t lo = 0, hi = 0;
  for (int32_t v : im.labels) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  if (lo >= 0 && hi <= 255) return VoxelType::u8;
  if (lo >= -32768 && hi <= 32767) return VoxelType::i16;
  return VoxelType::i32;
}

std::string pack(const LabelImage& im, VoxelType t) {
  std::string out(im.labels.size() * type_bytes(t), '\0');
  for (size_t i = 0; i < im.labels.size(); ++i) {
    const int32_t v = im.labels[i];
    if (t == VoxelType::u8) out[i] = char(uint8_t(v));
    else if (t == VoxelType::i16) { const int16_t s = int16_t(v); std::memcpy(&out[2 * i], &s, 2); }
    else std::memcpy(&out[4 * i], &v, 4);
  }
  return out;
}

std::string deflate_bytes(const std::string& in, bool gzip) {
  z_stream z{};
  if (deflateInit2(&z, 6, Z_DEFLATED, gzip ? 16 + MAX_WBITS : MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK)
    throw std::runtime_error("zlib could not start");
  std::string out(deflateBound(&z, uLong(in.size())) + 64, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = uInt(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = uInt(out.size());
  const int rc = deflate(&z, Z_FINISH);
  out.resize(z.total_out);
  deflateEnd(&z);
  if (rc != Z_STREAM_END) throw std::runtime_error("zlib could not compress");
  return out;
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), std::streamsize(bytes.size()));
  if (!out) throw std::runtime_error(fmt::format("{}: cannot write", path));
}

const char* little() { return std::endian::native == std::endian::little ? "little" : "big"; }

}  // namespace

LabelImage read_label_image(const std::string& path, const LabelImageReadOptions& options) {
  const std::string e = lower_ext(path);
  if (e == ".nrrd" || e == ".nhdr") return read_nrrd(path, options);
  if (e == ".nii" || e == ".nii.gz") return read_nifti(path, options);
  if (e == ".mha" || e == ".mhd") return read_metaimage(path, options);
  if (e == ".inr" || e == ".inr.gz") return read_inr(path, options);
  throw InputError(path, 0, "", fmt::format("unknown label image extension '{}' (.nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd, .inr, .inr.gz)", e));
}

void write_label_image(const std::string& path, const LabelImage& im, bool compress) {
  const std::string e = lower_ext(path);
  const VoxelType t = narrowest(im);
  const std::string data = pack(im, t);
  double sp[3], org[3];
  for (int a = 0; a < 3; ++a) {
    sp[a] = im.spacing[a] * 1e3;
    org[a] = im.origin[a] * 1e3;
  }
  const auto& D = im.direction;
  if (e == ".nrrd") {
    std::string h = "NRRD0004\n# written by Stroma\n";
    h += fmt::format("type: {}\ndimension: 3\nspace: right-anterior-superior\nsizes: {} {} {}\n",
                     t == VoxelType::u8 ? "uint8" : t == VoxelType::i16 ? "int16" : "int32", im.dims[0], im.dims[1], im.dims[2]);
    h += "space directions:";
    for (int a = 0; a < 3; ++a)
      h += fmt::format(" ({:.17g},{:.17g},{:.17g})", D[a] * sp[a], D[3 + a] * sp[a], D[6 + a] * sp[a]);
    h += fmt::format("\nspace units: \"mm\" \"mm\" \"mm\"\nspace origin: ({:.17g},{:.17g},{:.17g})\n", org[0], org[1], org[2]);
    if (t != VoxelType::u8) h += fmt::format("endian: {}\n", little());
    h += fmt::format("encoding: {}\n\n", compress ? "gzip" : "raw");
    write_bytes(path, h + (compress ? deflate_bytes(data, true) : data));
  } else if (e == ".mha") {
    std::string h = fmt::format("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = {}\n",
                                std::endian::native == std::endian::big ? "True" : "False");
    std::string comp;
    if (compress) comp = deflate_bytes(data, false);
    if (compress) h += fmt::format("CompressedData = True\nCompressedDataSize = {}\n", comp.size());
    h += "TransformMatrix =";
    for (int a = 0; a < 3; ++a)
      for (int r = 0; r < 3; ++r) h += fmt::format(" {:.17g}", D[3 * r + a]);
    h += fmt::format("\nOffset = {:.17g} {:.17g} {:.17g}\nElementSpacing = {:.17g} {:.17g} {:.17g}\n", org[0], org[1], org[2], sp[0], sp[1], sp[2]);
    h += fmt::format("DimSize = {} {} {}\nElementType = {}\nElementDataFile = LOCAL\n", im.dims[0], im.dims[1], im.dims[2],
                     t == VoxelType::u8 ? "MET_UCHAR" : t == VoxelType::i16 ? "MET_SHORT" : "MET_INT");
    write_bytes(path, h + (compress ? comp : data));
  } else if (e == ".nii" || e == ".nii.gz") {
    std::string hdr(352, '\0');
    auto put = [&](size_t off, auto v) { std::memcpy(&hdr[off], &v, sizeof(v)); };
    put(0, int32_t(348));
    put(40, int16_t(3));
    for (int a = 0; a < 3; ++a) put(42 + 2 * a, int16_t(im.dims[a]));
    for (int a = 3; a < 7; ++a) put(42 + 2 * a, int16_t(1));
    put(70, int16_t(t == VoxelType::u8 ? 2 : t == VoxelType::i16 ? 4 : 8));
    put(72, int16_t(8 * type_bytes(t)));
    put(76, 1.0f);
    for (int a = 0; a < 3; ++a) put(80 + 4 * a, float(sp[a]));
    put(108, 352.0f);
    hdr[123] = 2;  // mm
    put(254, int16_t(1));  // sform: scanner-anat
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) put(280 + 16 * r + 4 * c, float(D[3 * r + c] * sp[c]));
      put(280 + 16 * r + 12, float(org[r]));
    }
    std::memcpy(&hdr[344], "n+1\0", 4);
    if (std::endian::native == std::endian::big) throw std::runtime_error("NIfTI writer: little-endian hosts only");
    const std::string all = hdr + data;
    write_bytes(path, e == ".nii.gz" ? deflate_bytes(all, true) : all);
  } else if (e == ".inr" || e == ".inr.gz") {
    std::string h = fmt::format("#INRIMAGE-4#{{\nXDIM={}\nYDIM={}\nZDIM={}\nVDIM=1\nVX={:.17g}\nVY={:.17g}\nVZ={:.17g}\n"
                                "TX={:.17g}\nTY={:.17g}\nTZ={:.17g}\nTYPE={}\nPIXSIZE={} bits\nSCALE=2**0\nCPU={}\n",
                                im.dims[0], im.dims[1], im.dims[2], sp[0], sp[1], sp[2], org[0], org[1], org[2],
                                t == VoxelType::u8 ? "unsigned fixed" : "signed fixed", 8 * type_bytes(t),
                                std::endian::native == std::endian::big ? "sun" : "decm");
    const size_t total = ((h.size() + 4 + 255) / 256) * 256;
    h += std::string(total - h.size() - 4, '\n');
    h += "##}\n";
    const std::string all = h + data;
    write_bytes(path, e == ".inr.gz" ? deflate_bytes(all, true) : all);
  } else {
    throw std::runtime_error(fmt::format("{}: cannot write a label image with extension '{}' (.nrrd, .nii, .nii.gz, .mha, .inr, .inr.gz)", path, e));
  }
}

std::vector<std::pair<int32_t, int64_t>> label_histogram(const LabelImage& image) {
  std::map<int32_t, int64_t> m;
  for (int32_t v : image.labels) ++m[v];
  return {m.begin(), m.end()};
}

}  // namespace stroma
