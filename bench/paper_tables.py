#!/usr/bin/python3
"""Measures our rows of the paper's Tables 1 and 2 for the three scenes.

For each scene: `phasecast-precompute run --no-appearance` (dynamics: IRF
sampling and reduction, timed), then `run --resume` on the same checkpoints
(the appearance stage, timed: the sampled chains are reused, only the
reduction is redone), `phasecast-inspect --json` of both packages, and the
render client playing the first 8 IRFs of each package from disk (OSMesa, render-only
frames/s): without /appearance ("Defo") and with it
("Defo + Trnsfr").

  bench/paper_tables.py [--bin build/bin] [--work DIR] [--quick | --paper] [--reuse] [--size 512x512] [SCENE ...]

--quick samples 2 chains x 6 IRFs (the demo preset) instead of
phasecast-precompute's defaults. --paper runs the paper-size scenes of
scenes/paper/ (skipping scenes that have none yet) with the paper's #IRF
(Table 1) and its r_u, and adds V, DOF, both displacement errors at the
paper's r_u (its relErr, sigma_{r+1}/sigma_1 of §2.3.1, and our Frobenius
figure), and the peak memory of each stage. Prints a markdown table and
writes DIR/paper_tables.json.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import time

SCENES = ["toy_dashboard", "cloth_door", "plant_pot"]   # the paper's order: dinosaur, cloth, plant
PAPER = {  # Table 1 (F, V, r_u, relErr_u, N_a, r_a, relErr_a, N, #IRF) and Table 2 (times, SW fps)
    "toy_dashboard": ("Dinosaur", 49376, 24690, 12, "0.5%", 50, 7, "4.4%", 20010, 260, "33h 21m", "74h", 173, 82),
    "cloth_door": ("Cloth", 6365, 3310, 30, "1.5%", 200, 12, "15%", 8001, 171, "16h 46m", "71h 27m", 350, 149),
    "plant_pot": ("Plant", 6304, 3750, 18, "2.0%", 100, 12, "6.2%", 6245, 150, "≈ 1 week", "11h 40m", 472, 200),
}


# Chains x IRFs per chain giving the paper's #IRF (Table 1: 260, 171, 150).
PAPER_SAMPLING = {"toy_dashboard": (4, 65), "cloth_door": (3, 57), "plant_pot": (3, 50)}


def timed(args, log):
    """Wall seconds and peak resident memory (MiB) of one child run."""
    start = time.monotonic()
    with open(log, "w") as f:
        child = subprocess.Popen(args, stdout=f, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(child.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(args)} failed; see {log}")
    return time.monotonic() - start, usage.ru_maxrss / 1024.0


def inspect(bin_dir, package):
    out = subprocess.run([os.path.join(bin_dir, "phasecast-inspect"), package, "--json"], check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)


def render_fps(bin_dir, package, size, irfs):
    """Render-only frames/s over the first IRFs of the package (each a short
    play), weighted by their frames."""
    frames = seconds = 0.0
    for irf in range(irfs):
        out = subprocess.run([os.path.join(bin_dir, "phasecast-render"), "--package", package, "--play-irf", str(irf),
                              "--size", size, "--light", "grace", "--backdrop", "off"], check=True,
                             capture_output=True, text=True)
        m = re.search(r"(\d+) frames at \S+: ([\d.]+) frames/s render-only", out.stdout + out.stderr)
        if not m:
            raise RuntimeError(f"phasecast-render printed no frame rate for {package}")
        frames += int(m.group(1))
        seconds += int(m.group(1)) / float(m.group(2))
    return frames / seconds


def measure(scene, args):
    work = os.path.join(args.work, scene)
    os.makedirs(work, exist_ok=True)
    tool = os.path.join(args.bin, "phasecast-precompute")
    scene_file = os.path.join(args.source, "scenes", "paper" if args.paper else "", scene + ".toml")
    sampling = ["--chains", "2", "--irfs-per-chain", "6"] if args.quick else []
    if args.paper:
        chains, per_chain = PAPER_SAMPLING[scene]
        sampling = ["--chains", str(chains), "--irfs-per-chain", str(per_chain), "--rank", str(PAPER[scene][3]),
                    "--rank-a", str(PAPER[scene][6])]
    checkpoints = os.path.join(work, "checkpoints")
    defo, full = os.path.join(work, "defo.h5"), os.path.join(work, "full.h5")
    times = os.path.join(work, "times.json")
    if args.reuse and os.path.exists(times):
        saved = json.load(open(times))
        (t_dyn, mem_dyn), (t_transfer, mem_transfer) = saved[:2]
        t_reduce, mem_reduce = saved[2] if len(saved) > 2 else (None, None)
    else:
        print(f"paper_tables: {scene}: dynamics...", file=sys.stderr, flush=True)
        # The tables time the package's stages: check's trials (run's end) are left out.
        t_dyn, mem_dyn = timed([tool, "run", scene_file, "-o", defo, "--work-dir", checkpoints, "--no-appearance",
                                "--no-check", *sampling], os.path.join(work, "dynamics.log"))
        print(f"paper_tables: {scene}: transfer...", file=sys.stderr, flush=True)
        t_transfer, mem_transfer = timed([tool, "run", scene_file, "-o", full, "--work-dir", checkpoints, "--resume",
                                          "--no-check", *sampling], os.path.join(work, "transfer.log"))
        # The reduction alone on the same orbit store: its own time and peak memory (issue 17).
        print(f"paper_tables: {scene}: reduce alone...", file=sys.stderr, flush=True)
        rank = ["--rank", str(PAPER[scene][3])] if args.paper else []
        t_reduce, mem_reduce = timed([tool, "reduce", scene_file, os.path.join(checkpoints, "orbits.h5"), "-o",
                                      os.path.join(work, "reduced.h5"), "--no-appearance", *rank],
                                     os.path.join(work, "reduce.log"))
        json.dump([[t_dyn, mem_dyn], [t_transfer, mem_transfer], [t_reduce, mem_reduce]], open(times, "w"))
    s = inspect(args.bin, full)
    sigma = s["singular_values_u"]
    # V: simulated vertices, as the sampling stage prints them (the package's
    # deformable points also count the back side of sheets).
    dynamics_log = open(os.path.join(work, "dynamics.log")).read()
    m = re.search(r"^\S+: (\d+) vertices,", dynamics_log, re.M)
    vertices = int(m.group(1)) if m else None
    stages = stage_figures(dynamics_log)
    paper_r = PAPER[scene][3]
    print(f"paper_tables: {scene}: frame rates...", file=sys.stderr, flush=True)
    irfs = min(s["n_irf"], 8)
    return {
        "scene": scene, "F": s["F"], "S": s["S"], "V": vertices, "DOF": 3 * vertices if vertices else None, "r_u": s["r_u"],
        "rel_error_u": s["rel_error_u"],
        "sigma_ratio_at_paper_r_u": sigma[paper_r] / sigma[0] if len(sigma) > paper_r and sigma[0] > 0 else None,
        "peak_mib_dynamics": mem_dyn, "peak_mib_transfer": mem_transfer, "reduce_s": t_reduce,
        "peak_mib_reduce": mem_reduce, **stages,
        "N_a": s.get("N_a", 0), "r_a": s["r_a"], "rel_error_a": s["rel_error_a"], "N": s["N"], "n_irf": s["n_irf"],
        "sigma_ratio_a": s.get("sigma_ratio_a"), "held_out": s.get("held_out"),
        "transfer_weighting": s.get("transfer_weighting", "equal"),
        "dynamics_s": t_dyn, "transfer_s": t_transfer,
        "fps_defo": render_fps(args.bin, defo, args.size, irfs),
        "fps_defo_transfer": render_fps(args.bin, full, args.size, irfs),
        "frame_state_bytes": s["frame_state_bytes"], "full_vertex_frame_bytes": s["full_vertex_frame_bytes"],
    }


def stage_figures(log):
    """What `run` prints of its stages: each chain's wall time, the merge, and
    the randomized SVD's time and peak memory (docs/distributed.md's model)."""
    chains = [{"chain": int(c), "irfs": int(i), "frames": int(n), "seconds": float(t),
               "settle_s": float(settle) if settle else None}
              for c, i, n, t, settle in
              re.findall(r"chain (\d+): (\d+) IRFs, (\d+) state nodes in ([\d.]+) s(?: \(settling ([\d.]+) s)?", log)]
    merge = re.search(r"chain stores merged in ([\d.]+) s", log)
    svd = re.search(r"randomized SVD of A_u \((\d+) x (\d+)\): ([\d.]+) s", log)
    return {"chains": chains, "merge_s": float(merge.group(1)) if merge else None,
            "svd_rows": int(svd.group(1)) if svd else None, "svd_cols": int(svd.group(2)) if svd else None,
            "svd_s": float(svd.group(3)) if svd else None}


def pct(x):
    return f"{100 * x:.2g}%"


def sampling_text(args):
    if args.quick:
        return "quick sampling (2 x 6 IRFs)"
    return "the paper's #IRF, r_u and r_a" if args.paper else "phasecast-precompute defaults"


def relerr_a(r):
    """The appearance's relErr as the paper defines it (sigma_{r+1}/sigma_1 of A_a), then the Frobenius figure."""
    sigma = r.get("sigma_ratio_a")
    return f"{pct(sigma) if sigma is not None else 'n/a'} ({pct(r['rel_error_a'])})"


def held_out_text(r):
    h = r.get("held_out")
    if not h:
        return "n/a"
    l2 = f"{pct(h['l2_total'])}, truncation {pct(h['l2_truncation'])}" if h.get("l2_total") is not None else "n/a"
    # The clusters' own truncation over as many columns: what the held-out truncation compares with.
    if h.get("clusters_l2_truncation") is not None:
        l2 += f" (clusters alike: {pct(h['clusters_l2_truncation'])})"
    # The least any rank-r_a model about this M-bar reaches at those nodes: no basis or interpolant goes below.
    if h.get("l2_floor") is not None:
        l2 += f" (floor: {pct(h['l2_floor'])})"
    # Against the nodes' own variation, which no model moves, and the least any rank-r_a model has there.
    if h.get("l2_of_variation") is not None:
        l2 += (f"; of their own variation {pct(h['l2_of_variation'])} (floor {pct(h['l2_floor_of_variation'])}, "
               f"{r.get('transfer_weighting', 'equal')} weights)")
    return f"{h['nodes']} nodes: {l2} / {pct(h['total'])}{reach_text(r)}"


def reach_text(r):
    """Where Fig. 12's curve held out (truncation alone) falls to the paper's relErr_a, if within the clusters' span."""
    curve = (r.get("held_out") or {}).get("l2_truncation_curve")
    if not curve:
        return ""
    target = PAPER[r["scene"]][7]
    reached = next((rank for rank, e in enumerate(curve, 1) if 100 * e <= float(target.rstrip("%"))), None)
    where = f"from rank {reached}" if reached else "at no rank of the clusters"
    return f"; truncation held out reaches the paper's {target} {where} (all {len(curve)} directions: {pct(curve[-1])})"


def table(rows, args):
    print(f"| scene (paper) | F | V | r_u | relErr_u | N_a | r_a | relErr_a (Frobenius) | N | #IRF | dynamics | transfer "
          f"| fps Defo | fps Defo+Trnsfr | bytes/frame vs full vertices |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        p = PAPER[r["scene"]]
        print(f"| {r['scene']} | {r['F']} | {r['S']} | {r['r_u']} | {pct(r['rel_error_u'])} | {r['N_a']} | {r['r_a']} "
              f"| {relerr_a(r)} | {r['N']} | {r['n_irf']} | {r['dynamics_s']:.0f} s | {r['transfer_s']:.0f} s "
              f"| {r['fps_defo']:.0f} | {r['fps_defo_transfer']:.0f} "
              f"| {r['frame_state_bytes']} B vs {r['full_vertex_frame_bytes']} B |")
        print(f"| *{p[0]} (paper)* | {p[1]} | {p[2]} | {p[3]} | {p[4]} | {p[5]} | {p[6]} | {p[7]} | {p[8]} | {p[9]} "
              f"| {p[10]} | {p[11]} | {p[12]} | {p[13]} | |")
    print(f"\nfps: OSMesa llvmpipe, {args.size}, render-only, the first 8 IRFs played from the package; "
          f"{sampling_text(args)}.")
    if args.paper:
        print("\n| scene | V (simulated) | DOF | relErr = sigma_{r+1}/sigma_1 at the paper's r_u (§2.3.1) "
              "| Frobenius error at r_u | peak memory: dynamics run / reduce alone / transfer run "
              "| appearance held out: relErr (relative l2) / Frobenius |")
        print("|---|---|---|---|---|---|---|")
        for r in rows:
            ratio = r["sigma_ratio_at_paper_r_u"]
            reduce = f"{r['peak_mib_reduce']:.0f}" if r.get("peak_mib_reduce") is not None else "n/a"
            print(f"| {r['scene']} | {r['V']} | {r['DOF']} | {pct(ratio) if ratio is not None else 'n/a'} "
                  f"| {pct(r['rel_error_u'])} | {r['peak_mib_dynamics']:.0f} / {reduce} / {r['peak_mib_transfer']:.0f} MiB "
                  f"| {held_out_text(r)} |")
        print("\n| scene | chain: IRFs, state nodes, wall s | merge | SVD of A_u |")
        print("|---|---|---|---|")
        for r in rows:
            chains = "; ".join(f"{c['chain']}: {c['irfs']}, {c['frames']}, {c['seconds']:.0f} s" for c in r["chains"])
            svd = (f"{r['svd_rows']} x {r['svd_cols']}: {r['svd_s']:.1f} s" if r.get("svd_s") is not None else "n/a")
            merge = f"{r['merge_s']:.1f} s" if r.get("merge_s") is not None else "n/a"
            print(f"| {r['scene']} | {chains or 'n/a'} | {merge} | {svd} |")


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", metavar="SCENE", help=f"scenes among {SCENES} (default: all)")
    parser.add_argument("--bin", default=os.path.join(here, "..", "build", "bin"))
    parser.add_argument("--work", help="working folder (default: out/paper_tables, out/paper_tables_paper with --paper)")
    parser.add_argument("--quick", action="store_true", help="2 chains x 6 IRFs instead of the defaults")
    parser.add_argument("--paper", action="store_true",
                        help="the paper-size scenes of scenes/paper/ at the paper's #IRF and r_u")
    parser.add_argument("--size", default="512x512", help="render size for the frame rates")
    parser.add_argument("--reuse", action="store_true",
                        help="keep the packages and times of an earlier run in --work; measure the frame rates again")
    args = parser.parse_args()
    args.source = os.path.join(here, "..")
    if args.work is None:
        args.work = os.path.join(here, "..", "out", "paper_tables_paper" if args.paper else "paper_tables")
    unknown = [s for s in args.scenes if s not in SCENES]
    if unknown:
        parser.error(f"unknown scene {unknown[0]!r} (expected one of {', '.join(SCENES)})")
    if args.quick and args.paper:
        parser.error("--quick and --paper exclude each other")
    chosen = args.scenes or SCENES
    if args.paper:
        missing = [s for s in chosen if not os.path.exists(os.path.join(args.source, "scenes", "paper", s + ".toml"))]
        for s in missing:
            print(f"paper_tables: {s}: no paper-size scene in scenes/paper/ yet, skipped", file=sys.stderr)
        chosen = [s for s in chosen if s not in missing]
    rows = [measure(scene, args) for scene in chosen]
    os.makedirs(args.work, exist_ok=True)
    with open(os.path.join(args.work, "paper_tables.json"), "w") as f:
        json.dump(rows, f, indent=1)
    table(rows, args)


if __name__ == "__main__":
    main()
