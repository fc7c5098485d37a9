#!/usr/bin/python3
"""Prints a scene file's [demo] section as two lines: the example Lua script
(resolved against the scene file's folder) and the seed of the demo's small
sample. scripts/demo reads it; phasecast-precompute checks the same section
(docs/scenes.md, "[demo]").

With --field it reads a field file (scenes/fields/NAME.toml: many instances of
one scene in one view) and prints three lines: the scene it names, how many
instances, and its example Lua script.

With --make-blend it instead writes a Blender scene's missing .blend by running
its [simulator] make script in Blender (docs/simulator.md), and prints the
.blend's path (nothing for a scene of the built-in simulator)."""
import os
import shutil
import subprocess
import sys
import tomllib


def load(path, what):
    """The TOML file at `path`, or one line naming it and exit status 1."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as e:
        sys.exit(f"{path}: cannot read the {what} file ({e})")


def main(scene_file):
    scene = load(scene_file, "scene")
    demo = scene.get("demo")
    if not isinstance(demo, dict) or not isinstance(demo.get("script"), str):
        sys.exit(f"{scene_file}: [demo] script: expected the example Lua script to play "
                 "(or give one with --script FILE)")
    seed = demo.get("seed", 1)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        sys.exit(f"{scene_file}: [demo] seed: expected a whole number >= 0, got {seed!r}")
    print(os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(scene_file)), demo["script"])))
    print(seed)


def make_blend(scene_file):
    with open(scene_file, "rb") as f:
        simulator = tomllib.load(f).get("simulator", {})
    if simulator.get("kind") != "blender":
        return
    folder = os.path.dirname(os.path.abspath(scene_file))
    blend = os.path.join(folder, simulator.get("blend", ""))
    make = simulator.get("make")
    print(blend)
    if os.path.exists(blend) or not make:
        return  # phasecast-precompute names a missing .blend that has no maker
    blender = os.environ.get("PHASECAST_BLENDER") or shutil.which("blender")
    if not blender:
        sys.exit(f"{scene_file}: [simulator] make needs Blender: install Debian's package 'blender' "
                 "(scripts/install-deps does) or set PHASECAST_BLENDER")
    command = [blender, "-b", "--factory-startup", "--python", os.path.join(folder, make[0]), "--", blend,
               *make[1:]]
    print(f"demo: making {blend}", file=sys.stderr)
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0 or not os.path.exists(blend):
        tail = " | ".join(done.stdout.strip().splitlines()[-3:] + done.stderr.strip().splitlines()[-3:])
        sys.exit(f"{scene_file}: [simulator] make: {' '.join(command)} failed: {tail}")


def field(field_file):
    spec = load(field_file, "field")
    section = spec.get("field")
    if not isinstance(section, dict) or not isinstance(section.get("scene"), str):
        sys.exit(f"{field_file}: [field] scene: expected the name of the scene its instances play")
    count = section.get("instances")
    if not isinstance(count, int) or isinstance(count, bool) or not 1 <= count <= 1024:
        sys.exit(f"{field_file}: [field] instances: expected a whole number in 1..1024, got {count!r}")
    demo = spec.get("demo", {})
    if not isinstance(demo.get("script"), str):
        sys.exit(f"{field_file}: [demo] script: expected the Lua script that drives the field")
    print(section["scene"])
    print(count)
    print(os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(field_file)), demo["script"])))


if __name__ == "__main__":
    if sys.argv[1] == "--make-blend":
        make_blend(sys.argv[2])
    elif sys.argv[1] == "--field":
        field(sys.argv[2])
    else:
        main(sys.argv[1])
