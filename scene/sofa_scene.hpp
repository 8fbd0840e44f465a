#pragma once
/// \file sofa_scene.hpp
/// SOFA scenes (.scn, SOFA's XML scene format) as Stroma scenarios: the subset of SOFA's
/// components that describes what Stroma simulates is translated to scenario YAML, which the
/// ordinary loader then validates and compiles (docs/SOFA.md lists the components, attributes
/// and how each maps). Anything outside the subset — an unknown component, an attribute the
/// translation does not carry, a value Stroma would have to approximate — is an InputError
/// naming the scene file, the line, the component and attribute, and what is wrong: a scene is
/// translated exactly or refused, never approximated.

#include <string>
#include <vector>

namespace stroma {

/// The translation of one scene: scenario YAML (with comments citing the scene's lines, printed
/// by `stroma run --explain`) and what the translation decided that a reader should know
/// (defaults SOFA would take, components with no effect on the simulation).
struct SofaTranslation {
  std::string yaml;
  std::vector<std::string> notes;
};

/// Translates the scene in `xml` (read from `file`, which messages name; relative mesh paths
/// resolve against `base_dir`). Throws InputError(file, line, "Component.attribute", what).
SofaTranslation translate_sofa_scene(const std::string& xml, const std::string& file, const std::string& base_dir);

/// Reads and translates a .scn file (InputError when it cannot be read).
SofaTranslation translate_sofa_scene_file(const std::string& path);

/// Whether `path` names a SOFA scene (extension .scn, any case): load_scenario translates those.
bool is_sofa_scene_path(const std::string& path);

}  // namespace stroma
