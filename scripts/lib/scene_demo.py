#!/usr/bin/python3
"""Prints a scene file's [demo] section as two lines: the example Lua script
(resolved against the scene file's folder) and the seed of the demo's small
sample. scripts/demo reads it; phasecast-precompute checks the same section
(docs/scenes.md, "[demo]")."""
import os
import sys
import tomllib


def main(scene_file):
    try:
        with open(scene_file, "rb") as f:
            scene = tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as e:
        sys.exit(f"{scene_file}: cannot read the scene file ({e})")
    demo = scene.get("demo")
    if not isinstance(demo, dict) or not isinstance(demo.get("script"), str):
        sys.exit(f"{scene_file}: [demo] script: expected the example Lua script to play "
                 "(or give one with --script FILE)")
    seed = demo.get("seed", 1)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        sys.exit(f"{scene_file}: [demo] seed: expected a whole number >= 0, got {seed!r}")
    print(os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(scene_file)), demo["script"])))
    print(seed)


if __name__ == "__main__":
    main(sys.argv[1])
