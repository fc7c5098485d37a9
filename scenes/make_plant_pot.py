#!/usr/bin/env python3
"""Writes scenes/plant_pot.toml, the default plant: a rod stem in a pushed pot
with five leaf pairs, braced so that it has one rest (docs/scenes.md).

A rod carries no twist and a weld along the stem's axis is a hinge, so leaf
pairs welded to a bare stem turn freely about it: every orientation is a
rest, and the plant settled wherever its history left it (the neutral mode
`check` names). As the paper-size plant (scenes/paper/make_plant.py), the
stem gets a frame of points 2 cm off its axis, each braced to three stem
vertices, and each pair's two vertices beside the stem are braced to three
frame points. The pairs are fanned FAN_DEG apart, each overlapping the next
by half its height: nearer, their vertices beside the stem rest closer than
twice the contact thickness and push on each other (measured in
docs/scenes.md, "The default plant's rest").

    scenes/make_plant_pot.py > scenes/plant_pot.toml

Units are metres, in the pot's frame (soil at y = 0.115, stem on the y axis).
"""
import math

STEM_BOTTOM, STEM_STEP, STEM_SEGMENTS = 0.12, 0.025, 14
FRAME_RADIUS = 0.02              # m: the stem's frame points
FRAME_EA = 2e4                   # N: frame points held to the stem's axis
PAIRS, PAIR_BOTTOM, PAIR_STEP, PAIR_HEIGHT = 5, 0.245, 0.025, 0.05
PAIR_WIDTHS = (0.20, 0.12)       # m: the lowest pair's, the highest's
FAN_DEG = 12.0                   # degrees between neighbouring pairs about the stem
LEAF_BRACE = 50.0                # N: a pair's vertices beside the stem against turning
LEAF_CELLS = (6, 2)              # across, up: the middle column lies on the stem

HEADER = """# A stemmed plant in a pot that is pushed side to side (paper §6): a rod stem
# clamped in the pot carries five leaf pairs (membrane + bending shells welded to
# the stem), the pot moves along x at v in {-v0, 0, +v0} within +-0.3 m.
# Simulated in the pot's frame; leaves collide with each other. A braced frame
# around the stem holds the pairs' orientation, so the plant has one rest.
# Written by scenes/make_plant_pot.py: edit that, not this file.
name = "plant_pot"

"""
SIMULATION = """[simulation]
frame_dt = 0.02
substeps = 2
newton_iterations = 4
gravity = [0, -9.81, 0]
mass_damping = 0.2
stiffness_damping = 0.004
max_speed = 20
friction = 0.3

[support]
motion = "translational"
axis = [1, 0, 0]
range = [-0.3, 0.3]      # metres

[contact]
thickness = 0.003
self_collision = true

"""

STEM = """[[body]]
name = "stem"
albedo = [0.35, 0.45, 0.15]
energies = ["rod"]
density = 0.05            # kg/m
young = 5e7                # Pa, green stem
radius = 0.004            # m
render = { tube = 8 }     # drawn as a tube of its radius (docs/scenes.md)
polyline = { points = [[0, 0.12, 0], [0, 0.47, 0]], subdivisions = 14 }
pin = { min = [-0.01, 0.11, -0.01], max = [0.01, 0.146, 0.01] }   # clamped in the soil

"""

FOOTER = """[[obstacle]]
name = "pot"
min = [-0.07, 0.0, -0.07]
max = [0.07, 0.115, 0.07]
albedo = [0.72, 0.34, 0.2]   # terracotta
cell = 0.01                 # m: the faces the transfer sees are tessellated into cells this size

# The paper's pot has three speeds {-v0, 0, +v0}, changed by v0 steps, so
# "no more than two same-signed pushes in a row" (§3.5). Each entry names the
# speed it sets: left and right start only from rest or stop, stop only while
# the pot moves, as the door's close/stop/open. Every transition the server
# allows is one the sampler draws (left -> right, a 2 v0 jump, is neither).
[[palette]]
name = "left"
alpha_impulse = [-0.5, 0, 0]   # pot velocity, m/s
alpha_forcing = [-0.5, 0, 0]
t_max = 1.2                   # the whole 0.6 m range at 0.5 m/s
on_end = "stop"               # at the end of its range the pot stops, and the plant sways to rest
after = ["rest", "stop"]      # speed steps of v0 only (above)

[[palette]]
name = "stop"
alpha_impulse = [0, 0, 0]
alpha_forcing = [0, 0, 0]
after = ["left", "right"]     # the pot stops only when it moves
t_min = 3.5                   # drawn to rest (measured: IRFs ending mid-sway froze the served plant)
t_max = 4.0                   # played to rest: the plant sways for ~4 s after the pot stops

[[palette]]
name = "right"
alpha_impulse = [0.5, 0, 0]
alpha_forcing = [0.5, 0, 0]
t_max = 1.2                   # the whole 0.6 m range at 0.5 m/s
on_end = "stop"               # at the end of its range the pot stops, and the plant sways to rest
after = ["rest", "stop"]      # speed steps of v0 only (above)

# The appearance stage's defaults (§4, docs/transfer.md); the command line overrides them.
[appearance]
clusters = 48            # N_a (paper: 100 for its 3 750-vertex plant)
eps_a = 0.045            # r_a = 12 on the demo sample (sigma_13 / sigma_1 = 0.043)
held_out = 40            # other nodes whose true transfer measures the served appearance
paper_rank_a = 12        # Table 1: r_a = 12 at 6.2 %

# The interaction `phasecast-precompute validate` plays by default (docs/validation.md).
[validation]
schedule = "right 0.4; stop 2.5; left 0.6; stop 3"

# What scripts/demo plays: the example Lua script (relative to this file) and the seed of
# its small sample, one that gives every palette entry IRFs (docs/demo.md).
[demo]
script = "scripts/pot_left_right.lua"
seed = 1
"""


def fmt(v):
    return "[" + ", ".join(f"{x:.6f}" for x in v) + "]"


def brace(start, ends, ea):
    return f"[[brace]]\nfrom = {fmt(start)}\nto = [{', '.join(fmt(e) for e in ends)}]\nea = {ea:g}\n"


def stem_frame(stem):
    """One frame point per stem vertex on a helix of quarter turns, each braced
    to three stem vertices: the chain joining them resists the stem's twist."""
    frame = []
    for i, p in enumerate(stem):
        a = math.radians(90.0 * i + 45.0)
        frame.append([FRAME_RADIUS * math.cos(a), p[1], FRAME_RADIUS * math.sin(a)])
    body = f"""[[body]]
name = "stem_frame"
albedo = [0.35, 0.45, 0.15]
energies = ["rod"]        # its segments are the twist springs (not drawn; exported as rod segments)
density = 0.005           # kg/m
young = 4e7               # Pa on a 1 mm radius
radius = 0.001
polyline = {{ points = [{", ".join(fmt(p) for p in frame)}] }}
pin = {{ min = [-0.03, 0.11, -0.03], max = [0.03, 0.150, 0.03] }}   # in the soil, as the stem
"""
    braces = [brace(frame[i], [stem[j] for j in (i - 1, i, i + 1) if 0 <= j < len(stem)], FRAME_EA)
              for i in range(len(stem))]
    return body + "\n" + "\n".join(braces), frame


def leaf_pair(k, frame):
    """Pair k: a vertical blade through the stem, its middle column welded to
    it, its two vertices beside the stem braced to the three nearest frame
    points."""
    y = PAIR_BOTTOM + PAIR_STEP * k
    w = PAIR_WIDTHS[0] + (PAIR_WIDTHS[1] - PAIR_WIDTHS[0]) * k / (PAIRS - 1)
    a = math.radians(FAN_DEG * (k - (PAIRS - 1) / 2))
    d = [math.cos(a), 0.0, math.sin(a)]
    u = [w * d[0], 0.0, w * d[2]]
    body = f"""[[body]]
name = "leaves{k}"
albedo = [0.18, 0.55, 0.12]
energies = ["membrane", "bending"]
density = 0.25            # kg/m^2
young = 800               # N/m
poisson = 0.3
bending = 1e-4            # N m, leaf blade
drag = 0.8
weld_to = "stem"
weld_radius = 1e-4
grid = {{ origin = {fmt([-u[0] / 2, y, -u[2] / 2])}, u = {fmt(u)}, v = [0, {PAIR_HEIGHT:.6f}, 0], cells = [{LEAF_CELLS[0]}, {LEAF_CELLS[1]}] }}
"""
    middle = y + PAIR_HEIGHT / 2
    i = round((middle - STEM_BOTTOM) / STEM_STEP)
    anchors = frame[i - 1:i + 2]
    step = w / LEAF_CELLS[0]
    braces = [brace([side * step * d[0], middle, side * step * d[2]], anchors, LEAF_BRACE) for side in (-1, 1)]
    return body + "\n" + "\n".join(braces)


def main():
    stem = [[0.0, STEM_BOTTOM + STEM_STEP * i, 0.0] for i in range(STEM_SEGMENTS + 1)]
    frame_body, frame = stem_frame(stem)
    parts = [HEADER + SIMULATION + STEM, frame_body] + [leaf_pair(k, frame) for k in range(PAIRS)] + [FOOTER]
    print("\n".join(parts), end="")


if __name__ == "__main__":
    main()
