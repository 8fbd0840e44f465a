#!/usr/bin/env python3
"""Writes the suture demo's two tool scripts (scenarios/trajectories/liver_suture_*.yaml) for
scenarios/liver_suture.yaml: a scalpel incises the fine 16 cm liver along x at z = 12.5 mm; a
grasper then drives a half-circle needle (R 15 mm) across the incision as surgeons do — turned
about the arc's centre, entering one lip's outer surface, out through its cut face, into the
other lip's and out of its outer surface — lets go of it, regrasps it near the tip where it came
out and turns it on through until the tail is out, then lifts it away.

The needle's arc is in the world y-z plane (across the incision): its shape frame has z along
world -x (so turning it by psi about its centre drives the tip along its own arc, from -z to +z
under the centre), the tail at angle psi and the tip at psi + 180 degrees. The grasper's axis is
the shape frame's z too; its jaws' centre is 5 mm along it from its position.

The suture demo with its thread (scenarios/liver_suture_thread.yaml) has its own grasper script
(liver_suture_thread_grasper.yaml): the same stitch, then the needle pulled on to draw the thread
tight, and held.

Usage: scripts/suture_trajectories.py   (rewrites the three files; no arguments)
"""
import math
import os

XC, YC, ZC = -0.015, 0.129, 0.0125  # the arc's centre when in place (above the incision's middle, 7 mm
                                     # over the prestretched surface as it settles)
R = 0.015                            # the needle's arc radius (m)
JAW = 0.005                          # the jaws' centre from the grasper's position, along its axis
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenarios", "trajectories")


def quat(psi):
    """B * Rz(psi), B = rotation about y by -90 degrees (shape x -> world z, shape z -> world -x)."""
    b = (math.cos(-math.pi / 4), 0.0, math.sin(-math.pi / 4), 0.0)
    r = (math.cos(psi / 2), 0.0, 0.0, math.sin(psi / 2))
    w1, x1, y1, z1 = b
    w2, x2, y2, z2 = r
    return (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2)


def grip(psi, local, centre=(XC, YC, ZC), back=0.0):
    """The grasper's position holding the needle (turned by psi) at arc angle `local` from its
    tail: the arc point C + R (y: sin, z: cos) of world angle psi + local, moved JAW + back along
    +x (the grasper's axis points along -x)."""
    a = psi + local
    return (centre[0] + JAW + back, centre[1] + R * math.sin(a), centre[2] + R * math.cos(a))


def fmt(t, p, q, jaw):
    return ("  - {t: %.4f, position: [%.6f, %.6f, %.6f], orientation: [%.9f, %.9f, %.9f, %.9f], jaw: %.2f}"
            % (t, p[0], p[1], p[2], q[0], q[1], q[2], q[3], jaw))


def grasper():
    d = math.radians
    keys = []
    first, near_tail, near_tip = d(25), d(11.5), d(165)
    aside = (XC, YC + 0.02, ZC - 0.04)  # off the blade's path while the scalpel cuts
    keys.append((0.0, grip(first, near_tail, aside), quat(first), 0.0))
    keys.append((2.8, grip(first, near_tail, aside), quat(first), 0.0))
    keys.append((3.4, grip(first, near_tail), quat(first), 0.0))
    # Through both lips: psi 25 -> 175 degrees (the tip in at about 37, out at about 323 - 180).
    turn_end = d(175)
    n = 75
    for i in range(1, n + 1):
        psi = first + (turn_end - first) * i / n
        keys.append((3.4 + 3.2 * i / n, grip(psi, near_tail), quat(psi), 0.0))
    t = 6.6
    keys.append((t + 0.4, grip(turn_end, near_tail), quat(turn_end), 0.0))
    keys.append((t + 0.5, grip(turn_end, near_tail), quat(turn_end), 0.3))  # let go
    keys.append((t + 0.8, grip(turn_end, near_tail, back=0.01), quat(turn_end), 0.3))  # jaws back off the wire
    over = grip(turn_end, near_tail, back=0.01)
    keys.append((t + 1.1, (over[0], YC + 0.012, over[2]), quat(turn_end), 0.3))  # up, clear of the liver
    there = grip(turn_end, near_tip, back=0.01)
    keys.append((t + 1.5, (there[0], YC + 0.012, there[2]), quat(turn_end), 0.3))
    keys.append((t + 1.8, there, quat(turn_end), 0.3))
    keys.append((t + 2.1, grip(turn_end, near_tip), quat(turn_end), 0.3))  # jaws around the wire near the tip
    keys.append((t + 2.2, grip(turn_end, near_tip), quat(turn_end), 0.0))  # regrasp
    t += 2.4
    keys.append((t, grip(turn_end, near_tip), quat(turn_end), 0.0))
    # On through: psi 175 -> 335 degrees, the tail out of the far lip at about 323.
    pull_end = d(335)
    n = 80
    for i in range(1, n + 1):
        psi = turn_end + (pull_end - turn_end) * i / n
        keys.append((t + 3.2 * i / n, grip(psi, near_tip), quat(psi), 0.0))
    t += 3.2
    end = grip(pull_end, near_tip)
    keys.append((t + 0.8, (end[0], end[1] + 0.03, end[2]), quat(pull_end), 0.0))  # lifted away
    return keys


def thread_grasper():
    """The grasper of the suture demo with its thread (scenarios/liver_suture_thread.yaml): the
    stitch above, then the needle pulled on up and towards the far side at 10 mm/s, 38 mm, drawing
    the thread tight (about 2 N: WoundClosure.OneStitchPulledToItsTensionClosesTheIncisionAndHoldsIt
    reaches it at 36 mm), and held there while the lips stay closed."""
    keys = grasper()
    t, p, q, jaw = keys[-1]
    n = math.hypot(1.0, 0.5)
    d = (0.0, 1.0 / n, 0.5 / n)
    pull = 0.038
    keys.append((t + pull / 0.01, tuple(p[k] + d[k] * pull for k in range(3)), q, jaw))
    keys.append((t + pull / 0.01 + 2.0, tuple(p[k] + d[k] * pull for k in range(3)), q, jaw))
    return keys


def scalpel():
    q = (0.5, 0.5, 0.5, 0.5)  # edge down (world -y... as in liver_incision.yaml), normal along z
    return [(0.0, (-0.045, 0.185, ZC), q, 0.0), (0.6, (-0.045, 0.185, ZC), q, 0.0),
            (1.0, (-0.045, 0.125, ZC), q, 0.0), (2.0, (0.015, 0.125, ZC), q, 0.0),
            (2.4, (0.015, 0.185, ZC), q, 0.0), (2.8, (0.05, 0.2, ZC), q, 0.0)]


HEADER = {
    "grasper": """# The suture demo's grasper (scenarios/liver_suture.yaml, scripts/demo_needle.sh); written by
# scripts/suture_trajectories.py, which says how. Holds a half-circle needle (R 15 mm) off the
# blade's path while the scalpel incises (2.8 s), brings it over the incision, turns it about its
# centre through both lips and out (3.2 s), lets go, regrasps it near the tip where it came out,
# turns it on through until its tail is out (3.2 s) and lifts it away.
""",
    "thread_grasper": """# The grasper of the suture demo with its thread (scenarios/liver_suture_thread.yaml,
# scripts/demo_suture.sh); written by scripts/suture_trajectories.py, which says how. The needle
# demo's grasper (liver_suture_grasper.yaml: the needle through both lips and out, lifted away by
# 13 s), then the needle pulled on 38 mm up and towards the far side at 10 mm/s, drawing the thread
# tight through its four punctures, and held there 2 s: the lips close at the stitch.
""",
    "scalpel": """# The suture demo's scalpel (scenarios/liver_suture.yaml, scripts/demo_needle.sh); written by
# scripts/suture_trajectories.py. Still 0.6 s, then the incision of trajectories/liver_incision.yaml
# (down at x = -45 mm, drawn 60 mm along +x at z = 12.5 mm), lifted out and put aside.
""",
}

for name, keys in (("grasper", grasper()), ("thread_grasper", thread_grasper()),
                   ("scalpel", scalpel())):
    with open(os.path.join(ROOT, "liver_suture_%s.yaml" % name), "w") as f:
        f.write(HEADER[name])
        f.write("keyframes:\n")
        for k in keys:
            line = fmt(*k)
            if name == "scalpel":
                line = line.rsplit(", jaw", 1)[0] + "}"
            f.write(line + "\n")
