#include "runtime/vtu_writer.hpp"

#include <cstdio>
#include <memory>
#include <stdexcept>

#include <fmt/format.h>

#include "tissue/fem_forces.hpp"

namespace stroma {

namespace {
struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

File open_for_write(const std::string& path) {
  File f(std::fopen(path.c_str(), "w"));
  if (!f) throw std::runtime_error(fmt::format("cannot write '{}'", path));
  return f;
}
}  // namespace

void write_vtu(const std::string& path, const Model& m, const State& s) {
  std::vector<double> vm(m.fem.elements.size());
  element_von_mises(m.fem, s.tissue.x.data(), vm.data());
  std::string out;
  out += "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n";
  for (size_t bi = 0; bi < m.fem.bodies.size(); ++bi) {
    const BodyRange& b = m.fem.bodies[bi];
    const int32_t nn = b.node_end - b.node_begin;
    const int32_t ne = b.element_end - b.element_begin;
    out += fmt::format("<Piece Name=\"{}\" NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n", b.name, nn, ne);
    out += "<PointData Vectors=\"displacement\">\n<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for (int32_t i = b.node_begin; i < b.node_end; ++i)
      out += fmt::format("{:.9g} {:.9g} {:.9g}\n", s.tissue.x[3 * i] - m.fem.rest[3 * i],
                         s.tissue.x[3 * i + 1] - m.fem.rest[3 * i + 1],
                         s.tissue.x[3 * i + 2] - m.fem.rest[3 * i + 2]);
    out += "</DataArray>\n</PointData>\n<CellData Scalars=\"von_mises\">\n<DataArray type=\"Float64\" Name=\"von_mises\" format=\"ascii\">\n";
    for (int32_t e = b.element_begin; e < b.element_end; ++e) out += fmt::format("{:.9g}\n", vm[e]);
    out += "</DataArray>\n</CellData>\n<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n";
    for (int32_t i = b.node_begin; i < b.node_end; ++i)
      out += fmt::format("{:.12g} {:.12g} {:.12g}\n", s.tissue.x[3 * i], s.tissue.x[3 * i + 1], s.tissue.x[3 * i + 2]);
    out += "</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n";
    for (const Tet& t : m.body_tets[bi])
      out += fmt::format("{} {} {} {}\n", t[0] - b.node_begin, t[1] - b.node_begin, t[2] - b.node_begin, t[3] - b.node_begin);
    out += "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n";
    for (int32_t e = 0; e < ne; ++e) out += fmt::format("{}\n", 4 * (e + 1));
    out += "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    for (int32_t e = 0; e < ne; ++e) out += "10\n";
    out += "</DataArray>\n</Cells>\n</Piece>\n";
  }
  out += "</UnstructuredGrid>\n</VTKFile>\n";
  File f = open_for_write(path);
  if (std::fwrite(out.data(), 1, out.size(), f.get()) != out.size())
    throw std::runtime_error(fmt::format("cannot write '{}'", path));
}

void write_pvd(const std::string& path, const std::vector<std::pair<double, std::string>>& frames) {
  std::string out = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n";
  for (const auto& [t, file] : frames)
    out += fmt::format("<DataSet timestep=\"{:.9g}\" file=\"{}\"/>\n", t, file);
  out += "</Collection>\n</VTKFile>\n";
  File f = open_for_write(path);
  if (std::fwrite(out.data(), 1, out.size(), f.get()) != out.size())
    throw std::runtime_error(fmt::format("cannot write '{}'", path));
}

}  // namespace stroma
