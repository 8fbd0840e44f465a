// Tests for tissue/mesh_io: the real meshes in scenarios/meshes load with exact counts and
// values, small fixtures cover every format variant, and each kind of bad input is reported with
// the file, the line, the section and the right words.
#include <gtest/gtest.h>

#include <limits>

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cstdint>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "tissue/input_error.hpp"
#include "io/mesh_io.hpp"

namespace stroma {
namespace {

std::string real_mesh(const std::string& name) {
  return std::string(STROMA_SOURCE_DIR) + "/scenarios/meshes/" + name;
}
std::string fixture(const std::string& name) {
  return std::string(STROMA_TEST_DATA) + "/meshes/" + name;
}

std::string write_temp_file(const std::string& name, const std::string& bytes) {
  // TempDir() ends with a separator; the prefix keeps clear of other suites' files under ctest -j.
  const std::string path = ::testing::TempDir() + "mesh_io_" + name;
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return path;
}

/// Runs `load`, which must throw InputError, and checks every part of the report.
void expect_input_error(const std::function<void()>& load, const std::string& file, int line,
                        const std::string& field, const std::vector<std::string>& words) {
  try {
    load();
    ADD_FAILURE() << "no InputError for " << file;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), file) << what;
    EXPECT_EQ(e.line(), line) << what;
    EXPECT_EQ(e.field(), field) << what;
    const std::string where = line > 0 ? file + ":" + std::to_string(line) + ": " : file + ": ";
    EXPECT_EQ(what.rfind(where, 0), 0u)
        << "message does not start with '" << where << "': " << what;
    for (const std::string& word : words)
      EXPECT_NE(what.find(word), std::string::npos) << "missing '" << word << "' in: " << what;
  }
}

void expect_file_error(const std::string& path, int line, const std::string& field,
                       const std::vector<std::string>& words) {
  expect_input_error([&] { load_tet_mesh(path); }, path, line, field, words);
}

// ---------------------------------------------------------------------------------------------
// Real meshes
// ---------------------------------------------------------------------------------------------

struct RealMesh {
  const char* file;
  size_t nodes;
  size_t tets;
};

class RealMeshes : public ::testing::TestWithParam<RealMesh> {};

TEST_P(RealMeshes, LoadWithExactCounts) {
  const RealMesh& expected = GetParam();
  const std::string path = real_mesh(expected.file);
  const TetMesh mesh = load_tet_mesh(path);
  EXPECT_EQ(mesh.nodes.size(), expected.nodes);
  EXPECT_EQ(mesh.tets.size(), expected.tets);
  EXPECT_EQ(mesh.source, path);
  // Every index is a valid zero-based node index.
  for (const Tet& t : mesh.tets)
    for (int32_t n : t) ASSERT_TRUE(n >= 0 && n < static_cast<int32_t>(mesh.nodes.size())) << n;
}

INSTANTIATE_TEST_SUITE_P(ScenarioMeshes, RealMeshes,
                         ::testing::Values(RealMesh{"liver.msh", 181, 596},
                                           RealMesh{"liver2.msh", 507, 1493},
                                           RealMesh{"liver_fine.msh", 1059, 3876},
                                           RealMesh{"cylinder_8x30x6.msh", 1446, 6750},
                                           RealMesh{"Armadillo_Tetra_4406.vtu", 1446, 4406},
                                           RealMesh{"raptorTetra_8418.vtu", 2996, 8418},
                                           RealMesh{"raptorTetra_12580.vtu", 4104, 12580},
                                           RealMesh{"raptorTetra_19409.vtu", 5992, 19409},
                                           RealMesh{"beam_tet4_h5p000mm.msh", 191, 444}),
                         [](const auto& info) {
                           std::string name = info.param.file;
                           std::replace_if(
                               name.begin(), name.end(), [](char c) { return !std::isalnum(c); },
                               '_');
                           return name;
                         });

TEST(MeshIoRealValues, LiverGmsh10) {
  const TetMesh m = load_tet_mesh(real_mesh("liver.msh"));
  EXPECT_EQ(m.nodes[0], (Vec3{-0.979259, 2.23512, 2.61245}));   // "1 -0.979259 2.23512 2.61245"
  EXPECT_EQ(m.nodes[180], (Vec3{-3.80136, 1.56088, 1.80584}));  // "181 -3.80136 1.56088 1.80584"
  EXPECT_EQ(m.tets[0], (Tet{127, 140, 137, 141}));              // "1 4 1 1 4 128 141 138 142"
  EXPECT_EQ(m.tets[595], (Tet{145, 21, 7, 5}));                 // "596 4 1 1 4 146 22 8 6"
}

TEST(MeshIoRealValues, Liver2NonContiguousTagsAndMixedTypes) {
  const TetMesh m = load_tet_mesh(real_mesh("liver2.msh"));
  // Tags start at 2 and have gaps: the first node in the file is index 0 whatever its tag.
  EXPECT_EQ(m.nodes[0], (Vec3{0.3708951229648599, -0.4656592203247305, -0.1604279814553062}));
  // First tetrahedron "932 4 2 2 4 195 1380 332 1360": tags 195, 1380, 332, 1360 are the 42nd,
  // 494th, 82nd and 474th nodes of the file.
  EXPECT_EQ(m.tets[0], (Tet{41, 493, 81, 473}));
}

TEST(MeshIoRealValues, CylinderGmsh10) {
  const TetMesh m = load_tet_mesh(real_mesh("cylinder_8x30x6.msh"));
  EXPECT_EQ(m.nodes[1445],
            (Vec3{0.00978148, -0.00207912, 0.004}));       // "1446 0.00978148 -0.00207912 0.004"
  EXPECT_EQ(m.tets[0], (Tet{271, 241, 242, 0}));           // "1 4 1 1 4 272 242 243 1"
  EXPECT_EQ(m.tets[6749], (Tet{1204, 1203, 1445, 1174}));  // "6750 4 1 1 4 1205 1204 1446 1175"
}

TEST(MeshIoRealValues, BeamGmsh22) {
  const TetMesh m = load_tet_mesh(real_mesh("beam_tet4_h5p000mm.msh"));
  EXPECT_EQ(m.nodes[189], (Vec3{0.004960496347114497, 0.005104246794867075, 0.005104246794872792}));
  EXPECT_EQ(m.tets[0], (Tet{132, 173, 107, 153}));   // "1 4 2 1 1 133 174 108 154"
  EXPECT_EQ(m.tets[443], (Tet{139, 53, 127, 149}));  // "444 4 2 1 1 140 54 128 150"
}

TEST(MeshIoRealValues, ArmadilloVtu) {
  const TetMesh m = load_tet_mesh(real_mesh("Armadillo_Tetra_4406.vtu"));
  // Float32 ascii values are kept as the decimal text says, not rounded to float.
  EXPECT_EQ(m.nodes[0], (Vec3{3.14075, -3.05075, 1.16338}));
  EXPECT_EQ(m.nodes[1445], (Vec3{-1.50746, 7.56499, 2.96931}));
  EXPECT_EQ(m.tets[0], (Tet{337, 1374, 50, 349}));
  EXPECT_EQ(m.tets[4405], (Tet{614, 1324, 1365, 1444}));
}

TEST(MeshIoRealValues, Raptor19409Vtu) {
  const TetMesh m = load_tet_mesh(real_mesh("raptorTetra_19409.vtu"));
  EXPECT_EQ(m.nodes[0], (Vec3{0.0882744, 5.49143, -4.79826}));
  EXPECT_EQ(m.tets[0], (Tet{997, 1285, 5898, 4443}));
}

// ---------------------------------------------------------------------------------------------
// Small fixtures: every variant must give the same two tetrahedra
// ---------------------------------------------------------------------------------------------

const std::vector<Vec3> kFivePoints = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}};
const std::vector<Tet> kTwoTets = {{0, 1, 2, 3}, {1, 2, 3, 4}};

TEST(MeshIoFixtures, Gmsh41EntityBlocksNonContiguousTagsParametricAndTriangles) {
  // $Entities is skipped; tags 10..50 map to 0..4; the parametric surface node carries u v; the
  // triangle block is dropped.
  const TetMesh m = load_tet_mesh(fixture("tet2_v41.msh"));
  EXPECT_EQ(m.nodes, kFivePoints);
  EXPECT_EQ(m.tets, kTwoTets);
}

TEST(MeshIoFixtures, LegacyVtkAscii) {
  const TetMesh m = load_tet_mesh(fixture("tet2_ascii.vtk"));
  EXPECT_EQ(m.nodes, kFivePoints);
  EXPECT_EQ(m.tets, kTwoTets);
}

TEST(MeshIoFixtures, LegacyVtk51OffsetsConnectivityFieldAndMetadata) {
  const TetMesh m = load_tet_mesh(fixture("tet2_v51.vtk"));
  EXPECT_EQ(m.nodes, kFivePoints);
  EXPECT_EQ(m.tets, kTwoTets);
}

TEST(MeshIoFixtures, VtuAsciiAttributesInAnyOrderAndComments) {
  const TetMesh m = load_tet_mesh(fixture("tet2_ascii.vtu"));
  EXPECT_EQ(m.nodes, kFivePoints);
  EXPECT_EQ(m.tets, kTwoTets);
}

// The binary .vtu fixtures were written with Python's struct and base64 modules.
const std::vector<Vec3> kBinaryPoints = {
    {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1.5, 1.25, -2.0}};

TEST(MeshIoFixtures, VtuBinaryUInt32HeaderLittleEndianSeparatelyEncodedHeader) {
  const TetMesh m = load_tet_mesh(fixture("tet2_binary_u32.vtu"));
  EXPECT_EQ(m.nodes, kBinaryPoints);
  EXPECT_EQ(m.tets, kTwoTets);
}

TEST(MeshIoFixtures, VtuBinaryUInt64HeaderBigEndian) {
  const TetMesh m = load_tet_mesh(fixture("tet2_binary_u64.vtu"));
  EXPECT_EQ(m.nodes, kBinaryPoints);
  EXPECT_EQ(m.tets, kTwoTets);
}

// Written by VTK itself (scripts/meshes/write_vtu_variants.py, VTK 9.1 from Debian's
// python3-vtk9): every layout its XML writer produces, VTK's default (appended raw zlib) first.
const char* const kVtkLayouts[] = {"tet2_vtk_appended_raw_zlib.vtu",   "tet2_vtk_appended_raw_u32.vtu",
                                   "tet2_vtk_appended_base64_zlib.vtu", "tet2_vtk_inline_zlib.vtu",
                                   "tet2_vtk_appended_zlib_blocks.vtu", "tet2_vtk_appended_raw_zlib_big_endian.vtu"};

TEST(MeshIoFixtures, VtkWrittenVtuInEveryLayout) {
  for (const char* name : kVtkLayouts) {
    SCOPED_TRACE(name);
    const TetMesh m = load_tet_mesh(fixture(name));
    EXPECT_EQ(m.nodes, kBinaryPoints);
    EXPECT_EQ(m.tets, kTwoTets);
    EXPECT_EQ(m.tet_tags, (std::vector<int32_t>{1, 3})) << "the cell array `region` of the two tetrahedra";
  }
}

/// The message of the InputError that reading `text` as a VTU throws ("" if it loads).
std::string vtu_error(const std::string& text) {
  std::istringstream in(text);
  try {
    read_vtu(in, "x.vtu");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(MeshIoErrors, VtuCorruptCompressedDataTruncatedAppendedDataAndBadOffsets) {
  std::ifstream f(fixture("tet2_vtk_appended_raw_zlib.vtu"), std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string good = ss.str();
  ASSERT_EQ(vtu_error(good), "");
  const size_t data = good.find('_', good.find("<AppendedData")) + 1;
  // The Points array's block: its offset attribute (VTK pads it with spaces).
  const size_t tag = good.find("Name=\"Points\"");
  const size_t off_attr = good.find("offset=\"", tag) + 8;
  const size_t points = data + std::stoul(good.substr(off_attr, good.find('"', off_attr) - off_attr));
  // Its header (UInt64: #blocks, block size, last size, one compressed size) is 32 bytes; byte
  // 40 lies in its zlib stream.
  std::string corrupt = good;
  corrupt[points + 40] = static_cast<char>(corrupt[points + 40] ^ 0x5a);
  EXPECT_NE(vtu_error(corrupt).find("does not inflate"), std::string::npos) << vtu_error(corrupt);
  for (size_t keep : {size_t{0}, size_t{10}, size_t{36}, size_t{60}}) {
    const std::string e = vtu_error(good.substr(0, points + keep));
    EXPECT_TRUE(e.find("too short") != std::string::npos || e.find("runs past") != std::string::npos ||
                e.find("truncated") != std::string::npos || e.find("beyond") != std::string::npos)
        << keep << ": " << e;
  }
  std::string far = good;
  far.replace(off_attr, good.find('"', off_attr) - off_attr, "99999999");
  EXPECT_NE(vtu_error(far).find("beyond the appended data"), std::string::npos) << vtu_error(far);
  std::string no_data = good.substr(0, good.find("<AppendedData")) + "</VTKFile>\n";
  EXPECT_NE(vtu_error(no_data).find("no <AppendedData>"), std::string::npos) << vtu_error(no_data);
}

TEST(MeshIoFixtures, StreamReadersKeepSourceAndExtensionIsCaseInsensitive) {
  std::ifstream in(fixture("tet2_v41.msh"));
  std::stringstream text;
  text << in.rdbuf();
  std::istringstream stream(text.str());
  EXPECT_EQ(read_gmsh(stream, "from memory").source, "from memory");
  const std::string upper = write_temp_file("UPPER.MSH", text.str());
  EXPECT_EQ(load_tet_mesh(upper).tets, kTwoTets);
}

TEST(MeshIoFixtures, WindowsLineEndings) {
  for (const char* name : {"tet2_v41.msh", "tet2_ascii.vtk", "tet2_v51.vtk"}) {
    std::ifstream in(fixture(name));
    std::string crlf;
    for (std::string line; std::getline(in, line);) crlf += line + "\r\n";
    const TetMesh m = load_tet_mesh(write_temp_file(std::string("crlf_") + name, crlf));
    EXPECT_EQ(m.nodes, kFivePoints) << name;
    EXPECT_EQ(m.tets, kTwoTets) << name;
  }
}

// ---------------------------------------------------------------------------------------------
// Legacy VTK BINARY, written byte by byte here
// ---------------------------------------------------------------------------------------------

/// Appends `v` big-endian, as legacy VTK BINARY files store every value.
template <class T>
void put_big_endian(std::string& out, T v) {
  auto bytes = std::bit_cast<std::array<char, sizeof(T)>>(v);
  if constexpr (std::endian::native == std::endian::little)
    std::reverse(bytes.begin(), bytes.end());
  out.append(bytes.data(), bytes.size());
}

std::string binary_vtk_classic() {
  std::string s =
      "# vtk DataFile Version 3.0\nbinary two tets\nBINARY\nDATASET UNSTRUCTURED_GRID\n";
  s += "POINTS 5 float\n";
  for (const Vec3& p : kBinaryPoints)
    for (double c : p) put_big_endian(s, static_cast<float>(c));
  s += "\nCELLS 3 14\n";
  for (int32_t v : {4, 0, 1, 2, 3, 3, 0, 1, 2, 4, 1, 2, 3, 4}) put_big_endian(s, v);
  s += "\nCELL_TYPES 3\n";
  for (int32_t v : {10, 5, 10}) put_big_endian(s, v);
  s += "\nPOINT_DATA 5\nSCALARS t float 1\nLOOKUP_TABLE default\n";
  for (float v : {1.f, 2.f, 3.f, 4.f, 5.f}) put_big_endian(s, v);
  return s;
}

TEST(MeshIoLegacyBinary, ClassicCellsLayout) {
  const TetMesh m = load_tet_mesh(write_temp_file("tet2_binary.vtk", binary_vtk_classic()));
  EXPECT_EQ(m.nodes, kBinaryPoints);
  EXPECT_EQ(m.tets, kTwoTets);
}

TEST(MeshIoLegacyBinary, Vtk51OffsetsAndConnectivityInt64DoublePoints) {
  std::string s =
      "# vtk DataFile Version 5.1\nbinary two tets\nBINARY\nDATASET UNSTRUCTURED_GRID\n";
  s += "POINTS 5 double\n";
  for (const Vec3& p : kBinaryPoints)
    for (double c : p) put_big_endian(s, c);
  s += "\nCELLS 4 11\nOFFSETS vtktypeint64\n";
  for (int64_t v : {0, 4, 7, 11}) put_big_endian(s, v);
  s += "\nCONNECTIVITY vtktypeint64\n";
  for (int64_t v : {0, 1, 2, 3, 0, 1, 2, 1, 2, 3, 4}) put_big_endian(s, v);
  s += "\nCELL_TYPES 3\n";
  for (int32_t v : {10, 5, 10}) put_big_endian(s, v);
  s += "\n";
  const TetMesh m = load_tet_mesh(write_temp_file("tet2_binary51.vtk", s));
  EXPECT_EQ(m.nodes, kBinaryPoints);
  EXPECT_EQ(m.tets, kTwoTets);
}

TEST(MeshIoLegacyBinary, TruncatedDataHasNoLineNumber) {
  std::string s = binary_vtk_classic();
  s.resize(s.find("CELLS 3 14\n") + 11 + 20);  // cut inside the 56-byte cell list
  const std::string path = write_temp_file("truncated_binary.vtk", s);
  expect_file_error(path, 0, "CELLS", {"truncated binary data", "56 bytes", "found 20 bytes"});
}

// ---------------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------------

TEST(MeshIoErrors, MissingFile) {
  expect_file_error(fixture("no_such_mesh.msh"), 0, "", {"cannot open file"});
}

TEST(MeshIoErrors, UnknownExtension) {
  expect_file_error(real_mesh("liver-smooth.obj"), 0, "",
                    {"unknown mesh file extension", "'.obj'"});
}

TEST(MeshIoErrors, GmshBadHeader) {
  expect_file_error(fixture("bad_header.msh"), 1, "$MeshFormat",
                    {"not a gmsh file", "'MeshFormat'"});
}

TEST(MeshIoErrors, GmshUnsupportedVersion) {
  expect_file_error(fixture("bad_version.msh"), 2, "$MeshFormat", {"unsupported gmsh version 3.0"});
  std::istringstream v40("$MeshFormat\n4 0 8\n$EndMeshFormat\n");
  expect_input_error([&] { read_gmsh(v40, "v40.msh"); }, "v40.msh", 2, "$MeshFormat",
                     {"unsupported gmsh version 4"});
}

TEST(MeshIoErrors, GmshBinary) {
  expect_file_error(fixture("bad_binary.msh"), 2, "$MeshFormat",
                    {"binary .msh not supported; save as ASCII"});
}

TEST(MeshIoErrors, GmshUnknownNodeTag) {
  expect_file_error(fixture("bad_unknown_tag.msh"), 14, "$Elements", {"unknown node tag 99"});
}

TEST(MeshIoErrors, GmshTruncatedNodes) {
  expect_file_error(fixture("bad_truncated_nodes.msh"), 10, "$Nodes",
                    {"truncated", "expected 5 nodes, found 4", "'$EndNodes'"});
}

TEST(MeshIoErrors, GmshTruncatedAtEndOfFile) {
  std::istringstream in("$NOD\n2\n1 0 0 0\n");
  expect_input_error([&] { read_gmsh(in, "cut.msh"); }, "cut.msh", 3, "$NOD",
                     {"truncated", "expected 2 nodes, found 1", "end of the file"});
}

TEST(MeshIoErrors, GmshWrongNodeCount) {
  expect_file_error(fixture("bad_node_count.msh"), 9, "$Nodes",
                    {"expected $EndNodes after 3 nodes", "'4 0 0 1'"});
}

TEST(MeshIoErrors, GmshNonNumericCoordinate) {
  expect_file_error(fixture("bad_nonnumeric.msh"), 5, "$NOD",
                    {"non-numeric y coordinate", "'1.0e0x'"});
}

TEST(MeshIoErrors, GmshUnknownElementType) {
  std::istringstream v22(
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"
      "$EndNodes\n$Elements\n2\n1 4 2 0 1 1 2 3 4\n2 999 2 0 1 1 2 3 4\n$EndElements\n");
  expect_input_error([&] { read_gmsh(v22, "u.msh"); }, "u.msh", 14, "$Elements",
                     {"unknown element type 999"});
  std::istringstream v10("$NOD\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$ENDNOD\n$ELM\n1\n"
                          "1 0 1 1 4 1 2 3 4\n$ENDELM\n");
  expect_input_error([&] { read_gmsh(v10, "u10.msh"); }, "u10.msh", 10, "$ELM",
                     {"unknown element type 0"});
}

TEST(MeshIoErrors, GmshQuadraticTetrahedra) {
  expect_file_error(fixture("bad_quadratic.msh"), 30, "$Elements",
                    {"quadratic tetrahedra (type 11) are not supported; re-mesh with -order 1"});
  // 2.x: the error points at the element's own line.
  std::istringstream v22(
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n1\n1 0 0 0\n$EndNodes\n$Elements\n1\n"
      "1 11 2 0 1 1 1 1 1 1 1 1 1 1 1\n$EndElements\n");
  expect_input_error([&] { read_gmsh(v22, "q.msh"); }, "q.msh", 10, "$Elements",
                     {"quadratic tetrahedra (type 11)"});
}

TEST(MeshIoErrors, GmshNoTetrahedra) {
  expect_file_error(fixture("bad_no_tets.msh"), 11, "$Elements",
                    {"no tetrahedra", "found 2 elements of other types"});
}

TEST(MeshIoErrors, Gmsh41BlockCountsMustAddUp) {
  std::istringstream in(
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 5 1 4\n3 1 0 4\n1\n2\n3\n4\n"
      "0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n");
  expect_input_error([&] { read_gmsh(in, "sum.msh"); }, "sum.msh", 5, "$Nodes",
                     {"header announces 5 nodes but the blocks hold 4"});
}

TEST(MeshIoErrors, VtkBadHeader) {
  expect_file_error(fixture("bad_header.vtk"), 1, "header", {"not a VTK file"});
}

TEST(MeshIoErrors, VtkTruncatedPoints) {
  expect_file_error(fixture("bad_truncated_points.vtk"), 8, "POINTS",
                    {"truncated", "expected 15 point coordinates, found 12", "'CELLS'"});
}

TEST(MeshIoErrors, VtkQuadraticTetrahedra) {
  expect_file_error(fixture("bad_quadratic.vtk"), 11, "CELL_TYPES",
                    {"quadratic tetrahedra (VTK cell type 24)"});
}

TEST(MeshIoErrors, VtkOtherDatasetTypes) {
  std::istringstream in("# vtk DataFile Version 3.0\nsurface\nASCII\nDATASET POLYDATA\n");
  expect_input_error([&] { read_vtk_legacy(in, "s.vtk"); }, "s.vtk", 4, "header",
                     {"dataset type 'POLYDATA' is not supported"});
}

TEST(MeshIoErrors, VtuPointCountMismatch) {
  expect_file_error(fixture("bad_count.vtu"), 7, "Points",
                    {"truncated", "expected 18 point coordinates", "found 15"});
}

TEST(MeshIoErrors, VtuIndexOutOfRange) {
  expect_file_error(fixture("bad_index.vtu"), 11, "connectivity",
                    {"cell 0 refers to point 7", "4 points"});
}

TEST(MeshIoErrors, VtuNotVtk) {
  std::istringstream in("<html><body>not a mesh</body></html>\n");
  expect_input_error([&] { read_vtu(in, "page.vtu"); }, "page.vtu", 0, "VTKFile",
                     {"not a VTK XML file"});
}

TEST(MeshIoErrors, VtuCompressedHeaderTruncatedAndUnknownCompressor) {
  const std::string text =
      "<VTKFile type=\"UnstructuredGrid\" compressor=\"vtkZLibDataCompressor\">\n"
      "<UnstructuredGrid><Piece NumberOfPoints=\"1\" NumberOfCells=\"0\">\n<Points>\n"
      "<DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"binary\">AAAA</DataArray>\n"
      "</Points></Piece></UnstructuredGrid></VTKFile>\n";
  std::istringstream in(text);
  expect_input_error([&] { read_vtu(in, "z.vtu"); }, "z.vtu", 4, "Points", {"compressed DataArray too short"});
  std::string lz4 = text;
  lz4.replace(lz4.find("vtkZLibDataCompressor"), 21, "vtkLZ4DataCompressor");
  std::istringstream in2(lz4);
  expect_input_error([&] { read_vtu(in2, "lz4.vtu"); }, "lz4.vtu", 1, "VTKFile",
                     {"compressor 'vtkLZ4DataCompressor' is not supported"});
}

}  // namespace
}  // namespace stroma

namespace stroma {
namespace {

// Non-finite coordinates: refused by every reader, with the line where there is one (they used
// to load and fail later, without a line).
TEST(MeshIoErrors, NonFiniteCoordinatesAreRefusedWhereTheyAreRead) {
  const std::string gmsh =
      "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 nan 0\n4 0 0 1\n$EndNodes\n"
      "$Elements\n1\n1 4 0 1 2 3 4\n$EndElements\n";
  const std::string gpath = write_temp_file("nan.msh", gmsh);
  expect_file_error(gpath, 8, "$Nodes", {"non-finite", "'nan'"});
  const std::string vtk =
      "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0 1 0 0\n0 1 0 0 0 inf\n"
      "CELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n";
  const std::string vpath = write_temp_file("inf.vtk", vtk);
  expect_file_error(vpath, 7, "POINTS", {"non-finite", "'inf'"});
  // Binary data has no line: the point is named instead.
  std::string bin = "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n";
  for (double c : {0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0, 0.0, 1.0}) put_big_endian(bin, c);
  bin += "\nCELLS 1 5\n";
  for (int32_t v : {4, 0, 1, 2, 3}) put_big_endian(bin, v);
  bin += "\nCELL_TYPES 1\n";
  put_big_endian(bin, int32_t{10});
  bin += "\n";
  const std::string bpath = write_temp_file("nan_binary.vtk", bin);
  expect_file_error(bpath, 0, "points", {"point 2", "non-finite"});
}

// Binary junk in an error is escaped and capped, never echoed raw.
TEST(MeshIoErrors, QuotedFileTextIsEscapedAndCapped) {
  std::string junk = "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 1 double\n";
  junk += std::string("\x01\x02\xff") + std::string(100000, 'z') + "\n";
  try {
    load_tet_mesh(write_temp_file("junk.vtk", junk));
    ADD_FAILURE() << "accepted junk";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("\\x01\\x02\\xff"), std::string::npos) << what;
    EXPECT_LT(what.size(), 400u) << what;
    for (char c : what) EXPECT_TRUE(c == '\n' || (c >= 0x20 && c < 0x7f)) << "raw byte in: " << what;
  }
}

// Inputs the fuzzer found (tests/fuzz/corpus/tet_mesh/regress_*): a count or last offset the
// data cannot hold must be an InputError, never a std::length_error (which aborted the fuzz
// target: "deadly signal") nor a multi-gigabyte allocation.
TEST(MeshIo, FuzzFoundHugeCountsAreInputErrors) {
  const std::string dir = std::string(STROMA_SOURCE_DIR) + "/tests/fuzz/corpus/tet_mesh/";
  for (const char* name : {"regress_vtu_huge_offset.vtu", "regress_vtk_huge_cell_count.vtk"}) {
    std::ifstream f(dir + name, std::ios::binary);
    ASSERT_TRUE(f) << name;
    std::stringstream text;
    text << f.rdbuf();
    std::istringstream in(text.str());
    const bool vtu = std::string(name).ends_with(".vtu");
    EXPECT_THROW(vtu ? read_vtu(in, name) : read_vtk_legacy(in, name), InputError) << name;
  }
}

}  // namespace
}  // namespace stroma
