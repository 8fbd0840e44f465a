#include "runtime/state_io.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string_view>
#include <stdexcept>

#include <fmt/format.h>

#include "io/text_scan.hpp"
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
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, "", "cannot open reference state file");
  static const char* const kFields[] = {"node", "x", "y", "z"};
  std::string line;
  int ln = 0;
  std::vector<double> x;
  while (std::getline(in, line)) {
    ++ln;
    if (!line.empty() && line.back() == '\r') line.pop_back();  // written on Windows
    if (ln == 1) {
      if (line != "node,x,y,z")
        throw InputError(path, 1, "header", fmt::format("expected 'node,x,y,z', got '{}'", text::clip(line)));
      continue;
    }
    if (line.empty()) continue;
    std::vector<std::string_view> cells;
    for (size_t b = 0;;) {
      const size_t e = line.find(',', b);
      cells.push_back(std::string_view(line).substr(b, e == std::string::npos ? std::string::npos : e - b));
      if (e == std::string::npos) break;
      b = e + 1;
    }
    if (cells.size() != 4)
      throw InputError(path, ln, "", fmt::format("expected 4 values 'node,x,y,z', got {} in '{}'", cells.size(),
                                                 text::clip(line)));
    int64_t node = 0;
    if (!text::parse_number(cells[0], node))
      throw InputError(path, ln, "node", fmt::format("'{}' is not an integer", text::clip(cells[0])));
    if (node != static_cast<int64_t>(x.size() / 3))
      throw InputError(path, ln, "node", fmt::format("expected node {}, got {}", x.size() / 3, node));
    for (int k = 1; k < 4; ++k) {
      double v = 0;
      if (!text::parse_number(cells[k], v))
        throw InputError(path, ln, kFields[k], fmt::format("'{}' is not a number", text::clip(cells[k])));
      if (!std::isfinite(v)) throw InputError(path, ln, kFields[k], fmt::format("'{}' is not finite", text::clip(cells[k])));
      x.push_back(v);
    }
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
