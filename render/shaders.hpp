#pragma once
/// \file shaders.hpp
/// GLSL 3.30 core sources of the renderer. Lighting is done in linear colour and encoded to
/// sRGB at the end (so highlights and falloff look right on screen).

namespace stroma::render {

/// Tissue and tool surfaces: world-space position, normal, and three fields (stress, damage,
/// cut: 1 on the faces a cut made, −1 at the lips' vertices of the outer surface).
inline constexpr const char* kMeshVertexShader = R"(#version 330 core
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec3 a_field;
uniform mat4 u_view_proj;
out vec3 v_pos;
out vec3 v_normal;
out vec3 v_field;
void main() {
  v_pos = a_pos;
  v_normal = a_normal;
  v_field = a_field;
  gl_Position = u_view_proj * vec4(a_pos, 1.0);
}
)";

/// Blinn–Phong with a key light, a fill light, hemisphere ambient and a rim term; two-sided
/// (inner faces exposed by a cut are lit too); u_field 1 = stress colour map over the tissue
/// colour, 2 = damage darkening towards a bruise, then a dark wound colour at rupture.
inline constexpr const char* kMeshFragmentShader = R"(#version 330 core
in vec3 v_pos;
in vec3 v_normal;
in vec3 v_field;
uniform vec3 u_eye;
uniform vec3 u_key_dir;
uniform vec3 u_fill_dir;
uniform vec3 u_sky;
uniform vec3 u_base;
uniform vec3 u_cut;
uniform int u_field;
uniform vec2 u_range;
uniform float u_shininess;
uniform float u_specular;
uniform int u_wire;
out vec4 o_color;

// Stress colour map: blue → cyan → green → yellow → red, piecewise linear in sRGB.
vec3 ramp(float t) {
  vec3 c[5] = vec3[5](vec3(0.15, 0.25, 0.85), vec3(0.10, 0.75, 0.90), vec3(0.20, 0.80, 0.25),
                      vec3(0.98, 0.85, 0.15), vec3(0.90, 0.12, 0.08));
  float x = clamp(t, 0.0, 1.0) * 4.0;
  int i = min(int(x), 3);
  return pow(mix(c[i], c[i + 1], x - float(i)), vec3(2.2));
}

void main() {
  if (u_wire == 1) {
    o_color = vec4(0.02, 0.02, 0.03, 1.0);
    return;
  }
  vec3 n = normalize(v_normal);
  vec3 V = normalize(u_eye - v_pos);
  if (!gl_FrontFacing) n = -n;
  vec3 base = u_base;
  if (u_field == 1) {
    float t = clamp((v_field.x - u_range.x) / max(u_range.y - u_range.x, 1e-12), 0.0, 1.0);
    base = mix(base, ramp(t), 0.85);
  } else if (u_field == 2) {
    float d = clamp(v_field.y, 0.0, 1.0);
    vec3 bruise = vec3(0.09, 0.012, 0.035);
    vec3 wound = vec3(0.015, 0.002, 0.004);
    base = mix(base, bruise, smoothstep(0.0, 0.9, d));
    base = mix(base, wound, smoothstep(0.9, 1.0, d));
  }
  base = mix(base, u_cut, clamp(v_field.z, 0.0, 1.0));  // a cut's inner faces
  // The wound's edge on the outer surface (−1 at the lips' vertices): a dark line along the cut,
  // the last fifth of the way to the lip of each face that touches it.
  base = mix(base, 0.45 * u_cut, smoothstep(0.7, 0.95, -v_field.z));
  vec3 L = -u_key_dir;
  vec3 H = normalize(L + V);
  float key = max(dot(n, L), 0.0);
  float fill = max(dot(n, -u_fill_dir), 0.0);
  float hemi = 0.5 + 0.5 * dot(n, u_sky);
  float spec = key > 0.0 ? pow(max(dot(n, H), 0.0), u_shininess) * u_specular : 0.0;
  float rim = pow(1.0 - max(dot(n, V), 0.0), 3.0) * 0.12;
  vec3 c = base * (0.95 * key + 0.25 * fill + mix(0.05, 0.16, hemi)) + vec3(spec) + rim * vec3(0.9, 0.95, 1.0);
  o_color = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
}
)";

/// A full-screen triangle with a vertical gradient (no vertex buffer).
inline constexpr const char* kBackgroundVertexShader = R"(#version 330 core
out float v_y;
void main() {
  vec2 p = vec2((gl_VertexID == 1) ? 3.0 : -1.0, (gl_VertexID == 2) ? 3.0 : -1.0);
  v_y = 0.5 * (p.y + 1.0);
  gl_Position = vec4(p, 0.0, 1.0);
}
)";

inline constexpr const char* kBackgroundFragmentShader = R"(#version 330 core
in float v_y;
uniform vec3 u_top;
uniform vec3 u_bottom;
out vec4 o_color;
void main() { o_color = vec4(mix(u_bottom, u_top, clamp(v_y, 0.0, 1.0)), 1.0); }
)";

/// Contact markers: round, outlined points of a fixed size in pixels.
inline constexpr const char* kMarkerVertexShader = R"(#version 330 core
layout(location = 0) in vec3 a_pos;
uniform mat4 u_view_proj;
uniform float u_size;
void main() {
  gl_Position = u_view_proj * vec4(a_pos, 1.0);
  gl_Position.z -= 0.002 * gl_Position.w;  // pull towards the camera: drawn on the surface
  gl_PointSize = u_size;
}
)";

inline constexpr const char* kMarkerFragmentShader = R"(#version 330 core
uniform vec3 u_color;
out vec4 o_color;
void main() {
  vec2 d = 2.0 * gl_PointCoord - 1.0;
  float r2 = dot(d, d);
  if (r2 > 1.0) discard;
  o_color = vec4(r2 > 0.55 ? vec3(0.1, 0.08, 0.0) : u_color, 1.0);
}
)";

}  // namespace stroma::render
