#pragma once
/// \file label_image.hpp
/// A labelled volume image (a segmentation: each voxel holds the integer label of the tissue it
/// lies in, 0 = background) and its readers and writers: NRRD (.nrrd, raw or gzip encoding;
/// .nhdr with a detached raw file), NIfTI-1 (.nii, .nii.gz), MetaImage (.mha, .mhd with a raw
/// file; raw or zlib-compressed) and INRIMAGE-4 (.inr, .inr.gz; CGAL's own format).
///
/// Hand-written on purpose: each format's part that a segmentation uses is a header of a few
/// fields and one block of integers, and every reader here checks each field and the data size
/// before it allocates (fuzzed: tests/fuzz/fuzz_label_image.cpp). The libraries that read them
/// all (ITK, VTK) are hundreds of megabytes of dependencies for that header; nifticlib and teem
/// each cover one format and report errors on stderr rather than to the caller.
///
/// Units: geometry is returned in metres. Medical images give spacing in millimetres unless they
/// say otherwise: NIfTI's xyzt_units (metre, mm, µm; "unknown" is read as mm, as every viewer
/// does), NRRD's "space units" (m, mm, um; absent: mm); MetaImage and INR have no unit field and
/// are read as mm. `LabelImageReadOptions::unit_override` replaces the file's unit.
///
/// Orientation: the voxel (i, j, k) centre is at `origin + direction * diag(spacing) * (i, j, k)`.
/// `direction`'s columns are unit vectors and orthogonal (a rotation, possibly with a reflection:
/// LPS/RAS flips are common); a sheared grid is refused, because a mesh of it would need a
/// non-rigid map.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace stroma {

/// A labelled 3-D image. Invariants: dims[a] >= 1; labels.size() == dims[0]*dims[1]*dims[2],
/// x fastest (index = i + dims[0]*(j + dims[1]*k)); spacing[a] > 0 (metres); direction is
/// orthonormal (columns: the image axes in world coordinates).
struct LabelImage {
  std::array<int64_t, 3> dims{0, 0, 0};
  std::array<double, 3> spacing{1e-3, 1e-3, 1e-3};  ///< voxel size along each axis, metres
  std::array<double, 3> origin{0, 0, 0};            ///< centre of voxel (0,0,0), metres
  /// Row-major 3x3; column a is the world direction of image axis a.
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::vector<int32_t> labels;  ///< voxel labels, x fastest
  std::string source;           ///< file path (for messages)

  int64_t voxel_count() const { return dims[0] * dims[1] * dims[2]; }
  int32_t at(int64_t i, int64_t j, int64_t k) const { return labels[size_t(i + dims[0] * (j + dims[1] * k))]; }
  double voxel_volume() const { return spacing[0] * spacing[1] * spacing[2]; }
};

/// Options for reading. `unit_override` (metres per file unit; 0 = use the file's unit, or mm
/// where the format has none).
struct LabelImageReadOptions {
  double unit_override = 0.0;
};

/// Reads a label image, the format chosen by extension (.nrrd, .nhdr, .nii, .nii.gz, .mha, .mhd,
/// .inr, .inr.gz; case-insensitive). Voxel values must be integers (8/16/32-bit, signed or not;
/// a float image is refused unless every value is an integer). Throws InputError naming the
/// file, the header line (0 in binary data) and the field for every problem: an unknown
/// extension, a missing or contradictory field, a data block shorter than the header says
/// (truncated), a corrupt compressed stream, a non-3-D image, a sheared grid.
LabelImage read_label_image(const std::string& path, const LabelImageReadOptions& options = {});

/// Writes a label image in the format its extension names (the same list; .nii.gz / .nrrd
/// written gzip-compressed when `compress`). Spacing and origin are written in millimetres.
/// Voxels are stored as uint8 when every label fits, else int16 or int32. Throws
/// std::runtime_error if the file cannot be written.
void write_label_image(const std::string& path, const LabelImage& image, bool compress = true);

/// Per label, its voxel count (labels in increasing order, background 0 included if present).
std::vector<std::pair<int32_t, int64_t>> label_histogram(const LabelImage& image);

}  // namespace stroma
