/// \file mesh_write.cpp
/// gmsh 2.2 and VTU writers for tetrahedral meshes (see mesh_write.hpp).

#include "io/mesh_write.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>

#include <fmt/format.h>

#include "io/text_scan.hpp"

namespace stroma {
namespace {

void write_gmsh22(std::ostream& out, const TetMesh& m) {
  out << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
  if (!m.tag_names.empty()) {
    out << "$PhysicalNames\n" << m.tag_names.size() << "\n";
    for (const auto& [tag, name] : m.tag_names) out << fmt::format("3 {} \"{}\"\n", tag, name);
    out << "$EndPhysicalNames\n";
  }
  out << "$Nodes\n" << m.nodes.size() << "\n";
  for (size_t i = 0; i < m.nodes.size(); ++i)
    out << fmt::format("{} {:.17g} {:.17g} {:.17g}\n", i + 1, m.nodes[i][0], m.nodes[i][1], m.nodes[i][2]);
  out << "$EndNodes\n$Elements\n" << m.tets.size() << "\n";
  for (size_t t = 0; t < m.tets.size(); ++t) {
    const int32_t tag = m.tet_tags.empty() ? 1 : m.tet_tags[t];
    const Tet& e = m.tets[t];
    // type 4 = linear tetrahedron; two tags: physical group, elementary entity (the same here)
    out << fmt::format("{} 4 2 {} {} {} {} {} {}\n", t + 1, tag, tag, e[0] + 1, e[1] + 1, e[2] + 1, e[3] + 1);
  }
  out << "$EndElements\n";
}

void write_vtu_ascii(std::ostream& out, const TetMesh& m) {
  out << "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n"
         "  <UnstructuredGrid>\n";
  out << fmt::format("    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", m.nodes.size(), m.tets.size());
  out << "      <Points>\n        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
  for (const Vec3& p : m.nodes) out << fmt::format("          {:.17g} {:.17g} {:.17g}\n", p[0], p[1], p[2]);
  out << "        </DataArray>\n      </Points>\n      <Cells>\n"
         "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  for (const Tet& t : m.tets) out << fmt::format("          {} {} {} {}\n", t[0], t[1], t[2], t[3]);
  out << "        </DataArray>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  for (size_t t = 0; t < m.tets.size(); ++t) out << fmt::format("          {}\n", 4 * (t + 1));
  out << "        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
  for (size_t t = 0; t < m.tets.size(); ++t) out << "          10\n";
  out << "        </DataArray>\n      </Cells>\n";
  if (!m.tet_tags.empty()) {
    out << "      <CellData Scalars=\"region\">\n        <DataArray type=\"Int32\" Name=\"region\" format=\"ascii\">\n";
    for (int32_t tag : m.tet_tags) out << fmt::format("          {}\n", tag);
    out << "        </DataArray>\n      </CellData>\n";
  }
  out << "    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n";
}

}  // namespace

void write_tet_mesh(const std::string& path, const TetMesh& mesh) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = text::lower(c);
  if (ext != ".msh" && ext != ".vtu")
    throw std::runtime_error(fmt::format("{}: cannot write a mesh with extension '{}' (.msh or .vtu)", path, ext));
  const std::string tmp = path + ".part";
  {
    std::ofstream out(tmp);
    if (!out) throw std::runtime_error(fmt::format("{}: cannot write", path));
    if (ext == ".msh") write_gmsh22(out, mesh);
    else write_vtu_ascii(out, mesh);
    out.flush();
    if (!out) {
      std::remove(tmp.c_str());
      throw std::runtime_error(fmt::format("{}: write failed (disk full?)", path));
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    throw std::runtime_error(fmt::format("{}: cannot write ({})", path, ec.message()));
  }
}

}  // namespace stroma
