/// \file bullet_main.cpp
/// stroma_bench_bullet: Bullet Physics 3.24 as a peer on Stroma's reference problems, on the
/// same meshes (see bullet_cantilever.cpp, bullet_block.cpp, bullet_indentation.cpp for each
/// problem's fairness choices). `stroma bench accuracy --peers` runs it and merges its CSVs.

#include "bullet_problems.hpp"

#include <cstdio>
#include <string>

namespace {

constexpr const char* kUsage =
    "usage: stroma_bench_bullet [A|B] [--problem cantilever|block|indentation|all] [--quick] [--out DIR]\n"
    "  A / B      only peer A (Bullet's FEM, btDeformableMultiBodyDynamicsWorld) or B (classic btSoftBody;\n"
    "             cantilever only: it has no material law and no force to measure on block/indentation)\n"
    "  --problem  which problem (default all)\n"
    "  --quick    indentation: the two coarser contact gradings only\n"
    "  --out DIR  writes DIR/bullet_<problem>.csv (default out/bench/peers)\n";

}  // namespace

int main(int argc, char** argv) {
  const std::string root = STROMA_SOURCE_DIR;
  bool run_a = true, run_b = true, quick = false;
  std::string problem = "all", out = root + "/out/bench/peers";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "A") run_b = false;
    else if (a == "B") run_a = false;
    else if (a == "--quick") quick = true;
    else if (a == "--out" && i + 1 < argc) out = argv[++i];
    else if (a == "--problem" && i + 1 < argc) problem = argv[++i];
    else if (a == "--help" || a == "-h") {
      std::printf("%s", kUsage);
      return 0;
    } else {
      std::fprintf(stderr, "%s", kUsage);
      return 2;
    }
  }
  if (problem != "all" && problem != "cantilever" && problem != "block" && problem != "indentation") {
    std::fprintf(stderr, "%s", kUsage);
    return 2;
  }
  std::printf("btScalar is %zu bytes\n", sizeof(btScalar));
  auto finish = [&](const peers::Table& t) {
    t.print();
    t.write(out);  // after each problem, so a later failure keeps the earlier CSVs
  };
  if (problem == "all" || problem == "cantilever") finish(peers::run_cantilever(root, run_a, run_b));
  // Block and indentation: peer A only. B has no material law and no force to measure (its
  // links are position projections), so there is no top or indenter force to compare.
  if (run_a && (problem == "all" || problem == "block")) finish(peers::run_block(root));
  if (run_a && (problem == "all" || problem == "indentation")) finish(peers::run_indentation(out, quick));
  return 0;
}
