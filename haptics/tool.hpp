#pragma once
/// \file tool.hpp
/// Virtual surgical tools as the engine sees them: what a scenario declares (ToolSpec), the
/// pose a device or script commands (ToolPose), the checks every command passes before it may
/// reach physics (validate_tool_command), the tool's part of the simulation state (ToolState)
/// and what it felt in one tick (ToolOutput, with the device's ToolFeedback).
/// Contact and grasping: haptics/contact.hpp; feedback: haptics/feedback.hpp.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "tissue/tet_mesh.hpp"

namespace stroma {

/// A commanded device pose. Invariant once validated (validate_tool_command): finite values,
/// a unit quaternion (renormalised), the position inside the tool's workspace.
struct ToolPose {
  Vec3 position{0, 0, 0};                       ///< m
  std::array<double, 4> orientation{1, 0, 0, 0};  ///< unit quaternion (w, x, y, z)
  double jaw = 0;                               ///< jaw opening (rad)
  uint32_t buttons = 0;
};

/// What to do with a command that fails a check.
enum class InvalidCommandPolicy {
  Reject,  ///< drop it; the tool keeps its last accepted pose
  Clamp    ///< bring it into the workspace / speed limit (non-finite values are always rejected)
};

/// Geometry of a tool that touches tissue.
enum class ToolShape {
  None,   ///< moves, gets feedback, touches nothing
  Sphere,  ///< a sphere (a probe's tip) centred on the tool position
  Probe,   ///< a sphere tip plus a capsule shaft along the tool's local +z axis
  Blade,   ///< an edge (capsule of `radius`) of `length` along the tool's local x, centred
  Grasper  ///< two jaws (capsules of `radius`, `length`) from the hinge at the tool position,
           ///< along local +z opened by ±jaw/2 about the local y axis
};

/// `tools:` entry of a scenario. Invariants (checked at load): radius > 0 when shaped,
/// shaft_radius ≤ radius, lengths, stiffnesses, damping, friction, timeouts ≥ 0, max_force > 0,
/// grasp_close < grasp_open, workspace_min ≤ workspace_max. In a Model every automatic value
/// (0 stiffness) is resolved.
struct ToolSpec {
  std::string name;
  /// Where the tool is before its first command (`pose:` of the scenario's tool; default the
  /// first keyframe of its script, else the origin with the identity orientation). The initial
  /// state holds it, so every front end reports the tool's true pose from the first tick
  /// (CRTK's measured_cp, Python's tool poses). An idle tool touches nothing wherever it is.
  ToolPose rest_pose;
  Vec3 workspace_min{-1e3, -1e3, -1e3};
  Vec3 workspace_max{1e3, 1e3, 1e3};
  double max_speed = 5.0;        ///< m/s: faster jumps are rejected or clamped
  double timeout = 0.5;          ///< s without commands before the tool goes idle
  InvalidCommandPolicy on_invalid = InvalidCommandPolicy::Reject;
  ToolShape shape = ToolShape::None;
  double radius = 0;             ///< tip sphere radius (m)
  double shaft_radius = 0;       ///< probe: shaft radius (m), ≤ radius
  double shaft_length = 0;       ///< probe: shaft length; blade: edge length; grasper: jaw length (m)
  double contact_stiffness = 0;  ///< contact pressure per penetration (Pa/m = N/m³);
                                 ///< 0 = automatic: 100·E/radius of the stiffest body
                                 ///< (a cutting blade: 100·E/blade_height)
  double contact_damping = 0;    ///< pressure per penetration rate (Pa·s/m), normal direction
  /// Coulomb friction coefficient μ (0: frictionless). Regularised: below a slip speed of
  /// 1 % of the radius per second the friction is viscous (a stick that creeps), above it the
  /// tangential force is μ·|normal force| against the sliding direction.
  double friction = 0;
  double max_force = 10;         ///< N: the feedback force is clamped to this magnitude
  // Virtual coupling (`coupling:` section): the tool in the simulation is a proxy tied to the
  // device pose by a spring; the tissue stops the proxy (it does not sink through) and the
  // device feels the spring, stiffness·(proxy − device).
  double coupling_stiffness = 0; ///< N/m; 0 = no coupling (the tool follows the device exactly)
  double coupling_damping = 0;   ///< N·s/m on the proxy–device relative velocity
  // Grasping (`grasp:` section): closing the jaws (opening below `close`) attaches the surface
  // points within `reach`·radius of the tip (the contact samples of the surface triangles,
  // closest first), each by a spring to where it was in the tool's frame; opening above `open`
  // releases them. While grasping, the tip's contact is off.
  bool can_grasp = false;
  double grasp_close = 0.05;     ///< rad
  double grasp_open = 0.1;       ///< rad (hysteresis: > grasp_close)
  double grasp_reach = 1.2;      ///< × radius
  double grasp_stiffness = 0;    ///< N/m per point; 0 = automatic (contact stiffness × radius² / 4)
  // Cutting (`cut:` section, blades only): the blade's edge — the capsule's axis — cuts the
  // tissue edges it sweeps over between two ticks (docs/CUTTING.md). It passes through uncut
  // tissue; its sides push the wound's lips apart (contact on cut faces only, along the blade's
  // normal, its local y); the cutting resistance is
  // the toughness times the area cut per unit of blade travel, against the blade's motion.
  bool cuts = false;
  double cut_toughness = 0;      ///< J/m²: energy per unit of cut area (0: cuts without resistance)
  /// m: the blade's body behind its edge (local −z), which holds the wound open; 0 = half the
  /// edge's length (a scalpel blade is about twice as long as it is tall).
  double blade_height = 0;
};

/// Surface points a tool can hold at once (fixed so the state has no heap memory per grasp).
inline constexpr int kMaxGrasped = 64;
/// s: time constant over which the cutting resistance follows the cut rate (the cut advances
/// edge by edge: unsmoothed, the force would come in spikes a device renders as buzz).
inline constexpr double kCutForceTime = 0.005;

/// Outcome of validating one command.
struct ToolCheck {
  enum Result : uint8_t { Accepted, Clamped, Rejected } result = Accepted;
  /// Why a command was rejected or clamped: Malformed (a non-finite value, a quaternion that is
  /// not a unit one: the data is not a pose) or Limit (the workspace, max_speed: a valid pose the
  /// tool may not take). CRTK faults on a Limit only (docs/CRTK.md).
  enum Cause : uint8_t { None, Malformed, Limit } cause = None;
  const char* reason = "";  ///< static string, for counters and logs
  ToolPose pose;            ///< the pose to apply (clamped if Clamped)
};

/// Checks a command against the tool's limits: finite values, unit quaternion (|q| within
/// 1e-3 of 1; renormalised), position inside the workspace, speed since the last accepted
/// command (`dt` seconds ago; dt ≤ 0 skips the speed check) at most max_speed.
ToolCheck validate_tool_command(const ToolSpec& spec, const ToolPose& last, double dt,
                                const ToolPose& command);

/// Secants a HapticModel keeps: their median is its stiffness (engine/multirate.hpp).
inline constexpr int kSecantWindow = 3;

/// The local model a tool's force is rendered from between tissue steps (multirate,
/// solver.fem_every > 1; built by engine/multirate.cpp, rendered by haptics/haptic_model.hpp):
/// a step of the tissue solved with the tool at `center` left the wrench on the tool, and the
/// steps before it measured how the force changes as the tool moves along the contact normal.
/// Invariants: stiffness is symmetric negative semidefinite (row-major, N/m); secants[0,
/// secant_count) are ≤ 0, newest first; with valid false (no step finished yet) the model
/// renders no force.
struct HapticModel {
  bool valid = false;
  Vec3 center{0, 0, 0};               ///< the tool centre the step was solved with (m)
  Vec3 force{0, 0, 0};                ///< the tissue's force on the tool after that step (N)
  Vec3 torque{0, 0, 0};               ///< its torque about `center` (N·m)
  std::array<double, 9> stiffness{};  ///< dF/dp rendered with (N/m)
  std::array<double, kSecantWindow> secants{};  ///< normal secants of the last steps (N/m)
  int secant_count = 0;
};

/// A tool's part of the simulation state (copied with the state: replay reproduces it).
/// Invariants: grasped ≤ kMaxGrasped and grasped > 0 only while jaw_closed; `force` and
/// `stiffness` are those of the last solved step (zero before the first contact).
struct ToolState {
  ToolPose pose;
  uint64_t seq = 0;              ///< seq of the last applied command
  int64_t client_time_ns = 0;    ///< its client timestamp (echoed in feedback)
  double last_command_time = -1; ///< sim time of the last applied command (−1: never)
  bool active = false;           ///< a client is driving it (false after `timeout`)
  /// A front end posed it directly (Python's set_pose): its scenario script no longer drives it.
  /// State, not front-end bookkeeping, so a snapshot restores who drives the tool.
  bool posed = false;
  // The tissue's force on the tool at the end of the last tick and its stiffness dF/dx: the
  // virtual coupling's next quasi-static step starts from them (so they are state, not output).
  Vec3 force{0, 0, 0};
  std::array<double, 9> stiffness{};
  // Virtual coupling:
  bool has_center = false;
  Vec3 last_center{0, 0, 0};          ///< contact centre of the previous tick (tool velocity)
  bool has_proxy = false;
  Vec3 proxy{0, 0, 0};                ///< where the simulated tool is (contact happens here)
  Vec3 coupling_stretch{0, 0, 0};     ///< proxy − device of the previous tick (damping rate)
  // Grasp: attached surface points (collision triangle + barycentric u, v) and their offsets in
  // the tool frame at the moment of grasping.
  bool jaw_closed = false;  ///< for the open → closed transition that grasps
  int grasped = 0;
  std::array<int32_t, kMaxGrasped> grasp_triangle{};
  std::array<std::array<double, 2>, kMaxGrasped> grasp_uv{};
  std::array<Vec3, kMaxGrasped> grasp_offset{};
  // Grasp of a rigid body (engine/rigid_grasp.hpp): the body held (−1: none) and the points that
  // hold it, each in the body's frame and in the tool's (about the tool centre) at the moment of
  // grasping. Invariant: grasped_body ≥ 0 only while jaw_closed, and then grasped = 0.
  int32_t grasped_body = -1;
  std::array<Vec3, 3> body_hold_point{};
  std::array<Vec3, 3> tool_hold_point{};
  // Grasp of a thread (engine/thread_attach.hpp): the segment held — its first node, a global
  // node index (−1: none) — the point's place along it (0..1) and where the point was in the
  // tool's frame (about the tool centre) at the moment of grasping. Invariant:
  // grasped_segment ≥ 0 only while jaw_closed, and then grasped = 0 and grasped_body = −1.
  int32_t grasped_segment = -1;
  /// The thread segment (a global node) it last let go of — the one it held, or the end tied to
  /// the needle it held (−1: none): its jaws do not touch the segments within their reach of it
  /// until those are clear of them (the opened jaws' capsules still hold the thread they held;
  /// pushing it out from inside would fling it). engine/thread_contact.hpp.
  int32_t released_segment = -1;
  double grasp_segment_s = 0;
  Vec3 grasp_segment_offset{0, 0, 0};
  // Cutting: the blade's edge at the end of the last tick (the swept surface starts there) and
  // the cutting resistance felt (N, smoothed over kCutForceTime).
  bool has_blade = false;
  Vec3 blade_a{0, 0, 0}, blade_b{0, 0, 0};
  Vec3 cut_force{0, 0, 0};
  // Multirate (fem_every > 1): the model rendered now, and the one the last tissue step made,
  // which takes over when the next step starts (the step it came from took that long to run).
  HapticModel haptic, haptic_next;
};

/// What the device renders for one tick: the wrench and its stiffness after the coupling and
/// the clamp to max_force (haptics/feedback.hpp computes it, headless and served alike).
struct ToolFeedback {
  Vec3 force{0, 0, 0};                ///< N, |force| ≤ max_force
  Vec3 torque{0, 0, 0};               ///< N·m, about the device's tool centre
  std::array<double, 9> stiffness{};  ///< dF/d(device position), N/m, for extrapolation
  bool clamped = false;               ///< the force was scaled down to max_force
};

/// What one tool felt in one tick (TickReport::tools; not state). Forces are those of the
/// solved step: the contact springs the step was solved with, evaluated at its end state.
struct ToolOutput {
  Vec3 force{0, 0, 0};                ///< tissue on tool (N), unclamped
  std::array<double, 9> stiffness{};  ///< dF/dx of that force w.r.t. the tool position (N/m)
  Vec3 torque{0, 0, 0};               ///< of that force about the tool centre (N·m)
  ToolFeedback feedback;              ///< what the device renders
  int contacts = 0;                   ///< contact points (surface samples inside, or grasped)
  int contacts_dropped = 0;           ///< beyond the per-tick capacity (should stay 0)
  double contact_energy = 0;          ///< penalty potential Σ ½ k δ² where contacts were found (J)
  bool grasping = false;              ///< holding tissue (its springs are grasp springs)
  int32_t holding_body = -1;          ///< the rigid body it holds (−1: none)
  int cut_edges = 0;                  ///< mesh edges its blade cut this tick
  int32_t spring_begin = 0, spring_end = 0;  ///< its springs in the tick's spring list
};

/// Rotation matrix (row-major) of a unit quaternion (w, x, y, z).
void quaternion_to_matrix(const std::array<double, 4>& q, double* R);

/// A command that physics applies at the start of a tick (read_inputs stage).
struct ToolInput {
  int32_t tool = 0;   ///< index into the scenario's tools
  uint64_t seq = 0;
  int64_t client_time_ns = 0;
  ToolPose pose;
  /// `serve` only: when the server's input thread accepted it (steady_now_ns); 0 elsewhere.
  /// Times the command path (PhaseLock); not logged, never read by the tick.
  int64_t arrival_ns = 0;
};

/// Force feedback of one tool for one tick as the server sends it (ToolFeedback plus the
/// command it answers and timestamps).
struct ToolFeedbackFrame {
  int32_t tool = 0;
  uint64_t seq = 0;
  int64_t client_time_ns = 0;
  int64_t server_time_ns = 0;
  double sim_time = 0;
  Vec3 force{0, 0, 0}, torque{0, 0, 0};
  bool in_contact = false;
  std::array<double, 9> stiffness{};
  bool active = false;
  ToolPose pose;  ///< the tool's pose in this tick (the last command applied)
};

}  // namespace stroma
