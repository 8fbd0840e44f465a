#pragma once
/// \file gl.hpp
/// OpenGL declarations for render/: core-profile entry points are exported by libOSMesa itself,
/// so prototypes are enough (no loader). Include this, never <GL/gl.h> directly.
#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/gl.h>
#include <GL/glext.h>
