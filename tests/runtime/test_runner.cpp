// The headless runner's outputs: summary.json, metrics.csv, final.vtu, series.pvd,
// final_state.csv — their contents agree with the state the run ended in.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "io/mesh_io.hpp"
#include "runtime/headless_runner.hpp"
#include "runtime/state_io.hpp"
#include "tissue/input_error.hpp"

using namespace stroma;
namespace fs = std::filesystem;

namespace {
std::string read_all(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}
}  // namespace

TEST(Runner, WritesConsistentOutputs) {
  const fs::path dir = fs::temp_directory_path() / "stroma_runner_test";
  fs::remove_all(dir);
  // The liver without tools: the collide stage must cost exactly nothing.
  const CompiledScenario sc_m = compile_scenario(load_scenario(std::string(STROMA_SOURCE_DIR) + "/scenarios/regression/liver_damped.yaml"));
  const auto& m = sc_m.model;
  RunOptions o;
  o.steps = 20;
  o.out_dir = dir.string();
  o.vtu_every = 10;
  o.progress = false;
  const RunResult r = run_headless(sc_m, o);
  EXPECT_EQ(r.steps, 20);
  EXPECT_NEAR(r.sim_time, 20 * m->time_step, 1e-15);

  const auto j = nlohmann::json::parse(read_all(dir / "summary.json"));
  EXPECT_EQ(j["steps"], 20);
  EXPECT_NEAR(j["sim_time"].get<double>(), 0.02, 1e-15);
  EXPECT_GT(j["wall_seconds"].get<double>(), 0.0);
  for (const char* k : {"p50", "p99", "max"}) EXPECT_GT(j["step_ms"][k].get<double>(), 0.0) << k;
  EXPECT_LE(j["step_ms"]["p50"].get<double>(), j["step_ms"]["max"].get<double>());
  EXPECT_GE(j["cg_iterations"]["max"].get<int>(), 1);
  EXPECT_GT(j["stages"]["assemble"]["total_ms"].get<double>(), 0.0);
  EXPECT_EQ(j["stages"]["collide"]["total_ms"].get<double>(), 0.0);  // no tool: no collision work
  const Vec3 d = probe_displacement(*m, r.final_state, m->probes[0]);
  for (int k = 0; k < 3; ++k)
    EXPECT_DOUBLE_EQ(j["probes"]["lobe"]["displacement"][k].get<double>(), d[k]);

  // metrics.csv: header + one row per tick; last row's probe columns = final displacement.
  std::ifstream csv(dir / "metrics.csv");
  std::string header, line, last;
  std::getline(csv, header);
  EXPECT_EQ(header.rfind("step,time,step_ms,cg_iterations,cg_residual,kinetic_energy,elastic_energy", 0), 0u);
  EXPECT_NE(header.find("lobe_dx,lobe_dy,lobe_dz"), std::string::npos);
  int rows = 0;
  while (std::getline(csv, line))
    if (!line.empty()) {
      ++rows;
      last = line;
    }
  EXPECT_EQ(rows, 20);
  auto column = [](const std::string& line, int idx) {
    std::stringstream ss(line);
    std::string cell;
    for (int i = 0; i <= idx; ++i) std::getline(ss, cell, ',');
    return cell;
  };
  int dz_col = -1, col = 0;
  {
    std::stringstream hs(header);
    std::string name;
    while (std::getline(hs, name, ',')) {
      if (name == "lobe_dz") dz_col = col;
      ++col;
    }
  }
  ASSERT_GE(dz_col, 0);
  const double last_dz = std::stod(column(last, dz_col));
  EXPECT_NEAR(last_dz, d[2], 1e-12 * (1 + std::fabs(d[2])));

  // final.vtu read back with the engine's own VTU reader: deformed positions, same tets.
  const TetMesh back = load_tet_mesh((dir / "final.vtu").string());
  ASSERT_EQ(back.nodes.size(), static_cast<size_t>(m->fem.num_nodes));
  EXPECT_EQ(back.tets.size(), m->fem.elements.size());
  double worst = 0;
  for (size_t i = 0; i < back.nodes.size(); ++i)
    for (int k = 0; k < 3; ++k)
      worst = std::max(worst, std::fabs(back.nodes[i][k] - r.final_state.tissue.x[3 * i + k]));
  EXPECT_LT(worst, 1e-10);

  // final_state.csv round-trips exactly; the series has frames 0, 10, 20.
  EXPECT_EQ(read_state_csv((dir / "final_state.csv").string()), r.final_state.tissue.x);
  const std::string pvd = read_all(dir / "series.pvd");
  for (const char* f : {"state_000000.vtu", "state_000010.vtu", "state_000020.vtu"}) {
    EXPECT_NE(pvd.find(f), std::string::npos) << f;
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  }
  fs::remove_all(dir);
}

TEST(Runner, StateCsvErrorsNameFileAndLine) {
  const fs::path p = fs::temp_directory_path() / "stroma_bad_state.csv";
  std::ofstream(p) << "node,x,y,z\n0,1,2,3\n1,4,five,6\n";
  try {
    read_state_csv(p.string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.field(), "y");
    EXPECT_NE(std::string(e.what()).find("stroma_bad_state.csv:3"), std::string::npos) << e.what();
  }
  // A reference written on Windows (CRLF) reads like the original, and a NaN is refused with
  // its field (a CRLF file was refused quoting a line that looked valid).
  std::ofstream(p, std::ios::binary) << "node,x,y,z\r\n0,1,2,3\r\n1,4,5,6\r\n";
  EXPECT_EQ(read_state_csv(p.string()), (std::vector<double>{1, 2, 3, 4, 5, 6}));
  std::ofstream(p, std::ios::binary) << "node,x,y,z\n0,1,2,3\n1,4,5,nan\n";
  try {
    read_state_csv(p.string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.field(), "z");
  }
  fs::remove(p);
}
