// libFuzzer target: reference states (`stroma check SCENARIO REF.csv`, final_state.csv).
#include "fuzz_input.hpp"
#include "runtime/state_io.hpp"
#include "tissue/input_error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = stroma::fuzz::write_input(data, size, ".csv");
  try {
    stroma::read_state_csv(path);
  } catch (const stroma::InputError&) {
  }
  return 0;
}
