// libFuzzer target: a snapshot's bytes (engine/state_bytes; Python unpickles them) — decoding
// untrusted bytes must end in a State or an InputError, never a crash or a huge allocation;
// a decoded state re-encodes to the same bytes.

#include <cstdlib>

#include "engine/state_bytes.hpp"
#include "tissue/input_error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  try {
    uint64_t fp = 0;
    const stroma::State s = stroma::decode_state(bytes, &fp);
    if (stroma::encode_state(s, fp) != bytes) std::abort();  // the format has one encoding per state
  } catch (const stroma::InputError&) {
  }
  return 0;
}
