/// \file cmd_mesh.cpp
/// `stroma mesh surface` and `stroma mesh image`: a closed surface or a labelled image to a
/// tetrahedral mesh (tissue/meshing, CGAL Mesh_3), with its quality report (printed, JSON, PNG)
/// and, on request, a starter scenario. Every input is checked before anything is written; the
/// outputs are written only when meshing succeeded, each through a temporary file.

#include <cctype>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>

#include <fmt/format.h>

#include "cli/commands.hpp"
#include "io/label_image.hpp"
#include "io/mesh_write.hpp"
#include "io/surface_io.hpp"
#include "scene/starter_scenario.hpp"
#include "tissue/input_error.hpp"
#include "tissue/meshing/mesher.hpp"
#include "tissue/meshing/quality_report.hpp"

namespace fs = std::filesystem;

namespace stroma::cli {
namespace {

struct MeshArgs {
  std::string input, out, report, png, scenario, labels, up, unit;
  double size = 0, scale = 1, min_dihedral = 5, sliver_angle = 5, facet_distance = 0;
  long tets = 5000;
  unsigned seed = 1;
  bool quiet = false, no_png = false, repair = false, no_fit = false;
  double feature_angle = 0, smooth = 0.4;
  CLI::Option* size_opt = nullptr;
  std::string command_line;
};

void add_common(CLI::App* c, MeshArgs& a) {
  a.size_opt = c->add_option("--size", a.size,
                             "Mean edge length of the mesh in metres (surface: in the surface's units after --scale), met "
                             "within 8 %; the achieved one is reported. Default: the size that gives --tets elements");
  c->add_option("--tets", a.tets, "Without --size: this many tetrahedra, within 15 % (5000: what one core steps at 1 kHz)")
      ->capture_default_str()
      ->excludes(a.size_opt);
  c->add_option("--min-dihedral", a.min_dihedral,
                "Smallest dihedral angle (degrees) the mesh must have: the optimisers aim 5 degrees higher, and a mesh "
                "below it is reported (exit 1)")
      ->capture_default_str();
  c->add_option("--sliver-angle", a.sliver_angle, "Report elements with a dihedral angle below this (degrees) as slivers")
      ->capture_default_str();
  c->add_option("--facet-distance", a.facet_distance,
                "Largest distance between a boundary facet and the input surface (m). Default: H/40 with H the "
                "size control's CGAL size (images: H/20, at least a quarter voxel)");
  c->add_option("--out,-o", a.out, "Output mesh, .msh (gmsh 2.2, named regions) or .vtu. Default: INPUT's name with .msh, "
                                   "in the current folder");
  c->add_option("--report", a.report, "Quality report JSON. Default: OUT with .quality.json");
  c->add_option("--png", a.png, "Histogram plot PNG. Default: OUT with .quality.png");
  c->add_flag("--no-png", a.no_png, "Do not draw the histogram PNG");
  c->add_option("--scenario", a.scenario, "Also write a starter scenario YAML (SI units, bottom fixed) that runs as is");
  c->add_option("--up", a.up, "Up axis for the starter scenario's gravity and fixed bottom: x, y, z, -x, -y or -z "
                              "(default: z for images, y for surfaces)");
  c->add_flag("--no-fit", a.no_fit,
              "Keep the boundary's vertices on the surface (facets as chords: curved regions lose volume) instead of "
              "fitting the facets to straddle it");
  c->add_option("--seed", a.seed, "Seed of CGAL's random choices (same seed, same mesh)")->capture_default_str();
  c->add_flag("--quiet,-q", a.quiet, "Print only errors");
}

std::string with_suffix(const std::string& path, const std::string& suffix) {
  fs::path p(path);
  return (p.parent_path() / p.stem()).string() + suffix;
}

std::string input_stem(const std::string& path) {
  std::string name = fs::path(path).filename().string();
  for (const char* e : {".nii.gz", ".inr.gz"})
    if (name.size() > std::strlen(e) && name.ends_with(e)) return name.substr(0, name.size() - std::strlen(e));
  return fs::path(name).stem().string();
}

/// Parses "1=liver,2=tumour" (a bare "1" names the region label1).
std::vector<std::pair<int32_t, std::string>> parse_labels(const std::string& source, const std::string& spec) {
  std::vector<std::pair<int32_t, std::string>> out;
  if (spec.empty()) throw InputError(source, 0, "--labels", "empty: give LABEL=NAME pairs, e.g. --labels 1=liver,2=tumour");
  static const std::regex item(R"(^\s*(-?\d+)\s*(?:=\s*([A-Za-z_][A-Za-z0-9_.-]*)\s*)?$)");
  size_t start = 0;
  while (start <= spec.size()) {
    const size_t comma = spec.find(',', start);
    const std::string it = spec.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    std::smatch m;
    if (!std::regex_match(it, m, item))
      throw InputError(source, 0, "--labels",
                       fmt::format("'{}' is not LABEL=NAME (an integer label, a name of letters, digits, _ . -)", it));
    const long v = std::stol(m[1].str());
    if (v <= 0 || v > 2147483647) throw InputError(source, 0, "--labels", fmt::format("label {} must be > 0 (0 is background)", v));
    std::string name = m[2].matched ? m[2].str() : fmt::format("label{}", v);
    for (const auto& [l, n] : out) {
      if (l == v) throw InputError(source, 0, "--labels", fmt::format("label {} given twice", v));
      if (n == name) throw InputError(source, 0, "--labels", fmt::format("name '{}' given twice", name));
    }
    out.emplace_back(int32_t(v), name);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

void parse_up(const std::string& source, const std::string& up, StarterScenarioSpec& s) {
  static const std::map<std::string, std::pair<int, double>> k = {{"x", {0, 1}},  {"y", {1, 1}},  {"z", {2, 1}},
                                                                  {"-x", {0, -1}}, {"-y", {1, -1}}, {"-z", {2, -1}},
                                                                  {"+x", {0, 1}}, {"+y", {1, 1}}, {"+z", {2, 1}}};
  auto it = k.find(up);
  if (it == k.end()) throw InputError(source, 0, "--up", fmt::format("'{}' is not x, y, z, -x, -y or -z", up));
  s.up_axis = it->second.first;
  s.up_sign = it->second.second;
}

/// Checks what does not need the input's contents, and resolves the output paths.
void resolve(MeshArgs& a, const char* default_up) {
  if (a.size_opt->count() && !(a.size > 0))
    throw InputError(a.input, 0, "--size", fmt::format("{} is not a length > 0 (metres)", a.size));
  if (!(a.min_dihedral >= 0 && a.min_dihedral < 30))
    throw InputError(a.input, 0, "--min-dihedral", fmt::format("{} degrees: give 0..30 (CGAL's optimisers reach ~10-15)", a.min_dihedral));
  if (!(a.sliver_angle >= 0 && a.sliver_angle < 60))
    throw InputError(a.input, 0, "--sliver-angle", fmt::format("{} degrees: give 0..60", a.sliver_angle));
  if (!(a.facet_distance >= 0)) throw InputError(a.input, 0, "--facet-distance", fmt::format("{} is not a length >= 0", a.facet_distance));
  if (a.tets < 1) throw InputError(a.input, 0, "--tets", fmt::format("{} is not a positive count", a.tets));
  if (!(a.scale > 0)) throw InputError(a.input, 0, "--scale", fmt::format("{} is not > 0", a.scale));
  if (!(a.smooth >= 0 && a.smooth <= 3)) throw InputError(a.input, 0, "--smooth", fmt::format("{} voxels: give 0..3", a.smooth));
  if (a.out.empty()) a.out = input_stem(a.input) + ".msh";
  std::string ext = fs::path(a.out).extension().string();
  if (ext != ".msh" && ext != ".vtu") throw InputError(a.out, 0, "--out", fmt::format("'{}': the mesh is written as .msh or .vtu", ext));
  if (a.report.empty()) a.report = with_suffix(a.out, ".quality.json");
  if (a.png.empty()) a.png = with_suffix(a.out, ".quality.png");
  if (a.up.empty()) a.up = default_up;
  StarterScenarioSpec probe;
  parse_up(a.input, a.up, probe);
  for (const std::string* p : {&a.out, &a.report, &a.png, &a.scenario}) {
    if (p->empty()) continue;
    const fs::path parent = fs::path(*p).parent_path();
    if (!parent.empty() && !fs::is_directory(parent))
      throw InputError(*p, 0, "", fmt::format("folder '{}' does not exist; nothing written", parent.string()));
  }
  if (!fs::exists(a.input)) throw InputError(a.input, 0, "", "no such file");
}

meshing::MeshingOptions options_of(const MeshArgs& a) {
  meshing::MeshingOptions o;
  o.size = a.size;
  o.target_tets = a.tets;
  o.min_dihedral_deg = a.min_dihedral;
  o.sliver_angle_deg = a.sliver_angle;
  o.facet_distance = a.facet_distance;
  o.seed = a.seed;
  o.repair_self_intersections = a.repair;
  o.feature_angle_deg = a.feature_angle;
  o.smooth_voxels = a.smooth;
  o.fit_boundary = !a.no_fit;
  if (!a.quiet) {
    const auto t0 = std::chrono::steady_clock::now();
    o.progress = [t0](const std::string& m) {
      fmt::print(stderr, "[{:7.1f} s] {}\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), m);
    };
  }
  return o;
}

void write_text(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".part";
  {
    std::ofstream out(tmp);
    out << text;
    if (!out) throw std::runtime_error(fmt::format("{}: cannot write", path));
  }
  fs::rename(tmp, path);
}

/// Writes mesh, report, PNG and scenario; prints the report; returns the exit code (1 when the
/// mesh misses the requested minimum dihedral angle or has slivers or inverted elements).
int finish(const MeshArgs& a, const meshing::MeshingResult& r, const meshing::MeshingOptions& o, const char* default_up) {
  write_tet_mesh(a.out, r.mesh);
  const nlohmann::json j = meshing::quality_report_json(r, o, a.input, a.command_line);
  write_text(a.report, j.dump(2) + "\n");
  std::string png_note;
  if (!a.no_png) png_note = meshing::write_quality_png(r.quality, fmt::format("{} -> {}", input_stem(a.input), a.out), a.png);
  if (!a.scenario.empty()) {
    StarterScenarioSpec s;
    s.name = input_stem(a.out);
    for (char& c : s.name)
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-') c = '_';
    s.mesh_path = fs::relative(fs::absolute(a.out), fs::absolute(a.scenario).parent_path()).string();
    s.made_by = a.command_line;
    parse_up(a.input, a.up.empty() ? default_up : a.up, s);
    write_text(a.scenario, starter_scenario_yaml(r.mesh, s));
    if (const std::string w = real_time_warning(r.mesh.tets.size()); !w.empty())
      fmt::print(stderr, "warning: {} ({}).\n", w, a.scenario);
  }
  for (const std::string& n : r.notes)
    if (!a.quiet) fmt::print("note: {}\n", n);
  if (!a.quiet)
    fmt::print("size: asked {}; got {} elements, mean edge {:.4g} ({} refinement{} at CGAL size {:.4g})\n", r.size_asked,
               r.quality.tets, r.quality.edge_mean, r.size_passes, r.size_passes == 1 ? "" : "s", r.size);
  const MeshQuality& q = r.quality;
  const bool bound_met = q.dihedral_min_deg >= o.min_dihedral_deg && q.slivers == 0 && q.inverted == 0;
  if (!a.quiet) {
    fmt::print("{} -> {} (H = {:.4g} m)\n{}", a.input, a.out, r.size, format_mesh_quality(q));
    fmt::print("  wrote {}", a.report);
    if (!a.no_png) fmt::print(", {}", png_note.empty() ? a.png : "no PNG (" + png_note + ")");
    if (!a.scenario.empty()) fmt::print(", {} (run it: stroma run {})", a.scenario, a.scenario);
    fmt::print("\n");
  }
  if (!bound_met) {
    fmt::print(stderr,
               "warning: the mesh misses the quality asked for: min dihedral {:.2f} deg (asked {:g}), {} slivers below {:g} "
               "deg, {} inverted. Try a smaller --size or a lower --min-dihedral; the mesh is written for inspection.\n",
               q.dihedral_min_deg, o.min_dihedral_deg, q.slivers, o.sliver_angle_deg, q.inverted);
    return 1;
  }
  return 0;
}

}  // namespace

void add_mesh(CLI::App& app, std::vector<Command>& out) {
  auto* mesh = app.add_subcommand("mesh", "Make a tetrahedral mesh from a closed surface or a labelled image (CGAL Mesh_3)");
  mesh->require_subcommand(1);

  auto s = std::make_shared<MeshArgs>();
  auto* surf = mesh->add_subcommand("surface", "A closed surface (.stl .obj .off) to a quality tet mesh");
  surf->add_option("SURFACE", s->input, "Closed, manifold, self-intersection-free triangle surface (.stl, .obj, .off)")->required();
  surf->add_option("--scale", s->scale, "Multiply the surface's coordinates by this first (e.g. 0.001 for mm to m)")
      ->capture_default_str();
  surf->add_flag("--repair", s->repair, "Let CGAL remove self-intersecting triangles and refill the holes (small folds, "
                                       "e.g. in SOFA's liver-smooth.obj) instead of refusing the surface");
  surf->add_option("--sharp-edges", s->feature_angle,
                   "Keep sharp edges crisp: protect edges where the surface turns by more than this many degrees "
                   "(default 0: none; organs are smooth)");
  add_common(surf, *s);
  surf->footer("Example: stroma mesh surface scenarios/meshes/liver-smooth.obj --scale 0.025 --repair --tets 2000 --out liver_2k.msh "
               "--scenario liver_2k.yaml");
  out.push_back({surf, [s, surf] {
                   s->command_line = invocation();
                   resolve(*s, "y");
                   const SurfaceMesh input = read_surface_mesh(s->input);
                   const meshing::MeshingOptions o = options_of(*s);
                   const meshing::MeshingResult r = meshing::mesh_surface(input, s->scale, o);
                   return finish(*s, r, o, "y");
                 }});

  auto im = std::make_shared<MeshArgs>();
  auto* img = mesh->add_subcommand("image", "A labelled image (segmentation) to a multi-material tet mesh");
  img->add_option("LABELS", im->input, "Label image: .nrrd .nhdr .nii .nii.gz .mha .mhd .inr .inr.gz")->required();
  img->add_option("--labels", im->labels, "Labels to mesh and their region names: 1=liver,2=tumour (others: background)")
      ->required();
  img->add_option("--smooth", im->smooth,
                  "Smooth each label's surface with a Gaussian of this sigma, in voxels (0: staircase surfaces)")
      ->capture_default_str();
  img->add_option("--unit", im->unit, "Override the image's spacing unit: m, cm, mm or um (default: the file's; mm if none)");
  add_common(img, *im);
  img->footer("Example: stroma mesh image segmentation.nii.gz --labels 1=liver,2=tumour --size 0.006 --out liver.msh "
              "--scenario liver.yaml");
  out.push_back({img, [im] {
                   im->command_line = invocation();
                   resolve(*im, "z");
                   const auto labels = parse_labels(im->input, im->labels);
                   LabelImageReadOptions ro;
                   if (!im->unit.empty()) {
                     static const std::map<std::string, double> units = {{"m", 1.0}, {"cm", 1e-2}, {"mm", 1e-3}, {"um", 1e-6}};
                     auto u = units.find(im->unit);
                     if (u == units.end()) throw InputError(im->input, 0, "--unit", fmt::format("'{}' is not m, cm, mm or um", im->unit));
                     ro.unit_override = u->second;
                   }
                   const meshing::MeshingOptions o = options_of(*im);
                   if (o.progress) o.progress(fmt::format("reading {}", im->input));
                   const LabelImage image = read_label_image(im->input, ro);
                   if (o.progress)
                     o.progress(fmt::format("{} x {} x {} voxels of {:.3g} x {:.3g} x {:.3g} mm", image.dims[0], image.dims[1],
                                            image.dims[2], image.spacing[0] * 1e3, image.spacing[1] * 1e3, image.spacing[2] * 1e3));
                   const meshing::MeshingResult r = meshing::mesh_label_image(image, labels, o);
                   return finish(*im, r, o, "z");
                 }});
}

}  // namespace stroma::cli
