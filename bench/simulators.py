#!/usr/bin/python3
"""The built-in simulator and Blender side by side on the same tiny towel-on-door
(docs/simulator.md, "Blender as the black box"): run --no-appearance with the defaults per seed,
then validate each package against its own simulator on the standard schedule and on random ones.

    bench/simulators.py [--seeds 1 2 3] [--random 10] [--bin build/bin] [--out /tmp/simulators]
"""
import argparse
import json
import os
import re
import statistics
import subprocess

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = {"built-in": "scenes/tiny/cloth_door.toml", "Blender": "scenes/tiny/blender/cloth_door.toml"}
CHAIN = re.compile(r"(\d+) state nodes in ([\d.]+) s \(settling ([\d.]+) s, then ([\d.]+) ms per node")


def measure(precompute, scene, seed, schedules, out):
    # A Blender scene's .blend is built by its [simulator] make when missing (as scripts/demo does).
    subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "scripts", "lib", "scene_demo.py"), "--make-blend", scene],
                   check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    package = os.path.join(out, f"{os.path.basename(os.path.dirname(scene))}-{seed}.h5")
    run = subprocess.run([precompute, "run", scene, "-o", package, "--seed", str(seed), "--no-appearance"],
                         capture_output=True, text=True, check=True, cwd=ROOT)
    chains = [CHAIN.search(line) for line in run.stderr.splitlines()]
    chains = [c for c in chains if c]
    figures = {}
    for kind, extra in (("standard", []), ("random", ["--random", str(schedules), "--seed", "7"])):
        path = package + f".{kind}.json"
        subprocess.run([precompute, "validate", scene, package, "--json", path, *extra], capture_output=True,
                       check=True, cwd=ROOT)
        figures[kind] = json.load(open(path))
    standard = figures["standard"]["schedules"][0]
    random = [s["nrmse"] for s in figures["random"]["schedules"] if s["kind"] == "random"]
    summary = figures["random"]["summary_random"]
    return {"ms_per_node": [float(c.group(4)) for c in chains], "chain_seconds": sum(float(c.group(2)) for c in chains),
            "standard": standard["nrmse"], "ratios": [round(g["motion_ratio"], 2) for g in standard["segments"]],
            "median": statistics.median(random), "max": max(random),
            "within": f"{summary['moving_segments_within']}/{summary['moving_segments']}"}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--random", type=int, default=10, help="random schedules per package (default 10)")
    parser.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"))
    parser.add_argument("--out", default="/tmp/simulators")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    precompute = os.path.join(args.bin, "phasecast-precompute")
    print("| simulator | seed | ms per node | chains (s) | standard NRMSE (motion ratios) | random median (max) | moving in range |")
    print("|---|---|---|---|---|---|---|")
    for name, scene in SCENES.items():
        for seed in args.seeds:
            m = measure(precompute, scene, seed, args.random, os.path.join(args.out, name.replace(" ", "")))
            print(f"| {name} | {seed} | {min(m['ms_per_node']):.1f}–{max(m['ms_per_node']):.1f} | {m['chain_seconds']:.1f} | "
                  f"{m['standard']:.3f} ({', '.join(map(str, m['ratios']))}) | {m['median']:.3f} ({m['max']:.2f}) | "
                  f"{m['within']} |", flush=True)


if __name__ == "__main__":
    main()
