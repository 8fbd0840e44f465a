"""`import stroma` (python/stroma_module.cpp): the Python module against the engine itself.

Asserted: a step in Python is a step of `stroma run`, bit for bit (positions after N ticks
equal final_state.csv, whose %.17g round-trips doubles); positions/velocities are read-only
arrays that follow the state and never read freed memory; snapshot/restore replays bit for bit;
a bad scenario raises ValueError with the engine's file:line message; a scripted probe pressing
the liver feels it push back, and set_pose lifts it off; bad tool indices raise IndexError.
Run by ctest (test `python.pytest`) with PYTHONPATH=build/python and STROMA_BUILD_DIR set.
"""
import csv
import json
import os
import pathlib
import pickle
import subprocess
import sys

import numpy as np
import pytest

import stroma

SOURCE = pathlib.Path(__file__).resolve().parents[2]
BUILD = pathlib.Path(os.environ.get("STROMA_BUILD_DIR", SOURCE / "build"))
SCENARIOS = SOURCE / "scenarios"


def final_state(out_dir):
    with open(out_dir / "final_state.csv") as f:
        rows = list(csv.DictReader(f))
    return np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in rows])


@pytest.mark.parametrize("scenario", ["cantilever_dynamic.yaml", "liver.yaml"])
def test_a_python_step_is_a_step_of_stroma_run_bit_for_bit(scenario, tmp_path):
    steps = 40
    subprocess.run([str(BUILD / "stroma"), "run", str(SCENARIOS / scenario), "--steps", str(steps),
                    "--out", str(tmp_path), "--quiet", "--no-metrics"], check=True)
    sim = stroma.Simulation(str(SCENARIOS / scenario))
    assert sim.step(steps) == steps
    assert sim.steps == steps
    assert sim.time == pytest.approx(steps * sim.time_step, rel=1e-12)
    expected = final_state(tmp_path)
    assert expected.shape == sim.positions.shape
    moved = np.abs(expected - stroma.Simulation(str(SCENARIOS / scenario)).positions).max()
    assert moved > 0, "the run moved the body (else the comparison shows nothing)"
    assert np.array_equal(sim.positions, expected)


def test_the_solver_says_what_runs_and_who_chose_it(tmp_path):
    """`.solver` is summary.json's object: an untuned scene's preconditioner chosen by the
    engine (with the trial behind it), a shipped scene's as written."""
    untuned = stroma.Simulation(str(SCENARIOS / "untuned" / "plate_2mm_50kpa.yaml"))
    s = untuned.solver
    assert s["preconditioner_chosen_by"] == "auto" and s["on_cg_cap_chosen_by"] == "auto"
    assert s["preconditioner"] == "warped_cholesky", s["choice"]["reason"]
    assert {t["preconditioner"] for t in s["choice"]["trials"]} == {"jacobi", "block_jacobi", "warped_cholesky"}
    shipped = stroma.Simulation(str(SCENARIOS / "liver.yaml")).solver
    assert shipped["preconditioner"] == "jacobi" and shipped["preconditioner_chosen_by"] == "scenario"
    assert "choice" not in shipped
    subprocess.run([str(BUILD / "stroma"), "run", str(SCENARIOS / "untuned" / "plate_2mm_50kpa.yaml"), "--steps", "1",
                    "--out", str(tmp_path), "--quiet", "--no-metrics"], check=True)
    run_solver = json.load(open(tmp_path / "summary.json"))["solver"]
    for key in ("preconditioner", "preconditioner_refresh", "on_cg_cap", "tolerance", "max_iterations"):
        assert run_solver[key] == s[key], key


def test_positions_and_velocities_are_read_only_arrays_that_follow_the_state():
    sim = stroma.Simulation(str(SCENARIOS / "cantilever_dynamic.yaml"))
    x, v = sim.positions, sim.velocities
    assert x.shape == (sim.num_nodes, 3) and v.shape == (sim.num_nodes, 3)
    assert not x.flags.writeable and not v.flags.writeable
    before = x.copy()
    sim.step(10)
    assert not np.array_equal(x, before), "an array taken before a step shows the new state"
    assert x is sim.positions and np.array_equal(x, sim.positions)
    assert np.abs(v).max() > 0
    with pytest.raises(ValueError):
        x[0, 0] = 1.0


def test_arrays_taken_before_a_reset_or_a_cut_never_read_freed_memory():
    # Issue 41 §5: a view taken before reset() read freed memory (a cube summed to 2.6e-306).
    sim = stroma.Simulation(str(SCENARIOS / "cantilever_dynamic.yaml"))
    x, v = sim.positions, sim.velocities
    rest = x.copy()
    sim.step(30)
    sim.reset()
    assert np.array_equal(x, rest) and np.array_equal(x, sim.positions), "after reset: the initial state"
    assert np.abs(v).max() == 0
    for _ in range(3):  # resets that rebuild the engine's state many times over
        sim.step(5)
        sim.reset()
    assert np.array_equal(x, rest)
    # Across a cut the node count grows: the old array keeps the last values of the old mesh.
    cut = stroma.Simulation(str(SCENARIOS / "regression" / "liver_incision.yaml"))
    n0 = cut.num_nodes
    old = cut.positions
    span = np.ptp(old, axis=0).max()
    cut.step(2500)
    assert cut.num_nodes > n0, "the scalpel cut"
    assert old.shape == (n0, 3) and cut.positions.shape == (cut.num_nodes, 3), "the shape tells a stale array"
    assert np.isfinite(old).all() and np.abs(old - cut.positions[:n0]).max() < span, "real positions, not freed memory"


def test_snapshot_and_restore_replay_bit_for_bit():
    sim = stroma.Simulation(str(SCENARIOS / "cantilever_dynamic.yaml"))
    sim.step(15)
    snap = sim.snapshot()
    t0 = sim.time
    sim.step(25)
    first = sim.positions.copy()
    sim.restore(snap)
    assert sim.time == t0
    assert not np.array_equal(sim.positions, first)
    sim.step(25)
    assert np.array_equal(sim.positions, first)
    sim.reset()
    assert sim.time == 0 and sim.steps == 0


def test_a_bad_scenario_raises_with_file_line_and_field(tmp_path):
    mesh = SCENARIOS / "meshes" / "cube_tet4_h8p333mm.msh"
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nbodies:\n  - name: block\n    mesh: %s\n"
                   "    material: {model: corotational, young_modulus: -5, poisson_ratio: 0.3, density: 1000}\n" % mesh)
    with pytest.raises(ValueError) as e:
        stroma.Simulation(str(bad))
    assert "bad.yaml:5" in str(e.value)
    assert "young" in str(e.value).lower()
    with pytest.raises(ValueError):
        stroma.Simulation(str(tmp_path / "missing.yaml"))


def test_a_scripted_probe_presses_as_in_stroma_run_and_set_pose_takes_it_away(tmp_path):
    scenario = SCENARIOS / "regression" / "liver_probe_press.yaml"
    steps = 1500  # the script has pressed the probe 1.2 units down from y = 7 by t = 1.5 s
    subprocess.run([str(BUILD / "stroma"), "run", str(scenario), "--steps", str(steps), "--out", str(tmp_path),
                    "--quiet", "--no-metrics"], check=True)
    sim = stroma.Simulation(str(scenario))
    assert sim.num_tools == 1
    sim.step(steps)
    assert np.array_equal(sim.positions, final_state(tmp_path)), "tool contact included, bit for bit"
    fb = sim.feedback(0)
    assert fb["contacts"] > 0
    assert fb["force"][1] > 0, "the tissue pushes the probe up, out of the liver"
    assert sim.metrics["cg_iterations"] >= 1
    # Commanded from Python instead of the script: lifted at 20 units/s (max_speed 50), it
    # leaves the surface and the contact ends.
    y = 7.0 - 1.7 * 1.0 - 0.7 * 0.5  # the script's pose at t = 1.5 s
    for k in range(1, 101):
        sim.set_pose(0, [-1.5, y + 0.02 * k, 0.5])
        sim.step()
    assert sim.feedback(0)["contacts"] == 0
    assert sim.feedback(0)["force"] == [0.0, 0.0, 0.0]
    with pytest.raises(IndexError):
        sim.set_pose(1, [0, 0, 0])
    with pytest.raises(IndexError):
        sim.feedback(-1)


def test_set_pose_is_checked_refused_and_counted_as_every_front_end_s_commands():
    # The commands port of the engine's Simulation (docs/PYTHON.md): a NaN, a zero or non-unit
    # quaternion, or a jump of 10x max_speed in one tick is refused (the scenario's on_invalid:
    # reject), never applied, and counted, as `serve` refuses and counts them.
    sim = stroma.Simulation(str(SCENARIOS / "regression" / "liver_probe_press.yaml"))  # max_speed 50
    assert sim.set_pose(0, [-1.5, 7.0, 0.5]) == "accepted"
    sim.step(10)
    held = sim.feedback(0)
    refused = [
        sim.set_pose(0, [-1.5, float("nan"), 0.5]),
        sim.set_pose(0, [-1.5, 7.0, 0.5], [0, 0, 0, 0]),
        sim.set_pose(0, [-1.5, 7.0, 0.5], [0.5, 0.5, 0.5, 0.6]),
        sim.set_pose(0, [-1.5, 7.0 - 10 * 50 * 11 * sim.time_step, 0.5]),  # 10x the limit over 11 ticks
    ]
    assert refused == ["rejected"] * 4
    counts = sim.commands
    assert (counts["accepted"], counts["clamped"], counts["rejected"]) == (1, 0, 4)
    assert "max_speed" in counts["last_reason"]
    sim.step(5)
    assert sim.feedback(0) == held, "the tool held its accepted pose: nothing refused reached the tissue"
    # Within the limit it moves: 0.04 units in one tick at 50 units/s.
    assert sim.set_pose(0, [-1.5, 7.0 - 0.04, 0.5]) == "accepted"


def test_a_snapshot_restores_only_into_a_simulation_of_the_same_compiled_model():
    # liver.yaml and liver_probe_press.yaml share the mesh (states of one size) but not the model
    # (gravity, fixed set, damping, a tool): restoring across them is refused and changes nothing.
    liver = stroma.Simulation(str(SCENARIOS / "liver.yaml"))
    liver.step(5)
    snap = liver.snapshot()
    press = stroma.Simulation(str(SCENARIOS / "regression" / "liver_probe_press.yaml"))
    press.step(3)
    before = press.positions.copy()
    for s in (snap, pickle.loads(pickle.dumps(snap))):
        with pytest.raises(ValueError, match="another scenario"):
            press.restore(s)
    assert press.steps == 3 and np.array_equal(press.positions, before)
    same = stroma.Simulation(str(SCENARIOS / "liver.yaml"))
    same.restore(pickle.loads(pickle.dumps(snap)))
    assert same.steps == 5 and np.array_equal(same.positions, liver.positions)


def test_a_scalpel_run_cuts_as_stroma_run_and_restores_across_the_cut(tmp_path):
    scenario = SCENARIOS / "regression" / "liver_incision.yaml"
    steps = 2500
    subprocess.run([str(BUILD / "stroma"), "run", str(scenario), "--steps", str(steps), "--out", str(tmp_path),
                    "--quiet", "--no-metrics"], check=True)
    sim = stroma.Simulation(str(scenario))
    n0 = sim.num_nodes
    sim.step(100)
    before_cut = sim.snapshot()
    assert sim.num_nodes == n0, "not cut yet at 0.1 s"
    sim.step(steps - 100)
    assert sim.num_nodes > n0, "the scalpel cut: new DOFs"
    assert np.array_equal(sim.positions, final_state(tmp_path)), "cut swaps included, bit for bit"
    cut = sim.positions.copy()
    sim.restore(before_cut)
    assert sim.num_nodes == n0 and sim.steps == 100
    sim.step(steps - 100)
    assert np.array_equal(sim.positions, cut), "restored before the cut, it cuts again the same way"


def test_a_scenario_from_a_dict_equals_the_same_file(tmp_path):
    scenario = {
        "name": "dict_bar", "time_step": 0.001, "gravity": [0, 0, -9.81],
        "bodies": [{"name": "block", "mesh": "meshes/cube_tet4_h8p333mm.msh",
                    "material": {"model": "corotational", "young_modulus": 1.0e4, "poisson_ratio": 0.45,
                                 "density": 1000},
                    "fixed": [{"box": {"min": [-1, -1, -1.0e-6], "max": [1, 1, 1.0e-6]}}]}],
    }
    from_dict = stroma.simulation_from_dict(scenario, base_dir=SCENARIOS)
    path = tmp_path / "dict_bar.yaml"
    path.write_text(json_as_yaml(scenario, SCENARIOS))
    from_file = stroma.Simulation(str(path))
    from_dict.step(20)
    from_file.step(20)
    assert np.abs(from_dict.positions - stroma.simulation_from_dict(scenario, SCENARIOS).positions).max() > 0
    assert np.array_equal(from_dict.positions, from_file.positions)
    scenario["bodies"][0]["material"]["young_modulus"] = -1
    with pytest.raises(ValueError) as e:
        stroma.simulation_from_dict(scenario, base_dir=SCENARIOS)
    assert "<dict>:" in str(e.value) and "young" in str(e.value).lower()


def test_a_prestretched_body_starts_as_its_mesh_and_a_reset_returns_to_it():
    """docs/TISSUE.md, "Prestretch": the mesh is the tissue under tension; the state starts as the
    mesh (not the rest shape), the fixed boxes hold it there, the free faces neck in, and a reset
    returns to the mesh. The mesh's nodes are read from the same body without prestretch."""
    def bar(prestretch=None):
        body = {"name": "skin", "mesh": "meshes/cube_tet4_h8p333mm.msh",
                "material": {"young_modulus": 3.0e4, "poisson_ratio": 0.45, "density": 1000, "rayleigh_mass": 30},
                "fixed": [{"box": {"min": [-1, -1, -1], "max": [1.0e-9, 1, 1]}},
                          {"box": {"min": [0.0499999, -1, -1], "max": [1, 1, 1]}}]}
        if prestretch is not None:
            body["prestretch"] = prestretch
        return {"name": "bar", "time_step": 0.001, "gravity": [0, 0, 0], "bodies": [body]}
    mesh = stroma.simulation_from_dict(bar(), SCENARIOS).positions.copy()
    sim = stroma.simulation_from_dict(bar([1.05, 1, 1]), SCENARIOS)
    assert np.array_equal(sim.positions, mesh), "the first state is the mesh"
    sim.step(300)
    x = sim.positions
    assert x[:, 0].min() == 0 and x[:, 0].max() == 0.05, "held at both ends where the mesh has them"
    mid = x[np.abs(x[:, 0] - 0.025) < 0.005]
    extent = mid.max(axis=0) - mid.min(axis=0)
    assert extent[1] < 0.05 - 1e-4 and extent[2] < 0.05 - 1e-4, "the free faces neck in under the tension"
    sim.reset()
    assert np.array_equal(sim.positions, mesh), "a reset returns to the mesh, not the rest shape"
    assert np.array_equal(stroma.simulation_from_dict(bar(1.05), SCENARIOS).positions, mesh), "a number: every axis"
    with pytest.raises(ValueError) as e:
        stroma.simulation_from_dict(bar([1.05, 3, 1]), SCENARIOS)
    assert "<dict>:" in str(e.value) and "prestretch" in str(e.value)


def test_an_incision_where_the_tissue_is_under_tension_gapes():
    """The incision demo's scene (scenarios/liver_incision_tension.yaml, docs/CUTTING.md): the fine
    liver stretched 20 % across the incision and held on its lower face and sides. The blade's
    60 mm incision (trajectories/liver_incision.yaml, lifted out at 1.8 s), 0.7 s later: each DOF
    the cut created (a virtual node at a material node's place, on the other lip) stands from the
    nearest material node at least twice as far as in the same liver without the tension, whose
    lips touch. (Without the scenario's time budget: its wall-clock deadline would vary the run.)"""
    text = (SCENARIOS / "liver_incision_tension.yaml").read_text()
    text = text.replace("liver_incision_open.yaml", "liver_incision.yaml").replace(", time_budget: 0.0008", "")
    assert "prestretch: [1, 1, 1.2]" in text and "time_budget" not in text
    separation = {}
    for tension in (True, False):
        sim = stroma.Simulation(text if tension else text.replace("prestretch: [1, 1, 1.2]", "prestretch: 1"),
                                "liver_incision_tension.yaml", str(SCENARIOS))
        n = sim.num_nodes
        sim.step(2500)
        x = sim.positions
        assert len(x) > n + 10, "the incision split tetrahedra"
        separation[tension] = np.median([np.linalg.norm(x[:n] - p, axis=1).min() for p in x[n:]])
    assert separation[True] > 2 * separation[False], separation


def test_a_thread_is_read_as_its_nodes_and_swings_as_in_stroma_run(tmp_path):
    """docs/THREAD.md: `threads` names each thread's rows of `positions`; the shipped swinging
    suture (scenarios/thread_swing.yaml) steps in Python as in `stroma run` (final_state.csv's
    last rows, bit for bit), hangs from its fixed end after a second, and keeps its length."""
    sim = stroma.Simulation(str(SCENARIOS / "thread_swing.yaml"))
    (t,) = sim.threads
    first, end = t["nodes"]
    assert t["name"] == "suture" and end == sim.num_nodes and end - first == 61
    assert t["segment_length"] == pytest.approx(0.0025)
    start = sim.positions[first:end].copy()
    np.testing.assert_array_equal(t["positions"], start)
    assert t["length"] == pytest.approx(0.15, rel=1e-12)
    sim.step(1000)
    t = sim.threads[0]
    x = sim.positions[first:end]
    np.testing.assert_array_equal(t["positions"], x)
    np.testing.assert_array_equal(x[0], start[0])  # the fixed end
    assert x[-1, 1] < start[0, 1] - 0.1, "it hangs down from its fixed end"
    assert abs(t["length"] / 0.15 - 1) < 1e-3, "a suture barely stretches under its weight"
    tc = sim.metrics["thread_contact"]  # the last tick's thread contacts (docs/THREAD.md, "Contact")
    assert set(tc) == {"tissue", "self", "tools", "rigid", "dropped", "missed", "unchecked"}
    assert tc["unchecked"] == 0, "no deadline here: the continuous check always runs"
    subprocess.run([str(BUILD / "stroma"), "run", str(SCENARIOS / "thread_swing.yaml"), "--out", str(tmp_path),
                    "--quiet", "--no-metrics"], check=True)
    np.testing.assert_array_equal(final_state(tmp_path)[first:end], x)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["thread_contact"]["checks_skipped"] == 0
    assert summary["thread_contact"]["missed_springs_added"] >= 0


# A fixed tissue block far from the knot tests' threads (a scenario needs a tissue body).
_FAR_BLOCK = {"name": "far", "mesh": str(SCENARIOS / "meshes" / "cube_tet4_h5p000mm.msh"), "scale": 0.1,
              "translate": [1, 1, 1], "material": {"young_modulus": 1e4, "poisson_ratio": 0.45, "density": 1000},
              "fixed": [{"box": {"min": [-10, -10, -10], "max": [10, 10, 10]}}]}


def _overhand_lay(scale, tail):
    """An overhand knot laid loose: the trefoil (sin t + 2 sin 2t, cos t - 2 cos 2t, -sin 3t) at
    `scale`, cut open at its bottom lobe (t = pi +- 0.5), each cut end carried by a cubic Bezier
    into a straight tail along -x / +x (as tests/engine/test_thread_knot.cpp lays it)."""
    t = np.linspace(np.pi + 0.5, 3 * np.pi - 0.5, 2001)
    knot = scale * np.stack([np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t), -np.sin(3 * t)], 1)

    def tangent(u):
        d = np.array([np.cos(u) + 4 * np.cos(2 * u), -np.sin(u) + 4 * np.sin(2 * u), -3 * np.cos(3 * u)])
        return d / np.linalg.norm(d)

    def bezier(a, b, c, d, n=3000):
        u = np.linspace(0, 1, n)[:, None]
        return (1 - u) ** 3 * a + 3 * (1 - u) ** 2 * u * b + 3 * (1 - u) * u ** 2 * c + u ** 3 * d

    A, B = knot[0], knot[-1]
    y, arm = A[1] - 1.5 * scale, 1.5 * scale
    fs, fe = np.array([-tail, y, A[2]]), np.array([tail, y, B[2]])
    first = bezier(A, A - arm * tangent(np.pi + 0.5), fs + [tail / 3, 0, 0], fs)[::-1]
    last = bezier(B, B + arm * tangent(3 * np.pi - 0.5), fe - [tail / 3, 0, 0], fe)
    return np.concatenate([first[:-1], knot, last[1:]])


def test_an_overhand_knot_pulled_by_two_graspers_tightens_and_holds():
    """docs/THREAD.md, "Knots", from Python: a 3-0 suture laid loose in an overhand knot, its ends
    held by two graspers driven by set_pose, pulled apart at 20 mm/s each until the right one
    feels 2 N, then held still 0.3 s: the knot tightens (the thread it stores, length along the
    nodes less the ends' distance, falls below a third of the laid) and holds (that length steady
    within 1 %, the force within 5 %), never tighter than a tight open trefoil (10.1 diameters)."""
    lay = _overhand_lay(1e-3, 0.03)
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(lay, axis=0), axis=1))])
    n = int(round(s[-1] / 5e-4))
    q = np.stack([np.interp(np.linspace(0, s[-1], n + 1), s, lay[:, k]) for k in range(3)], 1)
    length = float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())
    grasper = lambda name, at: {"name": name, "shape": {"type": "sphere", "radius": 0.0003},
                                "grasp": {"close": 0.05, "open": 0.1, "stiffness": 1.0e4}, "max_speed": 1.0,
                                "pose": {"position": at.tolist()}}
    sim = stroma.simulation_from_dict({
        "name": "knot", "time_step": 0.001, "gravity": [0, -9.81, 0],
        "solver": {"integrator": "implicit_euler", "preconditioner": "block_jacobi", "tolerance": 1e-10},
        "bodies": [_FAR_BLOCK],
        "tools": [grasper("left", q[0]), grasper("right", q[-1])],
        "threads": [{"name": "suture", "length": length, "segments": n, "diameter": 2e-4, "young_modulus": 5e9,
                     "density": 1100, "damping": {"rayleigh_mass": 20}, "friction": 0.2, "path": q.tolist()}]})
    first, end = sim.threads[0]["nodes"]

    def stored():
        x = sim.positions[first:end]
        return np.linalg.norm(np.diff(x, axis=0), axis=1).sum() - np.linalg.norm(x[-1] - x[0])

    left, right = q[0].copy(), q[-1].copy()
    laid, least, loaded = stored(), stored(), None
    for i in range(4000):
        force = abs(sim.feedback(1)["force"][0])
        if i >= 50 and loaded is None:
            if force >= 2.0:
                loaded = (stored(), force)
            else:
                left[0] -= 2e-5
                right[0] += 2e-5
        if loaded is not None and i >= 50:
            break
        sim.set_pose(0, left.tolist(), jaw=0.0)
        sim.set_pose(1, right.tolist(), jaw=0.0)
        sim.step(1)
        least = min(least, stored())
    assert loaded is not None, "the graspers reached 2 N"
    sim.step(100)  # settle
    held, force = stored(), abs(sim.feedback(1)["force"][0])
    sim.step(300)
    assert laid > 0.02 and held < laid / 3, "the knot tightened"
    assert least > 10.1 * 2e-4, "never tighter than a tight open trefoil"
    assert abs(stored() - held) < 0.01 * held, "it holds: it does not slip"
    assert abs(abs(sim.feedback(1)["force"][0]) - force) < 0.05 * force
    assert force > 1.0


def _knot_determinant(x, seed, far=0.2):
    """The determinant of the knot the open thread `x` makes when its ends are joined outside a ball
    round it (each end out radially from the centroid to `far`, 0.2 m, then along that sphere: any such
    arc gives the same knot): |det| of the Fox colouring matrix of a generic projection, less a
    row and a column — 1 for the unknot, 3 for the trefoil (an overhand or half knot), 9 for a
    square or granny knot; it depends on the knot, not on the projection (`seed` picks one;
    None if that one is degenerate: a glancing crossing or one at a vertex)."""
    c = x.mean(axis=0)
    ends = [(x[-1] - c) / np.linalg.norm(x[-1] - c), (x[0] - c) / np.linalg.norm(x[0] - c)]
    mid = ends[0] + ends[1]
    mid = mid / np.linalg.norm(mid) if np.linalg.norm(mid) > 1e-6 else np.cross(ends[0], [0.3, 0.9, 0.1])
    arc = [(1 - t) * a + t * b for a, b in ((ends[0], mid), (mid, ends[1])) for t in np.linspace(0, 1, 9)]
    P = np.vstack([x] + [c + far * v / np.linalg.norm(v) for v in arc])
    q = np.random.default_rng(seed).normal(size=4)
    w, a, b, d = q / np.linalg.norm(q)
    R = np.array([[1 - 2 * (b * b + d * d), 2 * (a * b - d * w), 2 * (a * d + b * w)],
                  [2 * (a * b + d * w), 1 - 2 * (a * a + d * d), 2 * (b * d - a * w)],
                  [2 * (a * d - b * w), 2 * (b * d + a * w), 1 - 2 * (a * a + b * b)]])
    Q = P @ R.T
    A, B, n = Q, np.roll(Q, -1, axis=0), len(Q)
    cross = []  # (parameter along the curve on the over strand, on the under strand)
    for i in range(n):
        j = np.arange(i + 2, n if i > 0 else n - 1)
        r, s = B[i, :2] - A[i, :2], B[j, :2] - A[j, :2]
        den = r[0] * s[:, 1] - r[1] * s[:, 0]
        qp = A[j, :2] - A[i, :2]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (qp[:, 0] * s[:, 1] - qp[:, 1] * s[:, 0]) / den
            u = (qp[:, 0] * r[1] - qp[:, 1] * r[0]) / den
        for k in np.nonzero((den != 0) & (t >= 0) & (t < 1) & (u >= 0) & (u < 1))[0]:
            if abs(den[k]) < 1e-3 * np.linalg.norm(r) * np.linalg.norm(s[k]) or min(t[k], u[k]) < 1e-9 or max(t[k], u[k]) > 1 - 1e-9:
                return None  # a glancing crossing or one at a vertex: no diagram from this projection
            zi = A[i, 2] + t[k] * (B[i, 2] - A[i, 2])
            zj = A[j[k], 2] + u[k] * (B[j[k], 2] - A[j[k], 2])
            cross.append((i + t[k], j[k] + u[k]) if zi > zj else (j[k] + u[k], i + t[k]))
    if len(cross) < 2:
        return 1
    unders = sorted(c[1] for c in cross)
    m = len(cross)
    M = np.zeros((m, m))
    for row, (over, under) in enumerate(cross):
        k = unders.index(under)  # the under strand's arcs end and start here
        M[row, np.searchsorted(unders, over, side="right") % m] += 2
        M[row, k] -= 1
        M[row, (k + 1) % m] -= 1
    return int(round(abs(np.linalg.det(M[:-1, :-1]))))


def _knot(x, far=0.2):
    """The knot determinant in the first three projections that are not degenerate."""
    d = [k for k in (_knot_determinant(x, seed, far) for seed in range(20)) if k is not None][:3]
    assert len(d) == 3
    return d


def test_the_knot_determinant_tells_a_trefoil_from_an_unknot():
    """The test's own knot check against known knots, opened at an outermost point and closed
    far away: the (2,3) torus knot (the trefoil) 3, the (2,5) 5, a circle 1."""
    t = np.linspace(0, 2 * np.pi, 500, endpoint=False)[:490]
    torus = lambda p, q: np.stack([(2 + np.cos(q * t)) * np.cos(p * t), (2 + np.cos(q * t)) * np.sin(p * t), np.sin(q * t)], 1)
    assert _knot(torus(2, 3), far=100) == [3, 3, 3]
    assert _knot(torus(2, 5), far=100) == [5, 5, 5]
    assert _knot(torus(1, 0), far=100) == [1, 1, 1]


def test_an_instrument_tie_throws_a_half_knot_round_a_rod():
    """docs/THREAD.md, "Knots": the first throw of an instrument tie, scripted through set_pose. A
    3-0 suture passes under a fixed 2 mm rod; grasper A holds its long end, B — a needle holder
    with a 2 mm tip and shaft — holds the short end at its tip. B's shaft lies over the rod,
    parallel to it; A wraps its strand once round the shaft; B draws back along its shaft, so the
    wrap slides off its tip onto the short end; both pull apart to 1 N. The thread, unknotted
    before (knot determinant 1), is then a half knot round the rod: closed far away, a trefoil
    (determinant 3, in three projections), its loop still round the rod."""
    RR = 0.001 + 1e-4 + 5e-5
    path = [np.array([-0.004, 0.018, 0]) + (np.array([-RR, 0, 0]) - [-0.004, 0.018, 0]) * u for u in np.linspace(0, 1, 200)]
    path += [np.array([RR * np.cos(a), RR * np.sin(a), 0]) for a in np.linspace(np.pi, 2 * np.pi, 200)[1:]]
    path += [np.array([RR, 0, 0]) + (np.array([0.004, 0.009, 0]) - [RR, 0, 0]) * u for u in np.linspace(0, 1, 200)[1:]]
    lay = np.array(path)
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(lay, axis=0), axis=1))])
    n = int(round(s[-1] / 5e-4))
    q = np.stack([np.interp(np.linspace(0, s[-1], n + 1), s, lay[:, k]) for k in range(3)], 1)
    grasp = {"close": 0.05, "open": 0.1, "stiffness": 1.0e4}
    sim = stroma.simulation_from_dict({
        "name": "tie", "time_step": 0.001, "gravity": [0, -9.81, 0],
        "solver": {"integrator": "implicit_euler", "preconditioner": "block_jacobi", "tolerance": 1e-8},
        "bodies": [_FAR_BLOCK],
        "rigid_bodies": [{"name": "rod", "shape": {"type": "capsule", "radius": 0.001, "length": 0.1},
                          "density": 1000, "fixed": True, "pose": {"position": [0, 0, 0]}}],
        "tools": [{"name": "A", "shape": {"type": "sphere", "radius": 0.0003}, "grasp": grasp, "max_speed": 1.0,
                   "pose": {"position": q[0].tolist()}},
                  {"name": "B", "shape": {"type": "probe", "radius": 0.001, "length": 0.03}, "grasp": grasp,
                   "max_speed": 1.0, "pose": {"position": q[-1].tolist()}}],
        "threads": [{"name": "suture", "length": float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum()),
                     "segments": n, "diameter": 2e-4, "young_modulus": 5e9, "density": 1100,
                     "damping": {"rayleigh_mass": 20}, "friction": 0.2, "path": q.tolist()}]})
    first, end = sim.threads[0]["nodes"]
    x = lambda: np.array(sim.positions[first:end])
    pose = {"A": q[0].copy(), "B": q[-1].copy()}
    bad = []

    def step(a=None, b=None):
        if a is not None:
            pose["A"] = np.asarray(a, float)
        if b is not None:
            pose["B"] = np.asarray(b, float)
        sim.set_pose(0, pose["A"].tolist(), jaw=0.0)
        sim.set_pose(1, pose["B"].tolist(), jaw=0.0)  # B's shaft along +z: identity orientation
        sim.step(1)
        if sim.metrics["status"] not in (0, 1):
            bad.append(sim.metrics["status"])

    def line(who, to, speed):
        start = pose[who].copy()
        ticks = max(1, int(round(np.linalg.norm(np.asarray(to) - start) / speed * 1000)))
        for i in range(1, ticks + 1):
            p = start + (np.asarray(to) - start) * i / ticks
            step(a=p if who == "A" else None, b=p if who == "B" else None)

    for _ in range(50):
        step()
    assert _knot(x()) == [1, 1, 1]
    H, RW, ZW = 0.008, 0.004, 0.004
    line("B", [0, H, 0], 0.03)  # the tip over the rod, the shaft along +z beside it
    ring = lambda a: np.array([RW * np.cos(a), H + RW * np.sin(a), ZW])
    line("A", ring(np.pi) + [-0.002, 0.003, 0], 0.03)
    line("A", ring(np.pi), 0.03)
    ticks = int(round(2.25 * np.pi * RW / 0.03 * 1000))
    for i in range(1, ticks + 1):  # over the shaft, down behind it, under, up: one wrap and a quarter
        step(a=ring(np.pi - 2.25 * np.pi * i / ticks))
    while np.linalg.norm(sim.feedback(0)["force"]) < 0.05:  # A takes up the slack
        step(a=pose["A"] + [-1e-5, 2e-6, 0])
    line("B", pose["B"] + [0, 0, 0.009], 0.02)  # B draws back along its shaft: the wrap leaves its tip
    for _ in range(3000):  # both pull apart to 1 N
        if max(np.linalg.norm(sim.feedback(k)["force"]) for k in (0, 1)) >= 1.0:
            break
        step(a=pose["A"] + [-2e-5, -4e-6, 0], b=pose["B"] + [2e-5, -4e-6, 0])
    else:
        pytest.fail("the graspers never felt 1 N")
    assert not bad
    assert _knot(x()) == [3, 3, 3], "a half knot: closed far away, a trefoil"
    # its loop still goes round the rod: under it, the ends above it
    xs = x()
    under = xs[np.abs(xs[:, 0]) < 0.0015]
    assert under[:, 1].min() < -0.001 and xs[0, 1] > 0 and xs[-1, 1] > 0


def test_a_thread_drawn_through_the_tissue_lists_its_punctures():
    """docs/THREAD.md, "Through the tissue": a needle with a suture tied to its tail, driven through
    the 50 mm block by one grasper and pulled on by a second (tests/data/thread_draw_through.yaml,
    scripted here through set_pose as the C++ test scripts it), leaves the thread through the
    entry and the exit: `threads[0]["punctures"]` lists both, in the block, the thread's point at
    each (sigma) at the material point, at the arc length the needle travelled past it."""
    sim = stroma.Simulation(str(SOURCE / "tests" / "data" / "thread_draw_through.yaml"))
    assert sim.threads[0]["punctures"] == []
    along_x = [0.5 ** 0.5, 0, 0.5 ** 0.5, 0]

    def ramp(t, t0, t1, a, b):
        return a if t <= t0 else b if t >= t1 else a + (b - a) * (t - t0) / (t1 - t0)

    for i in range(4000):
        t = 0.001 * i
        sim.set_pose(0, [ramp(t, 0.05, 1.675, -0.0825, -0.0175), 0.03, 0.025], along_x, 0.0 if t < 1.75 else 0.3)
        sim.set_pose(1, [ramp(t, 1.8, 3.8, 0.054, 0.134), 0.03, 0.025], along_x, 0.3 if t < 1.7 else 0.0)
        sim.step()
    (thread,) = sim.threads
    punctures = thread["punctures"]
    assert len(punctures) == 2, "the entry and the exit"
    tail_x = thread["positions"][0, 0]
    for p, x in zip(punctures, [0.0, 0.05]):
        assert p["body"] == "block"
        assert p["point"][0] == pytest.approx(x, abs=0.003)
        assert p["sigma"] * thread["segment_length"] == pytest.approx(tail_x - p["point"][0], abs=0.004)


def json_as_yaml(scenario, base_dir):
    """The scenario as a YAML file elsewhere: JSON is YAML; the mesh path made absolute."""
    import copy
    import json
    s = copy.deepcopy(scenario)
    for b in s["bodies"]:
        b["mesh"] = str(pathlib.Path(base_dir) / b["mesh"])
    return json.dumps(s)


def test_set_positions_validates_and_moves_the_nodes():
    sim = stroma.Simulation(str(SCENARIOS / "cantilever_dynamic.yaml"))
    x = sim.positions.copy()
    with pytest.raises(ValueError):
        sim.set_positions(x[:-1])
    bad = x.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError) as e:
        sim.set_positions(bad)
    assert "entry 3" in str(e.value)
    assert np.array_equal(sim.positions, x), "a refused array changes nothing"
    moved = x + np.array([0.0, 0.0, 1e-3])
    sim.set_positions(moved)
    assert np.array_equal(sim.positions, moved)


def test_damage_view_metrics_and_stage_times():
    sim = stroma.Simulation(str(SCENARIOS / "regression" / "liver_probe_damage.yaml"))
    d = sim.damage
    assert d.dtype == np.float32 and not d.flags.writeable and d.max() == 0
    sim.step(2500)  # the scripted deep press damages the liver
    assert d.max() > 0, "the view follows the damage"
    assert sim.damage_counts[0] > 0
    m = sim.metrics
    assert "solve" in m["stage_ms"] and m["stage_ms"]["solve"] >= 0
    assert stroma.Simulation(str(SCENARIOS / "cantilever_dynamic.yaml")).damage.size == 0


def test_step_releases_the_gil():
    import threading
    sim = stroma.Simulation(str(SCENARIOS / "regression" / "liver_probe_press.yaml"))
    t = threading.Thread(target=sim.step, args=(1500,))
    count = 0
    t.start()
    while t.is_alive():
        count += 1
    t.join()
    assert sim.steps == 1500
    assert count > 1000, "Python ran while the engine stepped"


def test_the_press_environment_reaches_its_target_force_and_ends_on_damage():
    from stroma.env import ProbePressEnv
    env = ProbePressEnv(target_force=1.0)
    obs, info = env.reset(seed=0)
    assert obs.shape == (4,) and isinstance(info, dict)
    a = -1.0
    for _ in range(env.max_steps):
        # An integral controller on the target height: down until touching, then on the force error.
        a = float(np.clip(a + (0.02 if obs[1] <= 0 else 1e-3 * (1.0 - obs[1])), -1, 1))
        obs, reward, terminated, truncated, info = env.step([a])
        assert not terminated
        if truncated:
            break
    assert truncated
    assert abs(obs[1] - 1.0) < 0.2, "pressed to the target force"
    assert obs[2] == 0, "without damage"
    # Pushed to the bottom of its travel, it damages the liver and the episode ends.
    obs, _ = env.reset()
    terminated = False
    for _ in range(env.max_steps):
        obs, reward, terminated, truncated, info = env.step([1.0])
        if terminated:
            break
    assert terminated and reward <= -10 and obs[2] > 0


def check_env_rules(env):
    """What gymnasium.utils.env_checker.check_env checks, for where gymnasium is not installed:
    spaces, reset(seed) determinism, observations inside their space with its dtype, the step
    tuple's types, and that an action sampled from the space is accepted."""
    for space in (env.action_space, env.observation_space):
        assert hasattr(space, "low") and hasattr(space, "high") and space.low.shape == space.shape
        assert np.all(space.low <= space.high)
    obs1, info1 = env.reset(seed=42)
    obs2, _ = env.reset(seed=42)
    assert isinstance(info1, dict)
    assert np.array_equal(obs1, obs2), "reset(seed) is deterministic"
    assert obs1.dtype == env.observation_space.dtype and env.observation_space.contains(obs1), obs1
    a = env.action_space.sample()
    assert env.action_space.contains(a) and a.dtype == env.action_space.dtype
    out = env.step(a)
    assert len(out) == 5
    obs, reward, terminated, truncated, info = out
    assert env.observation_space.contains(obs) and obs.dtype == env.observation_space.dtype
    assert isinstance(reward, float) and isinstance(terminated, bool) and isinstance(truncated, bool)
    assert isinstance(info, dict)
    env.reset(seed=7)
    first = [env.action_space.sample() for _ in range(5)]
    env.reset(seed=7)
    assert all(np.array_equal(p, q) for p, q in zip(first, [env.action_space.sample() for _ in range(5)])), \
        "the action space is seeded by reset(seed)"


def test_the_environment_follows_gymnasium_s_rules():
    from stroma.env import ProbePressEnv
    env = ProbePressEnv()
    check_env_rules(env)
    try:
        from gymnasium.utils.env_checker import check_env
    except ImportError:
        return  # gymnasium is optional (not a Debian package): the rules above are its checks
    check_env(env, skip_render_check=True)


def test_invalid_actions_are_refused_and_a_random_policy_touches_the_tissue():
    from stroma.env import ProbePressEnv
    env = ProbePressEnv()
    obs, _ = env.reset(seed=1)
    for bad in ([np.nan], [np.inf], [2.0], [[0.1, 0.2]]):  # reject policy: out of the box is refused too
        obs, reward, terminated, truncated, info = env.step(bad)
        assert np.isfinite(obs).all() and np.isfinite(reward), f"a refused action {bad} poisoned the observation"
        assert obs[0] == 0, "refused: the probe holds its height"
    assert info["refused_actions"] == 4
    obs, reward, *_ = env.step([0.0])
    assert np.isfinite(obs).all() and obs[0] < 0, "a valid action after refused ones moves the probe"
    # Uniform random actions reach the tissue and move the reward (issue 41 §4: they never did).
    env.reset(seed=3)
    forces, rewards = [], []
    for _ in range(200):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        forces.append(obs[1])
        rewards.append(reward)
        if terminated or truncated:
            break
    assert max(forces) > 0.05, "a random policy never touched the tissue"
    assert np.ptp(rewards) > 0.05, "the reward never moved"
    assert info["refused_actions"] == 0


def test_a_snapshot_keeps_the_poses_set_from_python():
    # Issue 41 §5: a restored simulation followed the tool's script again (0.28 units off).
    scenario = str(SCENARIOS / "regression" / "liver_probe_press.yaml")
    sim = stroma.Simulation(scenario)
    sim.step(20)
    assert sim.set_pose(0, [-1.5, 6.95, 0.5]) == "accepted"  # near the script's pose (6.966): within max_speed
    sim.step(10)
    snap = sim.snapshot()
    other = stroma.Simulation(scenario)
    other.restore(pickle.loads(pickle.dumps(snap)))
    sim.step(1500)  # the script would press the liver from t = 1.0 s on; the posed probe stays above it
    other.step(1500)
    assert np.array_equal(sim.positions, other.positions), "the restored run holds the pose set from Python"
    scripted = stroma.Simulation(scenario)
    scripted.step(1530)
    assert not np.array_equal(scripted.positions, sim.positions), "the pose set differs from the script's"


def test_a_pickled_snapshot_restores_in_another_simulation_bit_for_bit():
    # A cut liver mid-incision: the other Simulation has only the uncut model, and must rebuild
    # the cut one from the snapshot's edge cuts; tools, warm start and time travel too.
    scenario = str(SCENARIOS / "regression" / "liver_incision.yaml")
    sim = stroma.Simulation(scenario)
    n0 = sim.num_nodes
    sim.step(1250)
    n_mid = sim.num_nodes
    assert n_mid > n0, "cut by 1.25 s"
    snap = pickle.loads(pickle.dumps(sim.snapshot()))
    assert snap.steps == 1250 and snap.time == sim.time
    other = stroma.Simulation(scenario)
    other.restore(snap)
    assert other.num_nodes == n_mid and other.steps == 1250
    assert np.array_equal(other.positions, sim.positions)
    sim.step(500)
    other.step(500)
    assert sim.num_nodes > n_mid, "the incision went on after the snapshot"
    assert other.num_nodes == sim.num_nodes
    assert np.array_equal(other.positions, sim.positions), "both cut on and step alike"
    # A probe in contact, with damage: force and damage carry over.
    scenario = str(SCENARIOS / "regression" / "liver_probe_damage.yaml")
    a, b = stroma.Simulation(scenario), stroma.Simulation(scenario)
    a.step(1200)
    b.restore(pickle.loads(pickle.dumps(a.snapshot())))
    assert np.array_equal(b.damage, a.damage)
    a.step(300)
    b.step(300)
    assert a.feedback(0)["force"] == b.feedback(0)["force"] and np.abs(a.feedback(0)["force"]).max() > 0
    assert np.array_equal(a.positions, b.positions)


def test_stiffness_every_n_steps_is_state_a_pickled_snapshot_replays_it_across_a_cut(tmp_path):
    # solver.stiffness_every (README): the element stiffness in use and the share being made are
    # in the state, so a snapshot taken mid-cycle, after the scalpel cut, restores bit for bit.
    source = (SCENARIOS / "regression" / "liver_incision.yaml").read_text()
    assert "tolerance: 1.0e-8}" in source
    text = source.replace("tolerance: 1.0e-8}", "tolerance: 1.0e-8, stiffness_every: 3}").replace("../", str(SCENARIOS) + "/")
    path = tmp_path / "lagged.yaml"
    path.write_text(text)
    sim = stroma.Simulation(str(path))
    n0 = sim.num_nodes
    sim.step(1251)
    assert sim.num_nodes > n0, "cut by 1.25 s"
    snap = pickle.loads(pickle.dumps(sim.snapshot()))
    other = stroma.Simulation(str(path))
    other.restore(snap)
    sim.step(400)
    other.step(400)
    assert np.array_equal(other.positions, sim.positions)
    plain = stroma.Simulation(str(SCENARIOS / "regression" / "liver_incision.yaml"))
    plain.step(1651)
    assert plain.num_nodes == sim.num_nodes
    assert not np.array_equal(plain.positions, sim.positions), "the lagged stiffness is in effect"
    assert np.abs(plain.positions - sim.positions).max() < 1e-5, "and changes the motion little (< 10 µm)"
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("stiffness_every: 3", "stiffness_every: 0"))
    with pytest.raises(ValueError) as e:
        stroma.Simulation(str(bad))
    assert "bad.yaml:" in str(e.value) and "stiffness_every" in str(e.value)


def test_a_snapshot_of_another_scenario_or_corrupt_bytes_is_refused():
    liver = stroma.Simulation(str(SCENARIOS / "liver.yaml"))
    beam = stroma.Simulation(str(SCENARIOS / "cantilever_dynamic.yaml"))
    beam.step(5)
    before = beam.positions.copy()
    with pytest.raises(ValueError, match="another scenario"):
        beam.restore(pickle.loads(pickle.dumps(liver.snapshot())))
    assert np.array_equal(beam.positions, before) and beam.steps == 5, "nothing changed"
    data = pickle.dumps(beam.snapshot())
    blob = bytearray(beam.snapshot().__getstate__())
    with pytest.raises(ValueError, match="truncated"):
        stroma.Snapshot.__new__(stroma.Snapshot).__setstate__(bytes(blob[:-3]))
    blob[0:6] = b"NOTSTR"
    with pytest.raises(ValueError, match="magic"):
        stroma.Snapshot.__new__(stroma.Snapshot).__setstate__(bytes(blob))
    beam.restore(pickle.loads(data))
    assert beam.steps == 5


def test_parallel_rollouts_equal_serial_ones():
    example = SOURCE / "examples" / "python" / "parallel_rollouts.py"
    r = subprocess.run([sys.executable, str(example), "--processes", "2", "--speeds", "0.1", "0.4", "--ticks", "600",
                        "--check"], capture_output=True, text=True, env=dict(os.environ), timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "parallel = serial, bit for bit" in r.stdout
    forces = [float(line.split("peak force")[1].split(",")[0]) for line in r.stdout.splitlines() if "peak force" in line]
    assert len(forces) == 2 and 0 < forces[0] < forces[1], "a deeper press pushes back harder: " + r.stdout


def test_rigid_bodies_are_read_as_poses_velocities_and_contacts():
    """`rigid_poses` (k, 7) and `rigid_velocities` (k, 6) follow the state as positions does
    (steps, restore); `rigid_bodies` names them with their mass and last tick's contacts. A ball
    falls as implicit Euler says, lands on the tissue block and is pushed back up."""
    scenario = {
        "name": "ball_on_block", "time_step": 0.001, "gravity": [0, 0, -9.81],
        "solver": {"preconditioner": "block_jacobi", "tolerance": 1.0e-10},
        "bodies": [{"name": "block", "mesh": "meshes/cube_tet4_h8p333mm.msh",
                    "material": {"young_modulus": 1.0e4, "poisson_ratio": 0.45, "density": 1000},
                    "fixed": [{"box": {"min": [-1, -1, -1.0e-6], "max": [1, 1, 1.0e-6]}}]}],
        "rigid_bodies": [{"name": "ball", "shape": {"type": "sphere", "radius": 0.005}, "density": 1200,
                          "pose": {"position": [0.025, 0.025, 0.06]}},
                         {"name": "post", "shape": {"type": "box", "size": [0.01, 0.01, 0.01]}, "density": 1000,
                          "pose": {"position": [0.3, 0, 0]}, "fixed": True}],
    }
    sim = stroma.simulation_from_dict(scenario, base_dir=SCENARIOS)
    poses = sim.rigid_poses
    assert poses.shape == (2, 7) and sim.rigid_velocities.shape == (2, 6)
    assert not poses.flags.writeable
    np.testing.assert_array_equal(poses[0], [0.025, 0.025, 0.06, 1, 0, 0, 0])
    bodies = sim.rigid_bodies
    assert [b["name"] for b in bodies] == ["ball", "post"] and bodies[1]["fixed"]
    assert bodies[0]["mass"] == pytest.approx(1200 * 4 / 3 * np.pi * 0.005 ** 3, rel=1e-12)
    n, h = 20, 0.001
    sim.step(n)
    # Free fall over 20 ticks (2 mm: the block's top is at 0.05, the ball's bottom still above it).
    assert poses[0, 2] == pytest.approx(0.06 - 9.81 * h * h * n * (n + 1) / 2, abs=1e-12)
    assert sim.rigid_velocities[0, 2] == pytest.approx(-9.81 * n * h, abs=1e-12)
    before = sim.snapshot()
    z_before = poses[0, 2]
    sim.step(280)  # lands (at ~0.03 s) and is pushed back
    assert poses[0, 2] - 0.005 > 0.045, "the ball rests on the block, not through it"
    assert sim.rigid_bodies[0]["contacts"] > 0
    assert sim.rigid_bodies[0]["contact_force"][2] > 0
    np.testing.assert_array_equal(sim.rigid_poses[1], [0.3, 0, 0, 1, 0, 0, 0])
    sim.restore(pickle.loads(pickle.dumps(before)))
    assert poses[0, 2] == z_before


def test_a_needle_is_read_with_its_phase_and_track():
    """A needle's `rigid_bodies[k]["needle"]` (docs/NEEDLE.md): outside, then — driven in by the
    shipped scenario's grasper — inserted, with its track's tissue points on the needle's axis and
    the force along it cutting + friction × inserted length; a snapshot restores the track."""
    sim = stroma.Simulation(str(SCENARIOS / "needle_insertion.yaml"))
    needle = sim.rigid_bodies[0]
    assert needle["shape"] == "needle" and needle["needle"]["phase"] == "outside"
    assert needle["needle"]["track"].shape == (0, 3)
    sim.step(400)
    n = sim.rigid_bodies[0]["needle"]
    assert n["phase"] == "inserted" and n["punctures"] == 1
    track = n["track"]
    assert track.shape[0] >= 2 and len(n["track_s"]) == track.shape[0]
    # The track is on the needle's axis (its body z through its centre of mass), in the block.
    x, (w, qx, qy, qz) = sim.rigid_poses[0, :3], sim.rigid_poses[0, 3:]
    axis = np.array([2 * (qx * qz + w * qy), 2 * (qy * qz - w * qx), 1 - 2 * (qx * qx + qy * qy)])
    off = (track - x) - np.outer((track - x) @ axis, axis)
    assert np.abs(off).max() < 2e-6
    assert (track[:, 1] < 0.0505).all()
    assert n["tip_force"] == pytest.approx(0.15, rel=1e-6)  # the scenario's cutting force
    assert n["friction_force"] == pytest.approx(-3 * n["inserted_length"], rel=0.05)
    before = sim.snapshot()
    sim.step(100)
    assert sim.rigid_bodies[0]["needle"]["track"].shape[0] >= track.shape[0]
    sim.restore(pickle.loads(pickle.dumps(before)))
    np.testing.assert_array_equal(sim.rigid_bodies[0]["needle"]["track"], track)


def test_a_needle_through_an_incisions_lips_and_its_snapshot():
    """Cutting and a needle in one scenario (docs/NEEDLE.md, the suture demo's): the scalpel's
    incision, then the needle turned across it — in through the near lip, out of its cut face,
    into the far lip and out: four punctures. A pickled snapshot of the cut model with the needle
    in both lips restores after a reset (the cut model rebuilt from its edge cuts) with the same
    track, and steps on bit for bit (without the scenario's time budget, whose wall-clock deadline
    would cut the solves differently each run)."""
    text = (SCENARIOS / "liver_suture.yaml").read_text().replace(", time_budget: 0.0008", "")
    assert "time_budget" not in text
    sim = stroma.Simulation(text, "liver_suture.yaml", str(SCENARIOS))
    sim.step(6000)  # the incision (to 2.0 s), the needle across it (3.4 .. 6.6 s)
    n = sim.rigid_bodies[0]["needle"]
    assert n["punctures"] == 4 and n["phase"] == "exited"
    track = n["track"].copy()
    before = pickle.dumps(sim.snapshot())
    sim.step(200)
    after = sim.rigid_bodies[0]["needle"]["track"].copy()
    sim.reset()
    assert sim.rigid_bodies[0]["needle"]["phase"] == "outside"
    sim.restore(pickle.loads(before))
    np.testing.assert_array_equal(sim.rigid_bodies[0]["needle"]["track"], track)
    sim.step(200)
    np.testing.assert_array_equal(sim.rigid_bodies[0]["needle"]["track"], after)


def test_a_bad_thread_contact_stiffness_raises_with_file_line_and_field(tmp_path):
    """The thread's `contact_stiffness` (docs/THREAD.md, "Contact") is checked by the one loader:
    from Python the same file:line:field error as from `stroma run`."""
    mesh = SCENARIOS / "meshes" / "cube_tet4_h8p333mm.msh"
    bad = tmp_path / "bad_thread.yaml"
    bad.write_text("name: bad\nbodies:\n  - name: block\n    mesh: %s\n"
                   "    material: {young_modulus: 3.0e4, poisson_ratio: 0.45, density: 1000}\n"
                   "threads:\n  - name: suture\n    length: 0.04\n    segments: 20\n    diameter: 2.0e-4\n"
                   "    young_modulus: 5.0e9\n    density: 1100\n    start: [0, 0.1, 0]\n"
                   "    contact_stiffness: -1\n" % mesh)
    with pytest.raises(ValueError) as e:
        stroma.Simulation(str(bad))
    assert "bad_thread.yaml:14: threads[0].contact_stiffness" in str(e.value)
    cli = subprocess.run([str(BUILD / "stroma"), "run", str(bad), "--out", str(tmp_path / "out"), "--quiet"],
                         capture_output=True, text=True)
    assert cli.returncode == 2
    assert "bad_thread.yaml:14: threads[0].contact_stiffness" in cli.stderr


def test_a_braided_threads_bending_stiffness_is_read_and_checked_by_every_front_end(tmp_path):
    """`bending_stiffness` (docs/THREAD.md, "Braided sutures"): read, it sets the rod's bending
    stiffness EI/l^3 (Python's view of the thread); above the solid rod's E*pi*d^4/64 it is the
    one loader's file:line:field error — from Python, `stroma run` and `stroma serve` alike."""
    mesh = SCENARIOS / "meshes" / "cube_tet4_h8p333mm.msh"
    text = ("name: braid\nbodies:\n  - name: block\n    mesh: %s\n"
            "    material: {young_modulus: 3.0e4, poisson_ratio: 0.45, density: 1000}\n"
            "threads:\n  - name: suture\n    length: 0.04\n    segments: 20\n    diameter: 2.0e-4\n"
            "    young_modulus: 5.0e9\n    density: 1100\n    start: [0, 0.1, 0]\n"
            "    bending_stiffness: %s\n")
    good = tmp_path / "braid.yaml"
    good.write_text(text % (mesh, "1.0e-8"))
    t = stroma.Simulation(str(good)).threads[0]
    assert t["bend_stiffness"] == pytest.approx(1e-8 / 0.002 ** 3, rel=1e-12)
    assert t["stretch_stiffness"] == pytest.approx(5e9 * np.pi * 1e-8 / 0.002, rel=1e-12)
    bad = tmp_path / "bad_braid.yaml"
    bad.write_text(text % (mesh, "1.0e-6"))
    where = "bad_braid.yaml:14: threads[0].bending_stiffness"
    with pytest.raises(ValueError) as e:
        stroma.Simulation(str(bad))
    assert where in str(e.value) and "more than a solid rod" in str(e.value)
    for cmd in (["run", str(bad), "--out", str(tmp_path / "out"), "--quiet"],
                ["serve", str(bad), "--domain", "147", "--duration", "1", "--realtime", "off"]):
        cli = subprocess.run([str(BUILD / "stroma")] + cmd, capture_output=True, text=True, timeout=60)
        assert cli.returncode == 2, cmd
        assert where in cli.stderr, cmd


@pytest.fixture(scope="module")
def stitch_env():
    """The stitch environment, made once for its tests (the scripted stitch runs ~15 s)."""
    from stroma.stitch_env import StitchEnv
    return StitchEnv()


def test_the_stitch_environment_closes_the_wound_and_fails_on_too_much_tension(stitch_env):
    env = stitch_env
    obs, info = env.reset(seed=0)
    assert obs.shape == (8,) and env.observation_space.contains(obs)
    assert obs[6] > 1e-3, "the wound gapes at the start (the needle's points on the two cut faces)"
    assert np.array_equal(obs[:3], np.zeros(3))
    # Pulling the needle up and towards the far side draws the thread tight: the gap closes
    # (reward = the fraction closed), then the tension passes max_tension and the stitch fails.
    best_gap, rewards, terminated = obs[6], [], False
    for _ in range(env.max_steps):
        obs, reward, terminated, truncated, info = env.step([0.0, 1.0, 0.5])
        rewards.append(reward)
        best_gap = min(best_gap, obs[6])
        if terminated or truncated:
            break
    assert best_gap < 0.5e-3, f"the pull closed the gap (to {best_gap * 1e3:.3f} mm)"
    assert max(rewards) > 0.7
    assert terminated and rewards[-1] < -9, "beyond max_tension the episode ends as a failure"
    assert np.linalg.norm(obs[3:6]) > env.max_tension
    # A reset is a snapshot restored: the same actions give the same episode, bit for bit.
    first, _ = env.reset(seed=0)
    a = [env.step([0.3, 0.8, -0.2])[0] for _ in range(5)]
    again, _ = env.reset(seed=0)
    b = [env.step([0.3, 0.8, -0.2])[0] for _ in range(5)]
    assert np.array_equal(first, again) and all(np.array_equal(p, q) for p, q in zip(a, b))


def test_the_stitch_environment_follows_gymnasium_s_rules_and_refuses_bad_actions(stitch_env):
    env = stitch_env
    check_env_rules(env)
    obs, _ = env.reset(seed=3)
    for bad in ([np.nan, 0, 0], [0, np.inf, 0], [[0.1, 0.2]]):
        obs, reward, terminated, truncated, info = env.step(bad)
        assert np.isfinite(obs).all() and np.isfinite(reward), f"a refused action {bad} poisoned the observation"
    assert info["refused_actions"] == 3
    assert np.array_equal(obs[:3], np.zeros(3)), "a refused action holds the grasper"
    try:
        from gymnasium.utils.env_checker import check_env
    except ImportError:
        return
    check_env(env, skip_render_check=True)


def test_the_stitch_environment_refuses_a_scenario_without_its_stitch(tmp_path):
    from stroma.stitch_env import StitchEnv
    with pytest.raises(ValueError, match="tool named 'grasper'"):
        StitchEnv(scenario=str(SCENARIOS / "cantilever_dynamic.yaml"))


def test_feedback_and_tool_pose_after_a_restore_are_the_restored_state_s():
    sim = stroma.Simulation(str(SCENARIOS / "regression" / "liver_probe_press.yaml"))
    sim.step(1200)  # the scripted probe presses the liver
    f1, p1 = sim.feedback(0)["force"], sim.tool_pose(0)
    assert np.linalg.norm(f1) > 0, "pressing"
    snap = sim.snapshot()
    sim.step(300)
    assert sim.feedback(0)["force"] != f1
    sim.restore(snap)
    assert sim.feedback(0)["force"] == f1, "the force of the step the snapshot was taken after"
    assert sim.tool_pose(0) == p1
    sim.reset()
    assert sim.feedback(0)["force"] == [0.0, 0.0, 0.0], "a reset run has no tick of the last one"
    with pytest.raises(IndexError):
        sim.tool_pose(5)
