#include "engine/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "tissue/input_error.hpp"
#include "io/text_scan.hpp"

namespace stroma {

namespace {

std::array<double, 4> slerp(std::array<double, 4> a, std::array<double, 4> b, double u) {
  double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
  if (d < 0) {  // shortest arc
    for (double& v : b) v = -v;
    d = -d;
  }
  std::array<double, 4> r;
  if (d > 0.9995) {  // nearly parallel: normalised lerp
    for (int k = 0; k < 4; ++k) r[k] = a[k] + u * (b[k] - a[k]);
  } else {
    const double th = std::acos(d), s = std::sin(th);
    const double wa = std::sin((1 - u) * th) / s, wb = std::sin(u * th) / s;
    for (int k = 0; k < 4; ++k) r[k] = wa * a[k] + wb * b[k];
  }
  const double n = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
  for (double& v : r) v /= n;
  return r;
}

void check_keys(const Trajectory& tr, const std::vector<int>& lines, const std::string& src) {
  if (tr.keys.empty()) throw InputError(src, 0, "keyframes", "trajectory has no keyframes");
  for (size_t i = 0; i < tr.keys.size(); ++i) {
    const Keyframe& k = tr.keys[i];
    // YAML reads .nan and .inf as numbers: refuse them here, field by field.
    auto finite = [&](const char* field, std::initializer_list<double> values) {
      for (double v : values)
        if (!std::isfinite(v)) throw InputError(src, lines[i], field, fmt::format("{} is not finite", v));
    };
    finite("t", {k.t});
    finite("position", {k.pose.position[0], k.pose.position[1], k.pose.position[2]});
    finite("orientation", {k.pose.orientation[0], k.pose.orientation[1], k.pose.orientation[2], k.pose.orientation[3]});
    finite("jaw", {k.pose.jaw});
    const auto& q = k.pose.orientation;
    const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(std::fabs(n - 1) <= 1e-3))
      throw InputError(src, lines[i], "orientation",
                       fmt::format("|q| = {:.6g} is not a unit quaternion (w, x, y, z)", n));
    if (i > 0 && !(tr.keys[i].t > tr.keys[i - 1].t))
      throw InputError(src, lines[i], "t",
                       fmt::format("time {} does not increase (previous keyframe: {})",
                                   tr.keys[i].t, tr.keys[i - 1].t));
  }
}

}  // namespace

ToolPose Trajectory::sample(double t) const {
  if (t <= keys.front().t) return keys.front().pose;
  if (t >= keys.back().t) return keys.back().pose;
  const auto it = std::upper_bound(keys.begin(), keys.end(), t,
                                   [](double v, const Keyframe& k) { return v < k.t; });
  const Keyframe& b = *it;
  const Keyframe& a = *(it - 1);
  return interpolate_pose(a.pose, b.pose, (t - a.t) / (b.t - a.t));
}

ToolPose interpolate_pose(const ToolPose& a, const ToolPose& b, double u) {
  ToolPose p;
  for (int k = 0; k < 3; ++k) p.position[k] = a.position[k] + u * (b.position[k] - a.position[k]);
  p.orientation = slerp(a.orientation, b.orientation, u);
  p.jaw = a.jaw + u * (b.jaw - a.jaw);
  p.buttons = a.buttons;
  return p;
}

Trajectory parse_trajectory_csv(const std::string& text, const std::string& src) {
  std::istringstream in(text);
  std::string line;
  int ln = 0;
  std::map<std::string, int> col;
  Trajectory tr;
  std::vector<int> lines;
  while (std::getline(in, line)) {
    ++ln;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) {
      c.erase(0, c.find_first_not_of(" \t"));
      c.erase(c.find_last_not_of(" \t") + 1);
      cells.push_back(c);
    }
    if (col.empty()) {
      for (size_t i = 0; i < cells.size(); ++i) col[cells[i]] = static_cast<int>(i);
      for (const char* req : {"t", "x", "y", "z"})
        if (!col.count(req))
          throw InputError(src, ln, "header", fmt::format("missing column '{}' (need t,x,y,z; optional qw,qx,qy,qz,jaw,buttons)", req));
      for (const auto& [name, i] : col)
        if (name != "t" && name != "x" && name != "y" && name != "z" && name != "qw" && name != "qx" &&
            name != "qy" && name != "qz" && name != "jaw" && name != "buttons")
          throw InputError(src, ln, "header", fmt::format("unknown column '{}'", name));
      continue;
    }
    auto num = [&](const char* name, double def) {
      const auto it = col.find(name);
      if (it == col.end()) return def;
      if (it->second >= static_cast<int>(cells.size()))
        throw InputError(src, ln, name, fmt::format("row has {} values, column '{}' is missing", cells.size(), name));
      const std::string& s = cells[it->second];
      char* end = nullptr;
      const double v = std::strtod(s.c_str(), &end);
      if (s.empty() || *end != '\0' || !std::isfinite(v))
        throw InputError(src, ln, name, fmt::format("expected a finite number, got '{}'", text::clip(s)));
      return v;
    };
    Keyframe k;
    k.t = num("t", 0);
    k.pose.position = {num("x", 0), num("y", 0), num("z", 0)};
    k.pose.orientation = {num("qw", 1), num("qx", 0), num("qy", 0), num("qz", 0)};
    k.pose.jaw = num("jaw", 0);
    const double buttons = num("buttons", 0);
    if (!(buttons >= 0 && buttons <= 4294967295.0 && buttons == std::floor(buttons)))
      throw InputError(src, ln, "buttons", fmt::format("{} is not a button mask (an integer in [0, 2^32))", buttons));
    k.pose.buttons = static_cast<uint32_t>(buttons);
    tr.keys.push_back(k);
    lines.push_back(ln);
  }
  check_keys(tr, lines, src);
  return tr;
}

Trajectory load_trajectory(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw InputError(path, 0, "", "cannot open trajectory file");
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string text = ss.str();
  const bool csv = path.size() >= 4 && path.compare(path.size() - 4, 4, ".csv") == 0;
  if (csv) return parse_trajectory_csv(text, path);

  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(path, e.mark.line + 1, "", "YAML syntax error: " + e.msg);
  }
  Trajectory tr;
  std::vector<int> lines;
  try {  // anything yaml-cpp still throws (a node of an unexpected kind) is a bad input too
    if (!root.IsMap())
      throw InputError(path, 1, "", "expected a map 'keyframes: [{t, position, orientation, jaw}, ...]'");
    const YAML::Node keys = root["keyframes"];
    if (!keys || !keys.IsSequence())
      throw InputError(path, 1, "keyframes", "expected a list 'keyframes: [{t, position, orientation, jaw}, ...]'");
    for (size_t i = 0; i < keys.size(); ++i) {
      const YAML::Node k = keys[i];
      const int ln = k.Mark().line + 1;
      const std::string field = fmt::format("keyframes[{}]", i);
      if (!k.IsMap()) throw InputError(path, ln, field, "expected a map {t, position, ...}");
      for (const auto& kv : k) {
        if (!kv.first.IsScalar())
          throw InputError(path, kv.first.Mark().line + 1, field, "expected a key name, got a list or map");
        const std::string key = kv.first.Scalar();
        if (key != "t" && key != "position" && key != "orientation" && key != "jaw" && key != "buttons")
          throw InputError(path, kv.first.Mark().line + 1, field + "." + key,
                           "unknown key (allowed: t, position, orientation, jaw, buttons)");
      }
      Keyframe kf;
      try {
        if (!k["t"] || !k["position"]) throw InputError(path, ln, field, "needs 't' and 'position'");
        kf.t = k["t"].as<double>();
        const auto p = k["position"].as<std::vector<double>>();
        if (p.size() != 3) throw InputError(path, ln, field + ".position", "expected 3 numbers");
        kf.pose.position = {p[0], p[1], p[2]};
        if (k["orientation"]) {
          const auto q = k["orientation"].as<std::vector<double>>();
          if (q.size() != 4) throw InputError(path, ln, field + ".orientation", "expected 4 numbers (w, x, y, z)");
          kf.pose.orientation = {q[0], q[1], q[2], q[3]};
        }
        if (k["jaw"]) kf.pose.jaw = k["jaw"].as<double>();
        if (k["buttons"]) kf.pose.buttons = k["buttons"].as<uint32_t>();
      } catch (const YAML::Exception& e) {
        throw InputError(path, ln, field, "expected numbers: " + e.msg);
      }
      tr.keys.push_back(kf);
      lines.push_back(ln);
    }
  } catch (const YAML::Exception& e) {
    throw InputError(path, e.mark.line + 1, "", "unexpected YAML: " + e.msg);
  }
  check_keys(tr, lines, path);
  return tr;
}

}  // namespace stroma
