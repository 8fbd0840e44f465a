// libFuzzer target: the tetrahedral mesh readers (gmsh 1/2/4, legacy VTK ASCII/binary, VTU) and
// what a scenario does next with a mesh: prepare_mesh (validation, boundary) and the visual
// mapping of a surface onto it. The format is sniffed from the content, so the seeds are plain
// mesh files.
#include <sstream>
#include <string>

#include "tissue/bounding_box.hpp"
#include "tissue/input_error.hpp"
#include "io/mesh_io.hpp"
#include "tissue/mesh_prepare.hpp"
#include "tissue/visual_mapping.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::istringstream in(text);
  try {
    stroma::TetMesh mesh;
    if (text.find("<VTKFile") != std::string::npos) mesh = stroma::read_vtu(in, "fuzz.vtu");
    else if (text.rfind("# vtk", 0) == 0) mesh = stroma::read_vtk_legacy(in, "fuzz.vtk");
    else mesh = stroma::read_gmsh(in, "fuzz.msh");
    stroma::PreparedMesh pm = stroma::prepare_mesh(std::move(mesh));
    // A visual surface: the mesh's own boundary vertices, nudged outwards a little.
    std::vector<stroma::Vec3> verts;
    for (const stroma::Tri& t : pm.boundary) {
      if (verts.size() >= 64) break;
      verts.push_back(pm.mesh.nodes[t[0]]);
    }
    const double diag = stroma::bounding_box(pm.mesh.nodes).diagonal();
    stroma::build_visual_mapping(pm.mesh, verts, 0.05 * diag, 0, 0, "fuzz.obj");
  } catch (const stroma::InputError&) {
  }
  return 0;
}
