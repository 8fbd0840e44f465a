// libFuzzer target: tool trajectories, YAML and CSV, then sampled across their time span as a
// headless run and `stroma tool --script` do. First byte: even YAML, odd CSV.
#include <cmath>

#include "engine/trajectory.hpp"
#include "fuzz_input.hpp"
#include "tissue/input_error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string path = stroma::fuzz::write_input(data + 1, size - 1, data[0] % 2 ? ".csv" : ".yaml");
  try {
    const stroma::Trajectory tr = stroma::load_trajectory(path);
    const double t0 = tr.keys.front().t, t1 = tr.keys.back().t;
    for (int i = 0; i <= 16; ++i) {
      const stroma::ToolPose p = tr.sample(t0 + (t1 - t0) * i / 16.0);
      for (double v : p.position)
        if (!std::isfinite(v)) __builtin_trap();  // a loaded trajectory samples to finite poses
    }
  } catch (const stroma::InputError&) {
  }
  return 0;
}
