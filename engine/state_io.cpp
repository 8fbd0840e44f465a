#include "engine/state_io.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include "tissue/input_error.hpp"

namespace stroma {

void write_state_csv(const std::string& path, const State& s) {
  std::string out = "node,x,y,z\n";
  const size_t n = s.tissue.x.size() / 3;
  for (size_t i = 0; i < n; ++i)
    out += fmt::format("{},{:.17g},{:.17g},{:.17g}\n", i, s.tissue.x[3 * i], s.tissue.x[3 * i + 1],
                       s.tissue.x[3 * i + 2]);
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error(fmt::format("cannot write '{}'", path));
  const bool ok = std::fwrite(out.data(), 1, out.size(), f) == out.size();
  std::fclose(f);
  if (!ok) throw std::runtime_error(fmt::format("cannot write '{}'", path));
}

std::vector<double> read_state_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "", "cannot open reference state file");
  std::string line;
  int ln = 0;
  std::vector<double> x;
  while (std::getline(in, line)) {
    ++ln;
    if (ln == 1) {
      if (line.rfind("node,x,y,z", 0) != 0)
        throw InputError(path, 1, "header", "expected 'node,x,y,z'");
      continue;
    }
    if (line.empty()) continue;
    long node;
    double a, b, c;
    char tail;
    if (std::sscanf(line.c_str(), "%ld,%lf,%lf,%lf%c", &node, &a, &b, &c, &tail) != 4)
      throw InputError(path, ln, "", fmt::format("expected 'node,x,y,z', got '{}'", line));
    if (node != static_cast<long>(x.size() / 3))
      throw InputError(path, ln, "node", fmt::format("expected node {}, got {}", x.size() / 3, node));
    x.insert(x.end(), {a, b, c});
  }
  if (x.empty()) throw InputError(path, ln, "", "reference state has no nodes");
  return x;
}

StateDifference compare_positions(const std::vector<double>& a, const std::vector<double>& b) {
  StateDifference d;
  const size_t n = std::min(a.size(), b.size()) / 3;
  double sum = 0;
  for (size_t i = 0; i < n; ++i) {
    const double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
    const double e = std::sqrt(dx * dx + dy * dy + dz * dz);
    sum += e;
    if (!(e <= d.max_error)) {  // also catches NaN
      d.max_error = std::isnan(e) ? INFINITY : e;
      d.worst_node = static_cast<int32_t>(i);
    }
  }
  d.mean_error = n ? sum / static_cast<double>(n) : 0.0;
  return d;
}

}  // namespace stroma
