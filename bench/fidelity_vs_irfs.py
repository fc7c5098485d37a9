#!/usr/bin/python3
"""Playback fidelity against IRF count (docs/sampling.md, "Fidelity against IRF count"): plain `run`
(random chains, `--no-appearance --no-check`) of each scene at several IRF counts and seeds, then one
`validate` per scene of all its packages on the same simulations: the scene's standard schedule and
held-out random schedules of their own seed, never the sampler's.

    bench/fidelity_vs_irfs.py [--scenes scenes/cloth_door.toml ...] [--irfs 16 32 64 128] [--seeds 1 2 3]
                              [--held-out 20] [--items 4] [--fidelity-seed 99] [--bin build/bin] [--out DIR]

`--reuse` measures packages already in DIR instead of sampling them again. `--adaptive N` adds, per seed, `--until-fidelity 0.001 --budget-irfs N` from a first round of half
that (its whole budget: the target is never met), measured on the same schedules; `--target T` samples
towards T instead (it may stop early: the row gives the IRFs it took), `--first-irfs F` sets the
first round and `--directed-chains C`, `--guide-schedules G` and `--fresh-schedules S` pass run's options of those names (the rows of earlier rules:
0 before 2026-12-05).
Prints one markdown row per scene, IRF count and seed, then the fewest IRFs at which every seed meets
median 0.15, 90th percentile 0.25 and 95 % of moving segments in range; writes every figure to
DIR/fidelity.json.
"""
import argparse
import json
import os
import re
import subprocess
import time
import tomllib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DEFAULT_SCENES = ["scenes/cloth_door.toml", "scenes/toy_dashboard.toml", "scenes/plant_pot.toml"]
CHAINS = 4  # run's default; the IRF count varies --irfs-per-chain
TARGET = {"median": 0.15, "p90": 0.25, "in_range": 0.95}


def sample(precompute, scene, out, seed, irfs, adaptive, args):
    """One package; returns its path, the minutes `run` took and the IRFs it sampled. A small draw may
    leave an entry without IRFs: the package is still measured (that entry plays nothing)."""
    kind = f"adaptive{args.target:g}" if adaptive else "random"
    if adaptive and args.directed_chains is not None:
        kind += f"-dc{args.directed_chains}"
    if adaptive and args.guide_schedules is not None:
        kind += f"-g{args.guide_schedules}"
    if adaptive and args.fresh_schedules is not None:
        kind += f"-f{args.fresh_schedules}"
    package = os.path.join(out, f"{os.path.splitext(os.path.basename(scene))[0]}-{kind}-{irfs}-{seed}.h5")
    per_chain = ((args.first_irfs or irfs // 2) if adaptive else irfs) // CHAINS
    command = [precompute, "run", scene, "-o", package, "--seed", str(seed), "--chains", str(CHAINS),
               "--irfs-per-chain", str(per_chain), "--no-appearance", "--no-check", "--allow-missing-entries"]
    if adaptive:  # the held-out figures are validate's below, on the same schedules as the random packages'
        command += ["--until-fidelity", str(args.target), "--budget-irfs", str(irfs), "--held-out-schedules", "0"]
        if args.directed_chains is not None:
            command += ["--directed-chains", str(args.directed_chains)]
        if args.guide_schedules is not None:
            command += ["--guide-schedules", str(args.guide_schedules)]
        if args.fresh_schedules is not None:
            command += ["--fresh-schedules", str(args.fresh_schedules)]
    log = package + ".log"
    if not (args.reuse and os.path.exists(package)):
        start = time.monotonic()
        with open(log, "w") as f:
            subprocess.run(command, check=True, cwd=ROOT, stdout=f, stderr=subprocess.DEVNULL)
        minutes = (time.monotonic() - start) / 60
    else:
        minutes = None
    return package, minutes, sampled_irfs(log) if adaptive else irfs


def sampled_irfs(log):
    """The IRFs adaptive sampling took, from run's last report line ("... after R rounds, N IRFs")."""
    found = re.findall(r"adaptive sampling: .* after \d+ rounds, (\d+) IRFs", open(log).read()) if os.path.exists(log) else []
    return int(found[-1]) if found else None


def figures(report):
    standard = next(s for s in report["schedules"] if s["kind"] == "given")
    summary = report["summary_random"]
    return {"standard": standard["nrmse"], "ratios": [round(g["motion_ratio"], 2) for g in standard["segments"]],
            "median": summary["median_nrmse"], "p90": summary["p90_nrmse"],
            "in_range": summary["moving_segments_within"] / max(1, summary["moving_segments"]),
            "moving": f"{summary['moving_segments_within']}/{summary['moving_segments']}"}


def meets(f):
    return f["median"] <= TARGET["median"] and f["p90"] <= TARGET["p90"] and f["in_range"] >= TARGET["in_range"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=DEFAULT_SCENES)
    parser.add_argument("--irfs", type=int, nargs="+", default=[16, 32, 64, 128], help=f"multiples of {CHAINS}")
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--adaptive", type=int, default=0, help="also adaptive packages of this IRF budget")
    parser.add_argument("--target", type=float, default=0.001, help="the adaptive packages' --until-fidelity")
    parser.add_argument("--first-irfs", type=int, default=0, help=f"their first round (multiple of {CHAINS}; 0: half the budget)")
    parser.add_argument("--directed-chains", type=int, help="the adaptive packages' --directed-chains (default: run's)")
    parser.add_argument("--guide-schedules", type=int, help="the adaptive packages' --guide-schedules (default: run's)")
    parser.add_argument("--fresh-schedules", type=int, help="the adaptive packages' --fresh-schedules (default: run's)")
    parser.add_argument("--held-out", type=int, default=20)
    parser.add_argument("--items", type=int, default=4)
    parser.add_argument("--fidelity-seed", type=int, default=99)
    parser.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"))
    parser.add_argument("--out", default="/tmp/fidelity-vs-irfs")
    parser.add_argument("--reuse", action="store_true", help="measure packages already in --out (minutes: -)")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    precompute = os.path.join(args.bin, "phasecast-precompute")
    results = []
    print("| scene | sampling | IRFs | seed | minutes | standard NRMSE (segment motion ratios) | held-out median / 90th pct | moving in range |")
    print("|---|---|---|---|---|---|---|---|")
    for scene in args.scenes:
        runs = [(irfs, seed, False) for irfs in args.irfs for seed in args.seeds]
        runs += [(args.adaptive, seed, True) for seed in args.seeds if args.adaptive]
        made = [(irfs, seed, adaptive, *sample(precompute, scene, args.out, seed, irfs, adaptive, args))
                for irfs, seed, adaptive in runs]
        json_path = os.path.join(args.out, os.path.basename(scene) + ".json")
        subprocess.run([precompute, "validate", scene, *[m[3] for m in made], "--schedule", standard_of(scene),
                        "--random", str(args.held_out), "--items", str(args.items), "--seed",
                        str(args.fidelity_seed), "--no-intersections", "--json", json_path],
                       check=True, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        reports = json.load(open(json_path))["packages"]
        for (irfs, seed, adaptive, _, minutes, took), report in zip(made, reports):
            f = figures(report)
            results.append({"scene": scene, "irfs": irfs, "seed": seed, "adaptive": adaptive, "minutes": minutes,
                            "sampled_irfs": took, **f})
            sampling = f"adaptive to {args.target:g}, budget {irfs}" if adaptive else "random"
            print(f"| {os.path.basename(scene)} | {sampling} | {took} | {seed} | "
                  f"{'-' if minutes is None else f'{minutes:.1f}'} | {f['standard']:.3f} ({', '.join(map(str, f['ratios']))}) | "
                  f"{f['median']:.3f} / {f['p90']:.3f} | {f['moving']} ({100 * f['in_range']:.0f} %) |", flush=True)
    for scene in args.scenes:
        enough = [irfs for irfs in args.irfs
                  if all(meets(r) for r in results if r["scene"] == scene and r["irfs"] == irfs and not r["adaptive"])]
        print(f"{scene}: every seed meets median {TARGET['median']}, 90th percentile {TARGET['p90']}, "
              f"{100 * TARGET['in_range']:.0f} % in range from {min(enough) if enough else 'none'} random IRFs")
    json.dump(results, open(os.path.join(args.out, "fidelity.json"), "w"), indent=1)


def standard_of(scene):
    """The scene's [validation] schedule (validate plays it when given no --schedule; here it is named
    so that the random schedules play beside it)."""
    with open(os.path.join(ROOT, scene), "rb") as f:
        return tomllib.load(f)["validation"]["schedule"]


if __name__ == "__main__":
    main()
