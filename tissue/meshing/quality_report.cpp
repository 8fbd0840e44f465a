/// \file quality_report.cpp
/// JSON and PNG quality reports (see quality_report.hpp).

#include "tissue/meshing/quality_report.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include <fmt/format.h>

namespace stroma::meshing {
namespace {

nlohmann::json histogram_json(const Histogram& h) {
  return {{"lo", h.lo}, {"hi", h.hi}, {"counts", h.counts}};
}

nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

}  // namespace

nlohmann::json quality_report_json(const MeshingResult& r, const MeshingOptions& o, const std::string& input,
                                   const std::string& command) {
  const MeshQuality& q = r.quality;
  nlohmann::json j;
  j["input"] = input;
  j["command"] = command;
  j["size"] = r.size;
  j["size_asked"] = r.size_asked;
  j["size_passes"] = r.size_passes;
  j["edge_length_m"] = {{"min", q.edge_min}, {"mean", q.edge_mean}, {"max", q.edge_max}};
  j["boundary_fit"] = {{"facets", r.fit.facets}, {"facets_measured", r.fit.facets_measured},
                       {"vertices_moved", r.fit.vertices_moved}, {"vertices_kept", r.fit.vertices_kept},
                       {"max_shift_m", r.fit.max_shift}};
  j["elements"] = q.tets;
  j["nodes"] = q.nodes;
  j["radius_ratio"] = {{"min", q.radius_ratio_min}, {"mean", q.radius_ratio_mean}, {"max", q.radius_ratio_max},
                       {"histogram", histogram_json(q.radius_ratio)}};
  j["dihedral_deg"] = {{"min", q.dihedral_min_deg}, {"max", q.dihedral_max_deg}, {"histogram", histogram_json(q.dihedral)}};
  j["min_dihedral_requested_deg"] = o.min_dihedral_deg;
  j["slivers"] = {{"threshold_deg", q.sliver_angle_deg}, {"count", q.slivers}};
  j["inverted"] = q.inverted;
  j["total_volume_m3"] = q.total_volume;
  nlohmann::json regions = nlohmann::json::array();
  for (const RegionVolume& v : q.regions)
    regions.push_back({{"tag", v.tag}, {"name", v.name}, {"tets", v.tets}, {"volume_m3", v.volume},
                       {"input_volume_m3", number_or_null(v.input_volume)}, {"relative_error", number_or_null(v.relative_error())}});
  j["regions"] = regions;
  j["hausdorff_m"] = number_or_null(q.hausdorff);
  j["hausdorff_reference"] = q.hausdorff_reference;
  nlohmann::json stages = nlohmann::json::object();
  double total = 0;
  for (const auto& [name, s] : r.stage_seconds) {
    stages[name] = s;
    total += s;
  }
  j["stage_seconds"] = stages;
  j["total_seconds"] = total;
  return j;
}

std::string write_quality_png(const MeshQuality& q, const std::string& title, const std::string& png_path) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / fmt::format("stroma-mesh-plot-{}", ::getpid());
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return "cannot create a temporary directory for the plot";
  auto dat = [&](const Histogram& h, const std::string& name) {
    std::ofstream out(dir / name);
    const double w = (h.hi - h.lo) / double(h.counts.size());
    for (size_t i = 0; i < h.counts.size(); ++i) out << fmt::format("{} {}\n", h.lo + w * (double(i) + 0.5), h.counts[i]);
  };
  dat(q.radius_ratio, "rr.dat");
  dat(q.dihedral, "dh.dat");
  const std::string tmp_png = png_path + ".part.png";
  std::string script = fmt::format(
      "set terminal pngcairo size 1000,420 font 'sans,10'\n"
      "set output {out}\n"
      "set multiplot layout 1,2 title {title} noenhanced\n"
      "set style fill solid 0.8 border -1\nset grid ytics\nset ylabel 'elements'\n"
      "set title sprintf('radius ratio (min %.3f, mean %.3f)', {rr_min}, {rr_mean})\n"
      "set xlabel 'radius ratio 3 r_{{in}} / R_{{circ}}'\n"
      "set xrange [0:1]\nset yrange [0:*]\nset boxwidth 0.045\nplot {rr} using 1:2 with boxes lc rgb '#3b75af' notitle\n"
      "set title sprintf('dihedral angles (min %.2f deg; %d slivers < %g deg)', {dh_min}, {slivers}, {sliver_angle})\n"
      "set xlabel 'dihedral angle (deg)'\nset ylabel 'angles (6 per element)'\nset xrange [0:180]\nset boxwidth 9\n"
      "set arrow from {sliver_angle},graph 0 to {sliver_angle},graph 1 nohead lc rgb '#c0392b' dt 2\n"
      "plot {dh} using 1:2 with boxes lc rgb '#519e3e' notitle\nunset multiplot\n",
      fmt::arg("out", shell_quote(tmp_png)), fmt::arg("title", shell_quote(title)), fmt::arg("rr_min", q.radius_ratio_min),
      fmt::arg("rr_mean", q.radius_ratio_mean), fmt::arg("dh_min", q.dihedral_min_deg), fmt::arg("slivers", q.slivers),
      fmt::arg("sliver_angle", q.sliver_angle_deg), fmt::arg("rr", shell_quote((dir / "rr.dat").string())),
      fmt::arg("dh", shell_quote((dir / "dh.dat").string())));
  {
    std::ofstream out(dir / "plot.gp");
    out << script;
  }
  const std::string cmd = fmt::format("gnuplot {} 2>&1", shell_quote((dir / "plot.gp").string()));
  std::string output;
  int rc = -1;
  if (FILE* p = ::popen(cmd.c_str(), "r")) {
    char buf[256];
    while (std::fgets(buf, sizeof buf, p)) output += buf;
    rc = ::pclose(p);
  }
  fs::remove_all(dir, ec);
  if (rc != 0) {
    fs::remove(tmp_png, ec);
    if (rc == 127 * 256 || output.find("not found") != std::string::npos)
      return "gnuplot is not installed (scripts/setup.sh installs gnuplot-nox)";
    return "gnuplot failed: " + output.substr(0, 300);
  }
  fs::rename(tmp_png, png_path, ec);
  if (ec) return "cannot write " + png_path + ": " + ec.message();
  return "";
}

}  // namespace stroma::meshing
