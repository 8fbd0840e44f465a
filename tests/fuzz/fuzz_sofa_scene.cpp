// libFuzzer target: the SOFA-scene importer — XML parse, translation (every refusal must be an
// InputError), then the translated scenario's parse and compile. Relative mesh paths resolve
// against scenarios/sofa/ (STROMA_SOURCE_DIR), so the seeds are the shipped scenes.

#include "scene/compiled_scenario.hpp"
#include "scene/scenario_spec.hpp"
#include "scene/sofa_scene.hpp"
#include "tissue/input_error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const std::string dir = STROMA_SOURCE_DIR "/scenarios/sofa";
  try {
    const stroma::SofaTranslation t = stroma::translate_sofa_scene(text, dir + "/fuzz.scn", dir);
    const stroma::ScenarioSpec spec = stroma::parse_scenario(t.yaml, "fuzz.scn (translated)", dir);
    stroma::compile_scenario(spec);
  } catch (const stroma::InputError&) {
  }
  return 0;
}
