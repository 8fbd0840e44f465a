#pragma once
/// \file bullet_problems.hpp
/// The problems of the Bullet peer benchmark; each returns its table of result rows.

#include "bullet_common.hpp"

#include <string>

namespace peers {

/// Cantilever (refs/a static deflection, refs/d first frequency); peers A and/or B.
Table run_cantilever(const std::string& root, bool run_a, bool run_b);

/// Bonded block, nu = 0.49, pressed 1 % (refs/c): top force; peer A only (see the file).
Table run_block(const std::string& root);

/// Sphere indentation (refs/e) on the mirrored quarter block, peer A only; `quick`: the two
/// coarser contact gradings. The generated mesh goes to work_dir.
Table run_indentation(const std::string& work_dir, bool quick);

}  // namespace peers
