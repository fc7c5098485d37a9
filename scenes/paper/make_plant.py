#!/usr/bin/env python3
"""Writes scenes/paper/plant_pot.toml: the paper's plant at its size (Table 1:
788 quadrilateral shell elements, 3 750 vertices and 6 304 triangles drawn;
§6, Figs. 10-11), on the pot of scenes/plant_pot.toml.

A rod stem clamped in the pot carries three rod branches; each branch carries
three petioles and the stem's top two more, and every petiole ends in a leaf:
11 leaves of 6 x 12 quads (792 shell quads, as two triangles each). Each
leaf's midrib runs on along its petiole's last segment, where the two share
vertices (`weld_to`), so a leaf is held along a line, not at a point. Leaves
of neighbouring branches overlap in plan, at least 1.6 cm apart at rest (self-collision,
thickness 3 mm); braced so that no joint has a mirror rest (farthest_off_plane),
they sway with their branches and do not come within 6 mm of each other on
the scene's pushes (docs/scenes.md). The leaves are drawn
through one Loop subdivision (`render = { subdivide = 1 }`): 6 336 triangles
on the screen from 1 584 simulated ones, as the paper's shells were drawn
finer than they were simulated. Stem, branches and petioles are drawn as
tubes of their radius (`render = { tube = k }`), so the leaves hang on
something; the stem's twist frame is not drawn.

Units are metres, in the pot's frame (soil at y = 0.115, stem on the y axis).
Run:  python3 scenes/paper/make_plant.py > scenes/paper/plant_pot.toml
"""
import math

STEM_BASE, STEM_TOP, STEM_SEGMENTS = 0.12, 0.64, 26   # stem vertices every 2 cm
BRANCHES = [  # (height on the stem, azimuth in degrees, rise): three main branches
    (0.38, 0.0, 0.55), (0.46, 125.0, 0.6), (0.54, 245.0, 0.65)]   # leaves droop clear of the pot
BRANCH_SEGMENTS, BRANCH_STEP = 5, 0.02                 # 10 cm branches
PETIOLE_SEGMENTS, PETIOLE_STEP = 6, 0.01               # 6 cm petioles, the last cm inside the leaf
LEAF_CELLS = (6, 12)                                   # across, along: 72 quads per leaf
LEAF_WIDTH = 0.06                                      # the leaf is 12 x 1 cm long
BRANCH_YOUNG, PETIOLE_YOUNG = 1.5e8, 5e7               # Pa
BRANCH_RADIUS, PETIOLE_RADIUS = 0.003, 0.002           # m
TUBE_SIDES, STEM_TUBE_SIDES = 6, 8                      # rods are drawn as tubes of these sides
STEM_FRAME_RADIUS = 0.02                               # m: the stem's frame points, see stem_frame
STEM_FRAME_YOUNG = 4e7                                 # Pa on a 1 mm radius: EA = 126 N, twist springs
STEM_FRAME_EA = 2e4                                    # N: frame points held to the stem's axis
JOINT_BRACE = 0.05                                     # a joint brace's EA, as a fraction of the child rod's
LEAF_BRACE = 50.0                                      # N: a leaf's corners against rolling on its petiole (at 5 N
                                                       # a push left leaves caught on each other, 5 cm RMS off rest)
LEAF = """energies = ["membrane", "bending"]
density = 0.25            # kg/m^2
young = 800               # N/m
poisson = 0.3
bending = 2e-3            # N m: the blade droops ~20 degrees at its tip (q L^3 / 6D)
drag = 0.8
render = {{ subdivide = 1 }}
weld_to = "{parent}"
weld_radius = 1e-4"""


def add(a, b, s=1.0):
    return [a[i] + s * b[i] for i in range(3)]


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def dot(a, b):
    return sum(a[i] * b[i] for i in range(3))


def unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def heading(azimuth_deg, rise):
    a = math.radians(azimuth_deg)
    return unit([math.cos(a), rise, math.sin(a)])


def fmt(v):
    return "[" + ", ".join(f"{c:.6f}" for c in v) + "]"


def rod(name, parent, start, direction, segments, step, radius, young):
    """A rod body and its vertex positions, start first."""
    end = add(start, direction, segments * step)
    points = [add(start, direction, i * step) for i in range(segments + 1)]
    return f"""[[body]]
name = "{name}"
albedo = [0.35, 0.45, 0.15]
energies = ["rod"]
density = 0.03            # kg/m
young = {young:g}
radius = {radius}
render = {{ tube = {TUBE_SIDES} }}   # drawn as a tube of the rod's radius
polyline = {{ points = [{fmt(start)}, {fmt(end)}], subdivisions = {segments} }}
weld_to = "{parent}"
weld_radius = 1e-4
""", points


def brace(start, ends, ea, why=""):
    comment = f"   # {why}" if why else ""
    return f"""[[brace]]
from = {fmt(start)}{comment}
to = [{", ".join(fmt(e) for e in ends)}]
ea = {ea:g}
"""


def stem_frame(stem):
    """A rod carries no twist, and a weld is a ball joint: alone, the crown
    could spin about the stem and every branch turn about its root. These
    'frame' points, one per stem vertex at STEM_FRAME_RADIUS on a helix of
    quarter turns, are each braced to three stem vertices; the chain joining
    them resists the stem's twist to first order (a quarter turn between
    neighbours), and branches and petioles brace to them."""
    frame = []
    for i, p in enumerate(stem):
        a = math.radians(90.0 * i + 45.0)
        frame.append(add(p, [math.cos(a), 0.0, math.sin(a)], STEM_FRAME_RADIUS))
    body = f"""[[body]]
name = "stem_frame"
albedo = [0.35, 0.45, 0.15]
energies = ["rod"]        # its segments are the twist springs (not drawn; exported as rod segments)
density = 0.005           # kg/m
young = {STEM_FRAME_YOUNG:g}
radius = 0.001
polyline = {{ points = [{", ".join(fmt(p) for p in frame)}] }}
pin = {{ min = [-0.03, 0.11, -0.03], max = [0.03, {stem[1][1] + 0.005:.4f}, 0.03] }}   # in the soil, as the stem
"""
    braces = [brace(frame[i], [stem[j] for j in (i - 1, i, i + 1) if 0 <= j < len(stem)], STEM_FRAME_EA)
              for i in range(len(stem))]
    return body + "\n" + "\n".join(braces), frame


def farthest_off_plane(a, b, c, candidates):
    """The candidate farthest from the plane through a, b and c. Springs from
    one point to anchors that all lie in one plane with the joint hold it
    twice over: its mirror image through that plane has the same spring
    lengths (a vertical plane keeps its height too), so a push could flip a
    petiole to its sibling's side, or a leaf over, and leave it there."""
    n = unit(cross(sub(b, a), sub(c, a)))
    return max(candidates, key=lambda p: abs(dot(sub(p, a), n)))


def joint(child, child_ea, anchors, extra, why):
    """Braces the child's second vertex to anchors off its axis, so that the
    weld at its first vertex holds its direction (and the turn about it); where
    the anchors lie in one plane with the weld, the one of `extra` farthest off
    it joins them (added always: elsewhere it does no harm)."""
    widest = max(((p, q) for p in anchors for q in anchors),
                 key=lambda pq: sum(c * c for c in cross(sub(pq[0], child[0]), sub(pq[1], child[0]))))
    anchors = anchors + [farthest_off_plane(child[0], *widest, extra)]
    return brace(child[1], anchors, JOINT_BRACE * child_ea, why)


def leaf(name, parent, petiole_last, direction):
    """A leaf whose midrib starts at the petiole's last-but-one vertex and runs
    along `direction`, its rows PETIOLE_STEP apart so the first segment is shared.
    Returns the body and its first row's two corners."""
    across = unit(cross(direction, [0.0, 1.0, 0.0]))
    along = [c * PETIOLE_STEP * LEAF_CELLS[1] for c in direction]
    u = [c * LEAF_WIDTH for c in across]
    origin = add(petiole_last, u, -0.5)
    return f"""[[body]]
name = "{name}"
albedo = [0.18, 0.55, 0.12]
{LEAF.format(parent=parent)}
grid = {{ origin = {fmt(origin)}, u = {fmt(u)}, v = {fmt(along)}, cells = [{LEAF_CELLS[0]}, {LEAF_CELLS[1]}] }}
""", [origin, add(origin, u)]


def petiole_and_leaf(index, parent, start, direction, anchors, extra):
    """A petiole from `start` on its parent and its leaf; `anchors` are points
    off the petiole's axis on the parent or the stem, which its joint and the
    leaf's blade are braced to, and `extra` stem frame points, one of which
    joins each where the others lie in one plane with its axis."""
    body, petiole = rod(f"petiole{index}", parent, start, direction, PETIOLE_SEGMENTS, PETIOLE_STEP, PETIOLE_RADIUS,
                        PETIOLE_YOUNG)
    blade, corners = leaf(f"leaf{index}", f"petiole{index}", petiole[-2], direction)
    ea = PETIOLE_YOUNG * math.pi * PETIOLE_RADIUS ** 2
    parts = [body, joint(petiole, ea, anchors, extra, f"petiole{index}'s joint"), blade]
    # The blade rolls about its midrib (the petiole's last segments): a second
    # anchor off the plane of that axis and the first keeps the roll's mirror out.
    rolls = [anchors[0], farthest_off_plane(petiole[-3], petiole[-2], anchors[0], anchors[1:] + extra)]
    parts += [brace(c, [petiole[-3]] + rolls, LEAF_BRACE, f"leaf{index} against rolling") for c in corners]
    return "\n".join(parts)


def plant():
    step = (STEM_TOP - STEM_BASE) / STEM_SEGMENTS
    stem = [[0.0, STEM_BASE + i * step, 0.0] for i in range(STEM_SEGMENTS + 1)]
    parts = [f"""[[body]]
name = "stem"
albedo = [0.35, 0.45, 0.15]
energies = ["rod"]
density = 0.05            # kg/m
young = 3e8               # Pa, a woody stem: it carries eleven leaves
radius = 0.006            # m
render = {{ tube = {STEM_TUBE_SIDES} }}   # drawn as a tube of the rod's radius
polyline = {{ points = [[0, {STEM_BASE}, 0], [0, {STEM_TOP}, 0]], subdivisions = {STEM_SEGMENTS} }}
pin = {{ min = [-0.01, 0.11, -0.01], max = [0.01, {STEM_BASE + 1.5 * step:.4f}, 0.01] }}   # clamped in the soil
"""]
    frame_body, frame = stem_frame(stem)
    parts.append(frame_body)
    leaves = 0
    for b, (height, azimuth, rise) in enumerate(BRANCHES):
        k = round((height - STEM_BASE) / step)  # on a stem vertex, where the weld finds it
        direction = heading(azimuth, rise)
        body, branch = rod(f"branch{b}", "stem", stem[k], direction, BRANCH_SEGMENTS, BRANCH_STEP, BRANCH_RADIUS,
                           BRANCH_YOUNG)
        parts.append(body)
        near = frame[k - 1:k + 2]
        parts.append(joint(branch, BRANCH_YOUNG * math.pi * BRANCH_RADIUS ** 2, [stem[k - 1], stem[k + 1], frame[k]],
                           near, f"branch{b}'s joint"))
        # Petioles from the branch's 3rd and 5th vertices: to either side, and on along the tip.
        for at, turn, lift in ((3, -55.0, 0.2), (3, 55.0, 0.2), (5, 0.0, 0.1)):
            anchors = [branch[at - 1], stem[k + 1]] + ([branch[at + 1]] if at + 1 < len(branch) else [])
            parts.append(petiole_and_leaf(leaves, f"branch{b}", branch[at], heading(azimuth + turn,
                                                                                      rise * 0.5 + lift),
                                          anchors, near))
            leaves += 1
    for azimuth in (60.0, 190.0):
        anchors = [stem[-2], stem[-3], frame[-1], frame[-2]]
        parts.append(petiole_and_leaf(leaves, "stem", stem[-1], heading(azimuth, 0.9), anchors, frame[-3:]))
        leaves += 1
    return "\n".join(parts), leaves


HEADER = """# Generated by scenes/paper/make_plant.py: edit that script, not this file.
# The paper's plant at its size (Table 1: 788 quad shells, 3 750 / 6 304
# drawn; Figs. 10-11): a rod stem in a pot with three branches, {leaves}
# leaves of 6 x 12 quads on petioles ({quads} shell quads), leaves of
# neighbouring branches overlapping in plan (they sway with their branches
# and do not meet on its pushes: docs/scenes.md). Leaves are drawn through
# one Loop subdivision, stem, branches and petioles as tubes of their
# radius. The pot is pushed side to side as scenes/plant_pot.toml (the fast
# default), same palette.
name = "paper_plant_pot"

[simulation]
frame_dt = 0.02
substeps = 2
newton_iterations = 4     # with 1 or 2 the stiff stem folds under contact and the plant falls into a
                          # heap (3 s at rest: stem top 0.64 -> 0.29 m), where resting contact costs 10x
gravity = [0, -9.81, 0]
mass_damping = 0.2
stiffness_damping = 0.004
max_speed = 20
friction = 0.3
settle = 3.0              # s of quasi-static relaxation: the crown droops for about 1.5 s (after 0.5 s it went on
                          # sinking 3 cm RMS, and every run measured that creep as motion)

[support]
motion = "translational"
axis = [1, 0, 0]
range = [-0.3, 0.3]      # metres

[contact]
thickness = 0.003
self_collision = true

"""

FOOTER = """
[[obstacle]]
name = "pot"
min = [-0.07, 0.0, -0.07]
max = [0.07, 0.115, 0.07]
albedo = [0.72, 0.34, 0.2]   # terracotta
cell = 0.01

[[palette]]
name = "left"
alpha_impulse = [-0.5, 0, 0]   # pot velocity, m/s
alpha_forcing = [-0.5, 0, 0]
t_max = 1.2
on_end = "stop"
after = ["rest", "stop"]

[[palette]]
name = "stop"
alpha_impulse = [0, 0, 0]
alpha_forcing = [0, 0, 0]
after = ["left", "right"]
t_min = 3.5
t_max = 4.0

[[palette]]
name = "right"
alpha_impulse = [0.5, 0, 0]
alpha_forcing = [0.5, 0, 0]
t_max = 1.2
on_end = "stop"
after = ["rest", "stop"]

[appearance]
clusters = 100           # N_a of Table 1
eps_a = 0.32             # r_a = 12, the paper's, on the demo sample: sigma_13 / sigma_1 = 0.317 (the paper: 6.2 %; our
                         # leaves turn and shadow each other, a flat spectrum); every sigma kept (r_a = 99) overflows
                         # the OSMesa client's 128 MiB storage block
held_out = 40
paper_rank_a = 12        # Table 1: r_a = 12 at 6.2 %

[validation]
schedule = "right 0.4; stop 2.5; left 0.6; stop 3"

# What scripts/demo plays: the example Lua script (relative to this file) and the seed of
# its small sample, one that gives every palette entry IRFs (docs/demo.md).
[demo]
script = "../scripts/pot_left_right.lua"
seed = 1
"""


def main():
    bodies, leaves = plant()
    quads = leaves * LEAF_CELLS[0] * LEAF_CELLS[1]
    print(HEADER.format(leaves=leaves, quads=quads) + bodies + FOOTER, end="")


if __name__ == "__main__":
    main()
