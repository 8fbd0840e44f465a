#include "render/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <unordered_set>
#include <vector>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "render/capsule_mesh.hpp"
#include "render/gl.hpp"
#include "render/shaders.hpp"

namespace stroma::render {

namespace {

using Eigen::Matrix4f;
using Eigen::Vector3f;

Vector3f v3(const Vec3f& a) { return {a[0], a[1], a[2]}; }

/// sRGB colour → linear (the shaders light in linear space and encode back to sRGB).
Vector3f linear(const Vec3f& c) {
  return {std::pow(c[0], 2.2f), std::pow(c[1], 2.2f), std::pow(c[2], 2.2f)};
}

Matrix4f look_at(const Vector3f& eye, const Vector3f& target, const Vector3f& up_hint) {
  const Vector3f f = (target - eye).normalized();
  Vector3f s = f.cross(up_hint);
  if (s.norm() < 1e-6f) s = f.cross(std::abs(f.y()) < 0.9f ? Vector3f::UnitY() : Vector3f::UnitX());
  s.normalize();
  const Vector3f u = s.cross(f);
  Matrix4f m = Matrix4f::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(eye);
  m(1, 3) = -u.dot(eye);
  m(2, 3) = f.dot(eye);
  return m;
}

Matrix4f perspective(float fov_deg, float aspect, float n, float f) {
  const float t = 1.0f / std::tan(0.5f * fov_deg * static_cast<float>(M_PI) / 180.0f);
  Matrix4f m = Matrix4f::Zero();
  m(0, 0) = t / aspect;
  m(1, 1) = t;
  m(2, 2) = (f + n) / (n - f);
  m(2, 3) = 2 * f * n / (n - f);
  m(3, 2) = -1;
  return m;
}

GLuint compile(GLenum type, const char* src) {
  const GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &src, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048];
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    throw std::runtime_error(fmt::format("GLSL compile error: {}", log));
  }
  return s;
}

GLuint link(const char* vs, const char* fs) {
  const GLuint p = glCreateProgram();
  const GLuint a = compile(GL_VERTEX_SHADER, vs), b = compile(GL_FRAGMENT_SHADER, fs);
  glAttachShader(p, a);
  glAttachShader(p, b);
  glLinkProgram(p);
  glDeleteShader(a);
  glDeleteShader(b);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048];
    glGetProgramInfoLog(p, sizeof log, nullptr, log);
    throw std::runtime_error(fmt::format("GLSL link error: {}", log));
  }
  return p;
}

/// Interleaved vertex: position, normal, (stress, damage, cut).
constexpr int kFloatsPerVertex = 9;

/// A triangle mesh on the GPU with its CPU-side vertex array (rewritten every frame).
struct GpuMesh {
  GLuint vao = 0, vbo = 0, ebo = 0;
  size_t vertices = 0, indices = 0, vbo_capacity = 0, ebo_capacity = 0;

  void create() {
    glGenVertexArrays(1, &vao);
    glGenBuffers(1, &vbo);
    glGenBuffers(1, &ebo);
    glBindVertexArray(vao);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ebo);
    const GLsizei stride = kFloatsPerVertex * sizeof(float);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, nullptr);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(3 * sizeof(float)));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 3, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(6 * sizeof(float)));
    glBindVertexArray(0);
  }
  void destroy() {
    if (!vao) return;
    glDeleteVertexArrays(1, &vao);
    glDeleteBuffers(1, &vbo);
    glDeleteBuffers(1, &ebo);
    vao = vbo = ebo = 0;
  }
  void upload_indices(const uint32_t* idx, size_t n) {
    glBindVertexArray(vao);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ebo);
    if (n > ebo_capacity) {
      glBufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(n * sizeof(uint32_t)), idx, GL_STATIC_DRAW);
      ebo_capacity = n;
    } else {
      glBufferSubData(GL_ELEMENT_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(n * sizeof(uint32_t)), idx);
    }
    indices = n;
    glBindVertexArray(0);
  }
  void upload_vertices(const float* v, size_t n) {
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    const size_t bytes = n * kFloatsPerVertex * sizeof(float);
    if (n > vbo_capacity) {
      glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(bytes), v, GL_STREAM_DRAW);
      vbo_capacity = n;
    } else {
      glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(bytes), v);
    }
    vertices = n;
  }
};

/// A tissue body: topology, current positions and fields, and its GPU mesh.
struct Body {
  Vector3f rest_lo, rest_hi;  // bounding box of the rest positions (camera framing)
  std::vector<uint32_t> triangles;
  std::vector<float> positions, stress, damage;
  std::vector<float> cut;          // per vertex 1: on a cut face (the wound's inner tissue)
  std::vector<float> interleaved;  // kFloatsPerVertex per vertex
  std::vector<Vector3f> normals;
  GpuMesh gpu;
  bool dirty = true;
};

void check_triangles(const uint32_t* tris, size_t n, size_t vertices) {
  for (size_t i = 0; i < 3 * n; ++i)
    if (tris[i] >= vertices)
      throw std::runtime_error(fmt::format("triangle {} refers to vertex {} of {}", i / 3, tris[i], vertices));
}

/// Area-weighted vertex normals (the cross product's length is twice the area).
void vertex_normals(const std::vector<float>& x, const std::vector<uint32_t>& tris, std::vector<Vector3f>& n) {
  const size_t nv = x.size() / 3;
  n.assign(nv, Vector3f::Zero());
  auto p = [&](uint32_t i) { return Vector3f(x[3 * i], x[3 * i + 1], x[3 * i + 2]); };
  for (size_t t = 0; t + 2 < tris.size(); t += 3) {
    const uint32_t a = tris[t], b = tris[t + 1], c = tris[t + 2];
    const Vector3f fn = (p(b) - p(a)).cross(p(c) - p(a));
    n[a] += fn;
    n[b] += fn;
    n[c] += fn;
  }
  for (Vector3f& v : n) {
    const float l = v.norm();
    v = l > 0 ? Vector3f(v / l) : Vector3f(0, 1, 0);
  }
}

/// Distance from p to the segment a–b.
float segment_distance(const Vector3f& p, const Vector3f& a, const Vector3f& b) {
  const Vector3f ab = b - a;
  const float l2 = ab.squaredNorm();
  const float t = l2 > 0 ? std::clamp((p - a).dot(ab) / l2, 0.0f, 1.0f) : 0.0f;
  return (p - (a + t * ab)).norm();
}

}  // namespace

struct Renderer::Impl {
  int width, height;
  Look look;
  Camera camera;
  std::vector<Body> bodies;
  std::vector<ToolView> tools;
  std::vector<RigidView> rigid;
  GpuMesh tool_mesh, rigid_mesh, thread_mesh;  // steel (tools, needles); the other rigid bodies; threads
  std::vector<float> tool_vertices, rigid_vertices, thread_vertices;
  std::vector<uint32_t> tool_indices, rigid_indices, thread_indices;
  GLuint marker_vao = 0, marker_vbo = 0, track_vao = 0, track_vbo = 0;
  std::vector<float> markers, track_marks;  // 3 per marker
  size_t marker_capacity = 0, track_capacity = 0;
  GLuint prog_mesh = 0, prog_background = 0, prog_marker = 0, empty_vao = 0;
  GLuint fbo_ms = 0, color_ms = 0, depth_ms = 0, fbo = 0, color = 0, depth = 0;
  int samples = 0;
  std::vector<uint8_t> rgba;
  size_t last_triangles = 0;
  float stress_max_seen = 0;  // automatic stress range: grows, never flickers
  std::vector<float> stress_scratch;  // per-frame copy for the percentile

  void create_framebuffers() {
    GLint max_samples = 0;
    glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
    samples = look.msaa > 1 ? std::min(look.msaa, max_samples) : 0;
    auto rb = [&](GLenum fmt, int s) {
      GLuint r = 0;
      glGenRenderbuffers(1, &r);
      glBindRenderbuffer(GL_RENDERBUFFER, r);
      if (s > 0) glRenderbufferStorageMultisample(GL_RENDERBUFFER, s, fmt, width, height);
      else glRenderbufferStorage(GL_RENDERBUFFER, fmt, width, height);
      return r;
    };
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    color = rb(GL_RGBA8, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color);
    depth = rb(GL_DEPTH_COMPONENT24, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("OpenGL: the off-screen framebuffer is incomplete");
    if (samples > 0) {
      glGenFramebuffers(1, &fbo_ms);
      glBindFramebuffer(GL_FRAMEBUFFER, fbo_ms);
      color_ms = rb(GL_RGBA8, samples);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color_ms);
      depth_ms = rb(GL_DEPTH_COMPONENT24, samples);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_ms);
      if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        throw std::runtime_error(fmt::format("OpenGL: the {}x multisample framebuffer is incomplete", samples));
    }
  }

  void destroy_framebuffers() {
    const GLuint fbos[] = {fbo_ms, fbo};
    const GLuint rbs[] = {color_ms, depth_ms, color, depth};
    glDeleteFramebuffers(2, fbos);
    glDeleteRenderbuffers(4, rbs);
    fbo_ms = color_ms = depth_ms = fbo = color = depth = 0;
  }

  /// Builds the interleaved vertex array of a body and uploads it.
  void upload_body(Body& b) {
    vertex_normals(b.positions, b.triangles, b.normals);
    const size_t nv = b.positions.size() / 3;
    b.interleaved.resize(nv * kFloatsPerVertex);
    for (size_t i = 0; i < nv; ++i) {
      float* o = &b.interleaved[i * kFloatsPerVertex];
      o[0] = b.positions[3 * i];
      o[1] = b.positions[3 * i + 1];
      o[2] = b.positions[3 * i + 2];
      o[3] = b.normals[i].x();
      o[4] = b.normals[i].y();
      o[5] = b.normals[i].z();
      o[6] = b.stress.empty() ? 0.0f : b.stress[i];
      o[7] = b.damage.empty() ? 0.0f : b.damage[i];
      o[8] = b.cut.empty() ? 0.0f : b.cut[i];
    }
    b.gpu.upload_vertices(b.interleaved.data(), nv);
    b.dirty = false;
  }

  /// Tool capsules (and needles' tubes) → one steel triangle mesh, the other rigid bodies → one
  /// more (rebuilt per frame: a few thousand vertices at most, or a rigid mesh's faces).
  void build_tools() {
    tool_vertices.clear();
    tool_indices.clear();
    rigid_vertices.clear();
    rigid_indices.clear();
    thread_vertices.clear();
    thread_indices.clear();
    for (const ToolView& t : tools)
      for (const ToolView::Capsule& c : t.capsules)
        append_capsule(c.a, c.b, c.r, tool_vertices, tool_indices, kFloatsPerVertex);
    for (const RigidView& b : rigid) {
      std::vector<float>& vert = b.thread ? thread_vertices : b.steel ? tool_vertices : rigid_vertices;
      std::vector<uint32_t>& idx = b.thread ? thread_indices : b.steel ? tool_indices : rigid_indices;
      for (const ToolView::Capsule& c : b.capsules) append_capsule(c.a, c.b, c.r, vert, idx, kFloatsPerVertex);
      for (size_t t = 0; t + 8 < b.triangles.size(); t += 9) {  // flat: the face's normal at its corners
        const Vector3f p0(&b.triangles[t]), p1(&b.triangles[t + 3]), p2(&b.triangles[t + 6]);
        Vector3f n = (p1 - p0).cross(p2 - p0);
        if (n.norm() > 0) n.normalize();
        for (const Vector3f* p : {&p0, &p1, &p2}) {
          idx.push_back(static_cast<uint32_t>(vert.size() / kFloatsPerVertex));
          vert.insert(vert.end(), {p->x(), p->y(), p->z(), n.x(), n.y(), n.z()});
          vert.resize(vert.size() + kFloatsPerVertex - 6, 0.0f);
        }
      }
    }
    tool_mesh.upload_vertices(tool_vertices.data(), tool_vertices.size() / kFloatsPerVertex);
    tool_mesh.upload_indices(tool_indices.data(), tool_indices.size());
    rigid_mesh.upload_vertices(rigid_vertices.data(), rigid_vertices.size() / kFloatsPerVertex);
    rigid_mesh.upload_indices(rigid_indices.data(), rigid_indices.size());
    thread_mesh.upload_vertices(thread_vertices.data(), thread_vertices.size() / kFloatsPerVertex);
    thread_mesh.upload_indices(thread_indices.data(), thread_indices.size());
  }

  /// A needle's track points → marks (drawn like contact markers, in Look::track).
  void build_track_marks() {
    track_marks.clear();
    for (const RigidView& b : rigid)
      for (const Vec3f& p : b.track) track_marks.insert(track_marks.end(), p.begin(), p.end());
    upload_points(track_vbo, track_marks, track_capacity);
  }

  static void upload_points(GLuint vbo, const std::vector<float>& pts, size_t& capacity) {
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    const size_t n = pts.size() / 3;
    if (n > capacity) {
      glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(pts.size() * sizeof(float)), pts.data(), GL_STREAM_DRAW);
      capacity = n;
    } else if (n > 0) {
      glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(pts.size() * sizeof(float)), pts.data());
    }
  }

  /// Surface vertices inside a tool (within 2 % of its radius): where it touches the tissue.
  void build_markers() {
    markers.clear();
    if (!look.contacts) return;
    for (const ToolView& t : tools)
      for (const ToolView::Capsule& c : t.capsules) {
        const Vector3f a = v3(c.a), bb = v3(c.b);
        const Vector3f lo = a.cwiseMin(bb).array() - c.r * 1.02f, hi = a.cwiseMax(bb).array() + c.r * 1.02f;
        for (const Body& b : bodies)
          for (size_t i = 0; i + 2 < b.positions.size(); i += 3) {
            const Vector3f p(b.positions[i], b.positions[i + 1], b.positions[i + 2]);
            if ((p.array() < lo.array()).any() || (p.array() > hi.array()).any()) continue;
            if (segment_distance(p, a, bb) <= c.r * 1.02f) markers.insert(markers.end(), {p.x(), p.y(), p.z()});
          }
      }
    upload_points(marker_vbo, markers, marker_capacity);
  }

  /// Bounding box of every body's rest positions (zero box without bodies).
  void rest_bounds(Vector3f& lo, Vector3f& hi) const {
    lo = Vector3f::Constant(1e30f);
    hi = Vector3f::Constant(-1e30f);
    for (const Body& b : bodies) {
      lo = lo.cwiseMin(b.rest_lo);
      hi = hi.cwiseMax(b.rest_hi);
    }
    if (lo.x() > hi.x()) lo = hi = Vector3f::Zero();
  }

  float scene_radius() const {
    Vector3f lo = Vector3f::Constant(1e30f), hi = Vector3f::Constant(-1e30f);
    for (const Body& b : bodies)
      for (size_t i = 0; i + 2 < b.positions.size(); i += 3) {
        const Vector3f p(b.positions[i], b.positions[i + 1], b.positions[i + 2]);
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
    return lo.x() > hi.x() ? 1.0f : 0.5f * (hi - lo).norm();
  }
  /// Camera matrices and light directions of one frame.
  struct View {
    Vector3f eye, key, fill, up;
    Matrix4f view_proj;
  };

  /// Near/far planes from the scene's extent around the target; the key light is the scene's
  /// direction, or above-left-behind the camera so the visible side is lit.
  View view() const {
    View v;
    v.eye = v3(camera.position);
    const Vector3f target = v3(camera.target);
    const float dist = (target - v.eye).norm();
    const float r = std::max(scene_radius(), 1e-6f);
    const float znear = std::max(1e-4f * dist, dist - 4.0f * r), zfar = dist + 4.0f * r;
    const Matrix4f view = look_at(v.eye, target, v3(camera.up));
    const Matrix4f proj =
        perspective(camera.fov_deg, static_cast<float>(width) / static_cast<float>(height), std::max(znear, 1e-6f), zfar);
    v.view_proj = proj * view;
    const Vector3f right(view(0, 0), view(0, 1), view(0, 2)), fwd = (target - v.eye).normalized();
    v.up = Vector3f(view(1, 0), view(1, 1), view(1, 2));
    v.key = v3(look.light_direction);
    if (v.key.norm() == 0) v.key = 0.45f * right - 0.75f * v.up + 0.5f * fwd;
    v.key.normalize();
    v.fill = (-0.6f * right - 0.2f * v.up + 0.75f * fwd).normalized();
    return v;
  }

  /// Background: a vertical gradient, one full-screen triangle, no depth.
  void draw_background() {
    glDisable(GL_DEPTH_TEST);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glUseProgram(prog_background);
    const Vector3f bt = v3(look.background_top), bb = v3(look.background_bottom);
    glUniform3f(glGetUniformLocation(prog_background, "u_top"), bt.x(), bt.y(), bt.z());
    glUniform3f(glGetUniformLocation(prog_background, "u_bottom"), bb.x(), bb.y(), bb.z());
    glBindVertexArray(empty_vao);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }

  /// The colour field's range. Automatic stress range: 0 to the largest 98th percentile of the
  /// per-vertex stress seen so far — not the maximum, which sits at a few stress-concentrating
  /// vertices (fixed nodes) and would leave the rest of the body one colour; never shrinking,
  /// so colours mean the same from frame to frame.
  std::pair<float, float> field_range() {
    if (look.field != ColorField::Stress || look.field_max > look.field_min) return {look.field_min, look.field_max};
    stress_scratch.clear();
    for (const Body& b : bodies) stress_scratch.insert(stress_scratch.end(), b.stress.begin(), b.stress.end());
    if (!stress_scratch.empty()) {
      const size_t k = stress_scratch.size() * 98 / 100;
      std::nth_element(stress_scratch.begin(), stress_scratch.begin() + static_cast<long>(k), stress_scratch.end());
      stress_max_seen = std::max(stress_max_seen, stress_scratch[k]);
    }
    return {0.0f, std::max(stress_max_seen, 1e-12f)};
  }

  /// The bodies (with the colour field, and their edges when wireframe), then the tools in
  /// polished steel, all with the mesh program's Blinn–Phong lighting.
  void draw_tissue_and_tools(const View& v) {
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glUseProgram(prog_mesh);
    auto loc = [&](const char* n) { return glGetUniformLocation(prog_mesh, n); };
    glUniformMatrix4fv(loc("u_view_proj"), 1, GL_FALSE, v.view_proj.data());
    glUniform3f(loc("u_eye"), v.eye.x(), v.eye.y(), v.eye.z());
    glUniform3f(loc("u_key_dir"), v.key.x(), v.key.y(), v.key.z());
    glUniform3f(loc("u_fill_dir"), v.fill.x(), v.fill.y(), v.fill.z());
    glUniform3f(loc("u_sky"), v.up.x(), v.up.y(), v.up.z());
    const auto [smin, smax] = field_range();
    const Vector3f tissue = linear(look.tissue);
    glUniform3f(loc("u_base"), tissue.x(), tissue.y(), tissue.z());
    const Vector3f cut = linear(look.cut_tissue);
    glUniform3f(loc("u_cut"), cut.x(), cut.y(), cut.z());
    glUniform1i(loc("u_field"), static_cast<int>(look.field));
    glUniform2f(loc("u_range"), smin, smax);
    glUniform1f(loc("u_shininess"), 48.0f);
    glUniform1f(loc("u_specular"), 0.35f);
    glUniform1i(loc("u_wire"), 0);
    last_triangles = 0;
    if (look.wireframe) {
      glEnable(GL_POLYGON_OFFSET_FILL);
      glPolygonOffset(1.0f, 1.0f);
    }
    for (const Body& b : bodies) {
      glBindVertexArray(b.gpu.vao);
      glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(b.gpu.indices), GL_UNSIGNED_INT, nullptr);
      last_triangles += b.gpu.indices / 3;
    }
    if (look.wireframe) {
      glDisable(GL_POLYGON_OFFSET_FILL);
      glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
      glUniform1i(loc("u_wire"), 1);
      for (const Body& b : bodies) {
        glBindVertexArray(b.gpu.vao);
        glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(b.gpu.indices), GL_UNSIGNED_INT, nullptr);
      }
      glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
      glUniform1i(loc("u_wire"), 0);
    }
    // Steel (tools, needles), then the other rigid bodies: flat colours, no field.
    auto draw_solid = [&](const GpuMesh& mesh, const Vec3f& colour, float shininess, float specular) {
      if (mesh.indices == 0) return;
      const Vector3f c = linear(colour);
      glUniform3f(loc("u_base"), c.x(), c.y(), c.z());
      glUniform1i(loc("u_field"), 0);
      glUniform1f(loc("u_shininess"), shininess);
      glUniform1f(loc("u_specular"), specular);
      glBindVertexArray(mesh.vao);
      glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(mesh.indices), GL_UNSIGNED_INT, nullptr);
      last_triangles += mesh.indices / 3;
    };
    draw_solid(tool_mesh, look.tool, 80.0f, 0.9f);
    draw_solid(rigid_mesh, look.rigid, 32.0f, 0.4f);
    draw_solid(thread_mesh, look.thread, 24.0f, 0.3f);
  }

  /// Contact markers and track marks: round points drawn over the surface they sit on.
  void draw_markers(const View& v) {
    draw_points(v, marker_vao, markers, look.marker);
    draw_points(v, track_vao, track_marks, look.track);
  }

  void draw_points(const View& v, GLuint vao, const std::vector<float>& pts, const Vec3f& colour) {
    if (pts.empty()) return;
    glUseProgram(prog_marker);
    glUniformMatrix4fv(glGetUniformLocation(prog_marker, "u_view_proj"), 1, GL_FALSE, v.view_proj.data());
    const Vector3f mc = v3(colour);
    glUniform3f(glGetUniformLocation(prog_marker, "u_color"), mc.x(), mc.y(), mc.z());
    glUniform1f(glGetUniformLocation(prog_marker, "u_size"), std::max(3.0f, 5.0f * static_cast<float>(height) / 480.0f));
    glEnable(GL_PROGRAM_POINT_SIZE);
    glDepthFunc(GL_LEQUAL);
    glBindVertexArray(vao);
    glDrawArrays(GL_POINTS, 0, static_cast<GLsizei>(pts.size() / 3));
    glDepthFunc(GL_LESS);
  }

  /// Resolves the samples, reads back and flips to top-down RGB.
  void read_back(Image& out) {
    if (samples > 0) {
      glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_ms);
      glBindFramebuffer(GL_DRAW_FRAMEBUFFER, fbo);
      glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
    out.width = width;
    out.height = height;
    out.channels = 3;
    out.pixels.resize(static_cast<size_t>(width) * height * 3);
    for (int y = 0; y < height; ++y) {
      const uint8_t* src = rgba.data() + static_cast<size_t>(height - 1 - y) * width * 4;
      uint8_t* dst = out.pixels.data() + static_cast<size_t>(y) * width * 3;
      for (int x = 0; x < width; ++x) {
        dst[3 * x] = src[4 * x];
        dst[3 * x + 1] = src[4 * x + 1];
        dst[3 * x + 2] = src[4 * x + 2];
      }
    }
  }
};

Renderer::Renderer(int width, int height, const Look& look) : impl_(std::make_unique<Impl>()) {
  if (width < 16 || height < 16 || width > 8192 || height > 8192)
    throw std::runtime_error(fmt::format("image size {}x{} is out of range (16..8192)", width, height));
  Impl& s = *impl_;
  s.width = width;
  s.height = height;
  s.look = look;
  s.prog_mesh = link(kMeshVertexShader, kMeshFragmentShader);
  s.prog_background = link(kBackgroundVertexShader, kBackgroundFragmentShader);
  s.prog_marker = link(kMarkerVertexShader, kMarkerFragmentShader);
  glGenVertexArrays(1, &s.empty_vao);
  s.tool_mesh.create();
  s.rigid_mesh.create();
  s.thread_mesh.create();
  for (auto [vao, vbo] : {std::pair{&s.marker_vao, &s.marker_vbo}, std::pair{&s.track_vao, &s.track_vbo}}) {
    glGenVertexArrays(1, vao);
    glGenBuffers(1, vbo);
    glBindVertexArray(*vao);
    glBindBuffer(GL_ARRAY_BUFFER, *vbo);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
  }
  glBindVertexArray(0);
  s.create_framebuffers();
  s.rgba.resize(static_cast<size_t>(width) * height * 4);
}

Renderer::~Renderer() {
  Impl& s = *impl_;
  for (Body& b : s.bodies) b.gpu.destroy();
  s.tool_mesh.destroy();
  s.rigid_mesh.destroy();
  s.thread_mesh.destroy();
  glDeleteVertexArrays(1, &s.marker_vao);
  glDeleteBuffers(1, &s.marker_vbo);
  glDeleteVertexArrays(1, &s.track_vao);
  glDeleteBuffers(1, &s.track_vbo);
  glDeleteVertexArrays(1, &s.empty_vao);
  glDeleteProgram(s.prog_mesh);
  glDeleteProgram(s.prog_background);
  glDeleteProgram(s.prog_marker);
  s.destroy_framebuffers();
}

namespace {

/// The wound's edge on the outer surface: the vertices of uncut faces at the place of a cut
/// face's vertex (the cut faces have their own vertices, at the same positions) get −1, which the
/// shader draws as a dark line along the lips — so a closed incision reads as one along the
/// blade's whole path, not as the hairline its touching lips leave.
void mark_wound_edge(const float* rest, std::vector<float>& cut) {
  struct Key {
    float x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct Hash {
    size_t operator()(const Key& k) const {
      uint32_t a, b, c;
      std::memcpy(&a, &k.x, 4), std::memcpy(&b, &k.y, 4), std::memcpy(&c, &k.z, 4);
      return (size_t(a) * 73856093u) ^ (size_t(b) * 19349663u) ^ (size_t(c) * 83492791u);
    }
  };
  std::unordered_set<Key, Hash> wound;
  for (size_t i = 0; i < cut.size(); ++i)
    if (cut[i] > 0) wound.insert({rest[3 * i], rest[3 * i + 1], rest[3 * i + 2]});
  if (wound.empty()) return;
  for (size_t i = 0; i < cut.size(); ++i)
    if (cut[i] == 0 && wound.count({rest[3 * i], rest[3 * i + 1], rest[3 * i + 2]})) cut[i] = -1.0f;
}

}  // namespace

int Renderer::add_body(const float* rest, size_t vertices, const uint32_t* triangles, size_t triangle_count,
                       const uint8_t* cut_faces) {
  check_triangles(triangles, triangle_count, vertices);
  impl_->bodies.emplace_back();
  impl_->bodies.back().gpu.create();
  const int id = static_cast<int>(impl_->bodies.size()) - 1;
  replace_body(id, rest, vertices, triangles, triangle_count, cut_faces);
  return id;
}

void Renderer::replace_body(int id, const float* rest, size_t vertices, const uint32_t* triangles,
                            size_t triangle_count, const uint8_t* cut_faces) {
  check_triangles(triangles, triangle_count, vertices);
  Body& b = impl_->bodies.at(id);
  b.cut.clear();
  if (cut_faces) {
    b.cut.assign(vertices, 0.0f);
    for (size_t t = 0; t < triangle_count; ++t)
      if (cut_faces[t])
        for (int k = 0; k < 3; ++k) b.cut[triangles[3 * t + k]] = 1.0f;
    mark_wound_edge(rest, b.cut);
  }
  b.positions.assign(rest, rest + 3 * vertices);
  b.rest_lo = Vector3f::Constant(1e30f);
  b.rest_hi = Vector3f::Constant(-1e30f);
  for (size_t i = 0; i < vertices; ++i) {
    const Vector3f p(rest[3 * i], rest[3 * i + 1], rest[3 * i + 2]);
    b.rest_lo = b.rest_lo.cwiseMin(p);
    b.rest_hi = b.rest_hi.cwiseMax(p);
  }
  b.triangles.assign(triangles, triangles + 3 * triangle_count);
  b.stress.clear();
  b.damage.clear();
  b.gpu.upload_indices(b.triangles.data(), b.triangles.size());
  b.dirty = true;
}

size_t Renderer::body_count() const { return impl_->bodies.size(); }

void Renderer::clear_bodies() {
  for (Body& b : impl_->bodies) b.gpu.destroy();
  impl_->bodies.clear();
  impl_->stress_max_seen = 0;
}

void Renderer::update_body(int id, const float* positions, const float* stress, const float* damage) {
  Body& b = impl_->bodies.at(id);
  const size_t nv = b.positions.size() / 3;
  std::copy(positions, positions + 3 * nv, b.positions.begin());
  if (stress) b.stress.assign(stress, stress + nv);
  else b.stress.clear();
  if (damage) b.damage.assign(damage, damage + nv);
  else b.damage.clear();
  b.dirty = true;
}

void Renderer::set_tools(std::vector<ToolView> tools) { impl_->tools = std::move(tools); }
void Renderer::set_rigid_bodies(std::vector<RigidView> bodies) { impl_->rigid = std::move(bodies); }
void Renderer::set_camera(const Camera& camera) { impl_->camera = camera; }
void Renderer::set_look(const Look& look) {
  const bool resample = look.msaa != impl_->look.msaa;
  impl_->look = look;
  if (resample) {
    impl_->destroy_framebuffers();
    impl_->create_framebuffers();
  }
}
const Look& Renderer::look() const { return impl_->look; }
int Renderer::width() const { return impl_->width; }
int Renderer::height() const { return impl_->height; }
size_t Renderer::last_triangles() const { return impl_->last_triangles; }
size_t Renderer::last_markers() const { return impl_->markers.size() / 3; }
size_t Renderer::last_track_marks() const { return impl_->track_marks.size() / 3; }

Camera Renderer::fit_camera(Vec3f view_direction, Vec3f up, float fov_deg) const {
  Vector3f lo, hi;
  impl_->rest_bounds(lo, hi);
  const Vector3f centre = 0.5f * (lo + hi);
  const float radius = std::max(0.5f * (hi - lo).norm(), 1e-6f);
  // Fit the bounding sphere in the smaller of the two fields of view (no margin: the sphere
  // around the box is already loose).
  const float aspect = static_cast<float>(impl_->width) / static_cast<float>(impl_->height);
  const float half_v = 0.5f * fov_deg * static_cast<float>(M_PI) / 180.0f;
  const float half = std::min(half_v, std::atan(std::tan(half_v) * aspect));
  const float dist = 1.0f * radius / std::sin(half);
  Vector3f d = v3(view_direction);
  d = d.norm() > 0 ? Vector3f(d.normalized()) : Vector3f(0, 0, -1);
  const Vector3f eye = centre - dist * d;
  Camera c;
  c.position = {eye.x(), eye.y(), eye.z()};
  c.target = {centre.x(), centre.y(), centre.z()};
  c.up = up;
  c.fov_deg = fov_deg;
  return c;
}

void Renderer::warm_up() {
  Impl& s = *impl_;
  Vector3f lo, hi;
  s.rest_bounds(lo, hi);
  // A sphere around the first body's first vertex: it touches the surface, so markers show.
  Vector3f c = 0.5f * (lo + hi);
  for (const Body& b : s.bodies)
    if (!b.positions.empty()) {
      c = Vector3f(b.positions[0], b.positions[1], b.positions[2]);
      break;
    }
  const float r = std::max(0.05f * (hi - lo).norm(), 1e-3f);
  const std::vector<ToolView> saved = s.tools;
  const Look look = s.look;
  ToolView t;
  t.capsules.push_back({{c.x(), c.y(), c.z()}, {c.x(), c.y() + r, c.z()}, r});
  s.tools = {t};
  s.look.contacts = true;
  Image scratch;
  for (bool wire : {false, true}) {
    s.look.wireframe = wire;
    render(scratch);
  }
  s.look = look;
  s.tools = saved;
}

void Renderer::render(Image& out) {
  Impl& s = *impl_;
  for (Body& b : s.bodies)
    if (b.dirty) s.upload_body(b);
  s.build_tools();
  s.build_markers();
  s.build_track_marks();
  const Impl::View v = s.view();
  glBindFramebuffer(GL_FRAMEBUFFER, s.samples > 0 ? s.fbo_ms : s.fbo);
  glViewport(0, 0, s.width, s.height);
  s.draw_background();
  s.draw_tissue_and_tools(v);
  s.draw_markers(v);
  glBindVertexArray(0);
  s.read_back(out);
  const GLenum err = glGetError();
  if (err != GL_NO_ERROR) throw std::runtime_error(fmt::format("OpenGL error 0x{:x} while rendering", err));
}

}  // namespace stroma::render
