#pragma once
/// \file quality_report.hpp
/// The quality report of `stroma mesh` as files: JSON (every number of MeshQuality, the
/// options, stage timings) and a PNG of the two histograms drawn by gnuplot (Debian's
/// gnuplot-nox, installed by scripts/setup.sh; if it is missing the PNG is skipped with a note).

#include <string>

#include <nlohmann/json.hpp>

#include "tissue/meshing/mesher.hpp"

namespace stroma::meshing {

/// The report as JSON: {"input", "command", "size", "elements", "nodes", "radius_ratio":
/// {min, mean, max, histogram: {lo, hi, counts}}, "dihedral_deg": {...}, "slivers":
/// {threshold_deg, count}, "inverted", "min_dihedral_requested_deg", "regions": [{tag, name, tets,
/// volume_m3, input_volume_m3, relative_error}], "hausdorff_m", "hausdorff_reference",
/// "stage_seconds": {...}, "total_seconds"}.
nlohmann::json quality_report_json(const MeshingResult& r, const MeshingOptions& o, const std::string& input,
                                   const std::string& command);

/// Draws both histograms into `png_path` with gnuplot. Returns "" on success, else why not.
std::string write_quality_png(const MeshQuality& q, const std::string& title, const std::string& png_path);

}  // namespace stroma::meshing
