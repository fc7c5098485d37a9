# Runs inside headless Blender (`blender -b scene.blend --python-expr <this file> -- MODE CONFIG`)
# for phasecast-precompute's Blender simulator (docs/simulator.md, "Blender"). It speaks
# to the simulator over the socket on file descriptor 3; Blender's own output goes to a
# log the simulator quotes when something fails.
#
#   describe  one JSON line: the deformable objects' evaluated world vertices and
#             triangles at the first frame, their base colours, the drawn objects'
#             evaluated meshes (one point per distinct corner normal), the pinned
#             vertices.
#   simulate  one JSON line {"vertices": V}; then per line "step m00 .. m23" (the
#             support's motion, a 3x4 in Blender's world) it moves the support,
#             advances one frame and answers "ok" and 3V little-endian
#             doubles: the deformable vertices in Blender's world.
#
# Any failure answers {"error": "..."} and exits.

import json
import os
import socket
import struct
import sys
import traceback

import bpy
import mathutils

try:
    import numpy
except ImportError:  # Blender without numpy: slower, and mathutils rounds to float32 first
    numpy = None

CLOTH_SECONDS_PER_FRAME = 0.001 ** 0.5  # at speed multiplier 1 (measured: free fall, any fps)
CHANNEL = socket.socket(fileno=3)
STREAM = CHANNEL.makefile("rwb")


def answer_json(value):
    STREAM.write((json.dumps(value) + "\n").encode())
    STREAM.flush()


def fail(message):
    answer_json({"error": message})
    STREAM.close()
    os._exit(1)


def find_object(name, role):
    obj = bpy.data.objects.get(name)
    if obj is None:
        known = ", ".join(sorted(o.name for o in bpy.data.objects))
        fail(f"{role} '{name}' is not an object of {bpy.data.filepath} (its objects: {known})")
    return obj


def descends_from(obj, ancestor):
    while obj is not None:
        if obj == ancestor:
            return True
        obj = obj.parent
    return False


def base_colour(obj):
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None:
            continue
        if mat.use_nodes and mat.node_tree is not None:
            for node in mat.node_tree.nodes:
                if node.type == "BSDF_PRINCIPLED":
                    return list(node.inputs["Base Color"].default_value)[:3]
        return list(mat.diffuse_color)[:3]
    return [0.8, 0.8, 0.8]


def world_vertices(obj):
    """The evaluated (simulated) vertices of obj in Blender's world, as floats."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    n, matrix = len(mesh.vertices), evaluated.matrix_world
    if numpy is not None:
        co = numpy.empty(3 * n, dtype=numpy.float32)
        mesh.vertices.foreach_get("co", co)
        m = numpy.array(matrix, dtype=numpy.float64)
        world = (co.reshape(n, 3).astype(numpy.float64) @ m[:3, :3].T + m[:3, 3]).reshape(-1).tolist()
    else:
        world = [c for v in mesh.vertices for c in matrix @ v.co]
    evaluated.to_mesh_clear()
    return world


def triangles_of(obj):
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    mesh.calc_loop_triangles()
    order = -1 if evaluated.matrix_world.is_negative else 1  # a mirror reverses the winding
    triangles = [list(t.vertices)[::order] for t in mesh.loop_triangles]
    evaluated.to_mesh_clear()
    return triangles


def drawn_mesh(obj):
    """obj's evaluated mesh in Blender's world, modifiers applied: a point per vertex and split
    normal (flat faces keep hard edges, smooth ones share their vertices) and its triangles."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    mesh.calc_normals_split()
    mesh.calc_loop_triangles()
    matrix = evaluated.matrix_world
    turn = matrix.to_3x3().inverted_safe().transposed()  # normals turn by the inverse transpose
    mirrored = matrix.is_negative  # a mirror reverses the winding; the normals stay outward
    vertices, normals, triangles, points = [], [], [], {}
    for t in mesh.loop_triangles:
        corners = []
        for v, n in zip(t.vertices, t.split_normals):
            key = (v, tuple(round(c, 4) for c in n))
            if key not in points:
                points[key] = len(vertices) // 3
                vertices.extend(matrix @ mesh.vertices[v].co)
                normals.extend((turn @ mathutils.Vector(n)).normalized())
            corners.append(points[key])
        triangles.append(corners[::-1] if mirrored else corners)
    evaluated.to_mesh_clear()
    return {"name": obj.name, "colour": base_colour(obj), "vertices": vertices, "normals": normals,
            "triangles": triangles}


def pinned_of(obj, count):
    groups = set()
    for m in obj.modifiers:
        if m.type == "CLOTH" and m.settings.vertex_group_mass:
            groups.add(m.settings.vertex_group_mass)
        if m.type == "SOFT_BODY" and m.settings.vertex_group_goal:
            groups.add(m.settings.vertex_group_goal)
    pinned = [0] * count
    for name in groups:
        group = obj.vertex_groups.get(name)
        if group is None:
            continue
        for v in obj.data.vertices:
            if v.index < count:
                for g in v.groups:
                    if g.group == group.index and g.weight ** 4 >= 0.999:  # Blender pins only these
                        pinned[v.index] = 1
    return pinned


def prepare(config):
    scene = bpy.context.scene
    scene.render.fps = config["fps"]
    scene.render.fps_base = config["fps_base"]
    scene.frame_end = 1048574
    support = find_object(config["support"], "support")
    if support.animation_data is not None or len(support.constraints) > 0:
        fail(f"the support '{support.name}' has animation or constraints: Phasecast moves it (remove them)")
    deformable = [find_object(n, "deformable object") for n in config["deformable"]]
    drawn = [find_object(n, "drawn object") for n in config["drawn"]]
    for obj in deformable + drawn:
        if obj.type != "MESH":
            fail(f"'{obj.name}' is a {obj.type.lower()}, not a mesh")
        if not descends_from(obj, support):
            fail(f"'{obj.name}' is not a child of the support '{support.name}': parent it so it moves with the support")
    for obj in deformable:
        for m in obj.modifiers:
            if m.type in ("CLOTH", "SOFT_BODY"):
                m.point_cache.frame_start = scene.frame_start
                m.point_cache.frame_end = scene.frame_end
            if m.type == "CLOTH":
                # Blender's cloth advances a fixed sqrt(0.001) s a frame whatever the frame rate (its
                # gravity is g * 0.001 per frame squared); its speed multiplier makes that frame_dt.
                m.settings.time_scale *= config["frame_dt"] / CLOTH_SECONDS_PER_FRAME
    scene.frame_set(scene.frame_start)
    return scene, support, deformable, drawn


def describe(config):
    _, _, deformable, drawn = prepare(config)
    vertices, triangles, pinned, bodies = [], [], [], []
    for obj in deformable:
        world = world_vertices(obj)
        count = len(world) // 3
        first = len(vertices) // 3
        bodies.append({"name": obj.name, "first": first, "count": count, "colour": base_colour(obj),
                       "first_triangle": len(triangles)})
        vertices.extend(world)
        triangles.extend([first + i for i in t] for t in triangles_of(obj))
        pinned.extend(pinned_of(obj, count))
        bodies[-1]["triangles"] = len(triangles) - bodies[-1]["first_triangle"]
    self_collision, distance = False, 0.0
    for obj in deformable:
        for m in obj.modifiers:
            if m.type == "CLOTH" and m.collision_settings.use_self_collision:
                self_collision = True
                distance = max(distance, m.collision_settings.self_distance_min)
    answer_json({"vertices": vertices, "triangles": triangles, "pinned": pinned, "bodies": bodies,
                 "drawn": [drawn_mesh(obj) for obj in drawn], "self_collision": self_collision, "self_distance": distance})


def simulate(config):
    scene, support, deformable, _ = prepare(config)
    base = support.matrix_world.copy()
    counts = [len(world_vertices(obj)) // 3 for obj in deformable]
    answer_json({"vertices": sum(counts)})
    frame = scene.frame_start
    while True:
        line = STREAM.readline()
        if not line or line.strip() == b"quit":
            return
        words = line.split()
        if words[0] != b"step" or len(words) != 13:
            fail(f"unexpected request {line[:60]!r}")
        m = [float(w) for w in words[1:]]
        motion = mathutils.Matrix((m[0:4], m[4:8], m[8:12], (0.0, 0.0, 0.0, 1.0)))
        support.matrix_world = motion @ base
        frame += 1
        scene.frame_set(frame)
        out = []
        for obj, count in zip(deformable, counts):
            world = world_vertices(obj)
            if len(world) // 3 != count:
                fail(f"'{obj.name}' has {len(world) // 3} vertices at frame {frame} but {count} at the "
                     f"first frame (a modifier that changes the topology?)")
            out.extend(world)
        STREAM.write(b"ok\n" + struct.pack(f"<{len(out)}d", *out))
        STREAM.flush()


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    mode, config = argv[0], json.loads(argv[1])
    try:
        if mode == "describe":
            describe(config)
        else:
            simulate(config)
    except SystemExit:
        raise
    except BaseException:
        fail("the Blender driver failed: " + " | ".join(traceback.format_exc().strip().splitlines()[-3:]))
    STREAM.close()
    os._exit(0)


main()
