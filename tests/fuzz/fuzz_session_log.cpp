// libFuzzer target: session logs (`stroma serve --record`, `stroma run --replay`), checked
// against a scenario with one tool as the replay does.
#include "fuzz_input.hpp"
#include "runtime/session_log.hpp"
#include "tissue/input_error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = stroma::fuzz::write_input(data, size, ".log");
  try {
    stroma::read_session_log(path, 1);
  } catch (const stroma::InputError&) {
  }
  return 0;
}
