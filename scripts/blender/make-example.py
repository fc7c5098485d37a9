"""Builds the Blender example scene: a towel pinned over a rail on a door that swings about its hinge.

    blender -b --factory-startup --python scripts/blender/make-example.py -- OUT.blend [--cells NX NZ]

The layout is scenes/tiny/cloth_door.toml's in Blender's Z-up world (Phasecast's (x, y, z) is
Blender's (x, -z, y)): the hinge line is Blender's Z axis through the origin, the door board
spans x in [0.02, 0.82], z in [0, 2], y in [0, 0.04], and the towel hangs on the board's -y face.
Objects: "Hinge" (an empty, the support), "Door" (the board, drawn, its faces cut 8 x 8 by a
simple subdivision so they carry the towel's shadow), "Rail" (a round bar the towel hangs from,
drawn; the cloth is pinned, not hung on it), "DoorCollider" (what the towel collides with: the
board's front face backed by 20 cm, not rendered) and "Towel" (cloth with self-collision, pinned
along its top edge); all but the hinge are children of the hinge. Nothing
binary is committed: scenes/blender/*.toml name this script as their [simulator] make
(docs/simulator.md, "Blender as the black box").
"""

import argparse
import math
import os
import sys

import bmesh
import bpy


def parse_arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="make-example.py", description=__doc__.splitlines()[0])
    parser.add_argument("output", help="the .blend to write")
    parser.add_argument("--cells", type=int, nargs=2, default=[10, 14], metavar=("NX", "NZ"),
                        help="towel cells across and down (default 10 14)")
    return parser.parse_args(argv)


def material(name, colour):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*colour, 1.0)
    mat.diffuse_color = (*colour, 1.0)
    return mat


def mesh_object(name, vertices, faces, parent, colour):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices, [], faces)
    mesh.validate()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.parent = parent
    obj.data.materials.append(material(name, colour))
    return obj


def box(name, lo, hi, parent, colour):
    v = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    obj = mesh_object(name, v, faces, parent, colour)
    # Collisions push cloth out along the face normals: they must point out of the box.
    mesh = bmesh.new()
    mesh.from_mesh(obj.data)
    bmesh.ops.recalc_face_normals(mesh, faces=mesh.faces)
    mesh.to_mesh(obj.data)
    mesh.free()
    return obj


def round_bar(parent, x0, x1, y, z, radius=0.012, sides=16):
    """A round bar along x: smooth sides, flat ends (auto smooth keeps the end edges sharp)."""
    ring = [(y + radius * math.cos(2 * math.pi * k / sides), z + radius * math.sin(2 * math.pi * k / sides))
            for k in range(sides)]
    vertices = [(x, cy, cz) for x in (x0, x1) for cy, cz in ring]
    faces = [(k, (k + 1) % sides, sides + (k + 1) % sides, sides + k) for k in range(sides)]
    faces += [tuple(reversed(range(sides))), tuple(range(sides, 2 * sides))]
    obj = mesh_object("Rail", vertices, faces, parent, (0.7, 0.7, 0.72))
    mesh = bmesh.new()
    mesh.from_mesh(obj.data)
    bmesh.ops.recalc_face_normals(mesh, faces=mesh.faces)
    mesh.to_mesh(obj.data)
    mesh.free()
    for polygon in obj.data.polygons:
        polygon.use_smooth = True
    obj.data.use_auto_smooth = True
    obj.data.auto_smooth_angle = math.radians(60)
    return obj


def door(parent):
    board = box("Door", (0.02, 0.0, 0.0), (0.82, 0.04, 2.0), parent, (0.62, 0.42, 0.24))
    cut = board.modifiers.new("Cells", "SUBSURF")
    cut.subdivision_type = "SIMPLE"
    cut.levels = 3
    # The towel collides with a proxy: the board's front face backed by 20 cm. Pressed onto the
    # 4 cm board itself, Blender's cloth ends up behind it within a few swings (measured).
    proxy = box("DoorCollider", (0.02, 0.0, 0.0), (0.82, 0.2, 2.0), parent, (0.5, 0.5, 0.5))
    proxy.hide_render = True
    proxy.display_type = "WIRE"
    collision = proxy.modifiers.new("Collision", "COLLISION")
    collision.settings.thickness_outer = 0.02
    collision.settings.damping = 0.5
    collision.settings.use_normal = True  # push along the normals, away from the face
    return board


def towel(parent, nx, nz):
    # Over the rail: 0.5 m wide, 0.7 m long, 3 cm in front of the board's -y face.
    x0, width, top, length, y = 0.2, 0.5, 1.85, 0.7, -0.03
    vertices = [(x0 + width * i / nx, y, top - length * k / nz) for k in range(nz + 1) for i in range(nx + 1)]
    faces = [(k * (nx + 1) + i, k * (nx + 1) + i + 1, (k + 1) * (nx + 1) + i + 1, (k + 1) * (nx + 1) + i)
             for k in range(nz) for i in range(nx)]
    obj = mesh_object("Towel", vertices, faces, parent, (0.12, 0.3, 0.75))
    round_bar(parent, x0 - 0.03, x0 + width + 0.03, y, top + 0.014)
    rail = obj.vertex_groups.new(name="rail")
    rail.add(list(range(nx + 1)), 1.0, "REPLACE")
    cloth = obj.modifiers.new("Cloth", "CLOTH")
    cloth.settings.vertex_group_mass = "rail"
    cloth.settings.mass = 0.3  # kg per vertex, Blender's cotton
    cloth.settings.quality = 12
    cloth.settings.air_damping = 3.0  # at Blender's 1.0 the towel still swung at 15 mm/s 3 s after a door stop (check)
    cloth.collision_settings.collision_quality = 10  # fewer passes let the towel slip into the board
    cloth.collision_settings.use_self_collision = True
    cloth.collision_settings.distance_min = 0.004
    cloth.collision_settings.self_distance_min = 0.004
    return obj


def main():
    args = parse_arguments()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start = 1
    scene.render.fps = 50
    hinge = bpy.data.objects.new("Hinge", None)
    scene.collection.objects.link(hinge)
    door(hinge)
    towel(hinge, *args.cells)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.output))
    print(f"wrote {args.output}")


main()
