#pragma once
/// \file renderer.hpp
/// Draws tissue surfaces and tools into an off-screen image: smooth per-frame vertex normals,
/// Blinn–Phong lighting (key + fill + hemisphere ambient + rim), a stress or damage colour map
/// over the tissue colour, tools as capsules, rigid bodies (needles as steel tubes with their
/// track marks), contact markers, optional wireframe, multisample
/// anti-aliasing. Knows nothing of DDS or the engine: the render process and the tests feed it
/// plain arrays. Needs a current GL 3.3+ core context (GlContext) on the calling thread.

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "render/png_io.hpp"

namespace stroma::render {

using Vec3f = std::array<float, 3>;

/// What the tissue colour shows.
enum class ColorField { None, Stress, Damage };

/// A pinhole camera looking from `position` at `target`.
struct Camera {
  Vec3f position{0, 0, 5}, target{0, 0, 0}, up{0, 1, 0};
  float fov_deg = 35;  ///< vertical field of view
};

/// How a frame looks. Colours are sRGB in 0..1.
struct Look {
  Vec3f background_top{0.20f, 0.23f, 0.28f}, background_bottom{0.04f, 0.045f, 0.055f};
  Vec3f tissue{0.66f, 0.26f, 0.22f};  ///< liver-like red-brown
  Vec3f cut_tissue{0.85f, 0.10f, 0.09f};  ///< the inner faces a cut exposed: fresh, bloody red
  Vec3f tool{0.80f, 0.82f, 0.86f};    ///< brushed steel
  Vec3f marker{1.0f, 0.85f, 0.15f};   ///< contact markers
  Vec3f rigid{0.35f, 0.55f, 0.80f};   ///< rigid bodies other than needles (needles are steel: `tool`)
  Vec3f track{0.12f, 0.03f, 0.05f};   ///< a needle's track marks: dark, where the tissue was pierced
  Vec3f thread{0.45f, 0.22f, 0.66f};  ///< suture threads: violet (dyed polyglactin)
  /// Key light direction in world coordinates (from the light towards the scene); all zero:
  /// above and to the left of the camera, following it.
  Vec3f light_direction{0, 0, 0};
  ColorField field = ColorField::Damage;
  float field_min = 0, field_max = 0;  ///< colour-map range; max <= min: automatic (stress:
                                       ///< 0 to the largest 98th percentile seen)
  bool wireframe = false;
  bool contacts = true;                ///< markers where the surface is inside a tool
  int msaa = 4;                        ///< samples per pixel (0 or 1: none)
};

/// A tool to draw: capsules (segment a–b swept by radius r) in world coordinates.
struct ToolView {
  struct Capsule {
    Vec3f a, b;
    float r;
  };
  std::vector<Capsule> capsules;
  bool in_contact = false;
};

/// A rigid body to draw, in world coordinates (render/rigid_view.hpp makes it from a shape and a
/// pose): capsules (spheres, capsules, a needle's tube), flat triangles (9 floats each,
/// counter-clockwise from outside) and a needle's track points, drawn as dark marks.
struct RigidView {
  std::vector<ToolView::Capsule> capsules;
  std::vector<float> triangles;
  std::vector<Vec3f> track;
  bool steel = false;  ///< drawn in the tools' steel (a needle) rather than Look::rigid
  bool thread = false;  ///< a suture thread's tube, drawn in Look::thread
};

/// Off-screen renderer of bodies (triangle surfaces with per-vertex fields) and tools.
class Renderer {
 public:
  /// Creates the framebuffers and shaders for width × height images. Throws std::runtime_error
  /// with the GL log if a shader fails or the framebuffer is incomplete.
  Renderer(int width, int height, const Look& look);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  /// Adds a body with its rest positions (3 floats per vertex) and triangles (3 indices each,
  /// counter-clockwise from outside); returns its id. `cut_faces` (optional, one per triangle):
  /// 1 draws the triangle as cut tissue (Look::cut_tissue; its vertices should be its own, or
  /// the colour spreads to the skin triangles sharing them). Throws on an index out of range.
  int add_body(const float* rest, size_t vertices, const uint32_t* triangles, size_t triangle_count,
               const uint8_t* cut_faces = nullptr);
  /// Replaces body `id`'s surface (a new mesh: a restarted server, or a new topology).
  void replace_body(int id, const float* rest, size_t vertices, const uint32_t* triangles, size_t triangle_count,
                    const uint8_t* cut_faces = nullptr);
  size_t body_count() const;
  /// Removes every body (a new scene).
  void clear_bodies();
  /// New positions (3 per vertex) and optional per-vertex stress (Pa) and damage (0..1).
  void update_body(int id, const float* positions, const float* stress, const float* damage);
  void set_tools(std::vector<ToolView> tools);
  void set_rigid_bodies(std::vector<RigidView> bodies);
  void set_camera(const Camera& camera);
  void set_look(const Look& look);
  const Look& look() const;

  /// A camera that frames the bounding sphere of every body's rest positions, looking along
  /// `view_direction` (from the camera to the scene) with `up` up.
  Camera fit_camera(Vec3f view_direction, Vec3f up, float fov_deg = 35) const;

  /// Renders a frame into `out` (RGB, rows top to bottom; resized on first use).
  void render(Image& out);

  /// Renders (and discards) frames that use every pipeline state — tissue, a tool, contact
  /// markers, wireframe — so the software rasteriser compiles its shaders now rather than
  /// during a recording (~0.1 s each on llvmpipe).
  void warm_up();

  int width() const;
  int height() const;
  /// Triangles drawn in the last frame (tissue, tools and rigid bodies), contact markers and
  /// track marks.
  size_t last_triangles() const;
  size_t last_markers() const;
  size_t last_track_marks() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace stroma::render
