#!/usr/bin/env python3
"""Writes the demo's summary (markdown, stdout) from what scripts/demo left in OUT.

  demo_summary.py OUT PACKAGE RATE

Reads OUT/inspect.json (phasecast-inspect --json), OUT/validation.json
(phasecast-precompute validate --json: playback against the full simulation),
OUT/stats.json (the server's Stats after the impulses), OUT/logs/render-{a,b}.log (the renderers' summary
lines), the size of OUT/session.glb (phasecast-export) and compares the two renderers' frames file
by file. Links OUT/contact_sheet.png
(scripts/lib/contact_sheet.py, its line in OUT/logs/contact_sheet.log) and OUT/demo.mp4 when the demo
made them, or says why not.
"""
import json
import os
import re
import shutil
import sys


def renderer_figures(log_path):
    text = open(log_path).read() if os.path.exists(log_path) else ""
    fps = re.search(r"(\d+) frames at (\d+x\d+): ([\d.]+) frames/s render-only, ([\d.]+) frames/s end-to-end", text)
    seq = re.search(r"sequence gaps .*", text)
    return fps, (seq.group(0) if seq else "no sequence line")


def compare_frames(a_dir, b_dir):
    a = set(n for n in os.listdir(a_dir) if n.endswith(".png"))
    b = set(n for n in os.listdir(b_dir) if n.endswith(".png"))
    common = sorted(a & b)
    same = sum(open(os.path.join(a_dir, n), "rb").read() == open(os.path.join(b_dir, n), "rb").read() for n in common)
    return len(a), len(b), common, same


def percent(x):
    return f"{100 * x:.3g}%" if x is not None else "n/a"


def validation_rows(path):
    """Playback fidelity of the standard schedule (docs/validation.md)."""
    if not os.path.exists(path):
        return [("playback vs full simulation", "not measured (see logs/validate.log)")]
    v = json.load(open(path))
    rows = []
    for s in v.get("schedules", []):
        segments = ", ".join(f"{g['entry']} {g['motion_ratio']:.2f}" for g in s["segments"])
        rows.append((f"playback vs full simulation: `{s['schedule']}`",
                     f"NRMSE {s['nrmse']:.3f} (0 perfect, 1 = showing the mean shape), motion ratio "
                     f"{s['motion_ratio']:.2f} (per segment: {segments}), "
                     f"self-intersecting served frames {s['frames_with_intersections']}"))
    return rows


def last_line(path):
    lines = open(path).read().strip().splitlines() if os.path.exists(path) else []
    return lines[-1] if lines else ""


def pictures(out):
    """Markdown lines for the contact sheet and the video, or why they are missing."""
    sheet, video = os.path.join(out, "contact_sheet.png"), os.path.join(out, "demo.mp4")
    if not shutil.which("ffmpeg") and not os.path.exists(sheet) and not os.path.exists(video):
        return ["No `demo.mp4` and no `contact_sheet.png`: ffmpeg is not installed (`scripts/install-deps` "
                "installs it)."]
    lines = []
    if os.path.exists(sheet):
        made = last_line(os.path.join(out, "logs", "contact_sheet.log")).split(": ", 1)[-1]
        lines += ["![Contact sheet: frames of renderer a from the first to the last](contact_sheet.png)", "",
                  f"[`contact_sheet.png`](contact_sheet.png): {made or '4 x 3 frames of renderer a'}"]
    else:
        why = last_line(os.path.join(out, "logs", "contact_sheet.log")) or "not made"
        lines += [f"No contact sheet: {why}"]
    lines.append("")
    if os.path.exists(video):
        lines.append(f"Video: [`demo.mp4`](demo.mp4) (renderer a, {os.path.getsize(video)} bytes)")
    else:
        lines.append("No video: renderer a wrote no `demo.mp4` (see `logs/render-a.log`)")
    return lines


def fidelity_row(f):
    """The package's own held-out figures (/fidelity/, stored by run --held-out-schedules)."""
    label = "held-out fidelity stored in the package"
    if not f:
        return (label, "none (run --held-out-schedules K or --until-fidelity X stores it)")
    text = (f"median NRMSE {f['median_nrmse']:.3f}, 90th percentile {f['p90_nrmse']:.3f} over {f['schedules']} "
            f"random schedules (seed {int(f['seed'])}); moving segments in [0.67, 1.5]: "
            f"{f['moving_segments_within']}/{f['moving_segments']}")
    if "adaptive" in f:
        a = f["adaptive"]
        text += (f"; sampled towards median {a['target_median_nrmse']:.3f}: "
                 f"{'met' if a['target_met'] else 'not met'} after {a['rounds']} rounds, {a['sampled_irfs']} IRFs")
    return (label, text)


def main():
    out, package, rate = sys.argv[1], sys.argv[2], float(sys.argv[3])
    instances = int(sys.argv[4]) if len(sys.argv) > 4 else 1  # a field: renderer a draws them all
    s = json.load(open(os.path.join(out, "inspect.json")))
    stats_path = os.path.join(out, "stats.json")
    stats = json.load(open(stats_path)) if os.path.exists(stats_path) else {}
    na, nb, common, same = compare_frames(os.path.join(out, "frames", "a"), os.path.join(out, "frames", "b"))

    rows = [
        ("package", f"`{os.path.relpath(package, out)}` ({os.path.getsize(package)} bytes)"),
        ("scene points S / triangles F", f"{s['S']} / {s['F']}"),
        ("state nodes N / IRFs", f"{s['N']} / {s['n_irf']}"),
        ("palette", ", ".join(s["palette"])),
        ("displacement rank r_u, rel. error", f"{s['r_u']}, {percent(s['rel_error_u'])}"),
        ("appearance rank r_a, rel. error",
         f"{s['r_a']}, {percent(s['rel_error_a'])}" if s["r_a"] else "0 (no /appearance: grey diffuse shading of the rest normals)"),
        ("thin-client download (once)", f"{s['client_download_bytes']} bytes"),
        ("bytes per frame (reduced state)", s["frame_state_bytes"]),
        ("bytes per frame (full vertex streaming)", s["full_vertex_frame_bytes"]),
        ("server tick rate", f"{rate:g} Hz"),
        ("server frames published / late ticks (when the script ended)", f"{stats.get('frames_published', '?')} / {stats.get('late_ticks', 0 if stats else '?')}"),
        ("impulses applied / refused by the palette",
         f"{stats.get('impulses_applied', 0 if stats else '?')} / {stats.get('impulses_refused', 0 if stats else '?')}"),
        ("server longest tick", f"{1e3 * float(stats.get('max_tick_seconds', 'nan')):.3g} ms"),
    ]
    for tag in ("a", "b"):
        fps, seq = renderer_figures(os.path.join(out, "logs", f"render-{tag}.log"))
        if fps:
            what = f" ({instances} instances in one view)" if tag == "a" and instances > 1 else ""
            rows.append((f"renderer {tag}{what}",
                         f"{fps.group(1)} frames at {fps.group(2)}: {fps.group(3)} frames/s render-only, "
                         f"{fps.group(4)} frames/s end-to-end; {seq}"))
        else:
            rows.append((f"renderer {tag}", "no summary line (see logs/render-%s.log)" % tag))
    check_log = os.path.join(out, "logs", "replay-check.log")
    check_lines = open(check_log).read().strip().splitlines() if os.path.exists(check_log) else []
    rows.append(("recording `session.phcrec` replay check", check_lines[-1] if check_lines else "not run"))
    rows += validation_rows(os.path.join(out, "validation.json"))
    rows.append(fidelity_row(s.get("fidelity")))
    if instances > 1:  # a field and one plant: different pictures by design
        rows.append(("renderers a / b: frames", f"{na} / {nb} (a: the field, b: instance 1; not compared)"))
        common = []
    else:
        rows.append(("renderers a / b: frames, common frames, byte-identical PNGs",
                     f"{na} / {nb}, {len(common)}, {same}"))
    glb = os.path.join(out, "session.glb")
    rows.append(("glTF export `session.glb` (phasecast-export, docs/gltf.md)",
                 f"{os.path.getsize(glb)} bytes" if os.path.exists(glb) else "failed (see logs/export.log)"))

    print(f"# Phasecast demo: scene '{s['scene']}'\n")
    print("\n".join(pictures(out)) + "\n")
    print("| figure | value |\n|---|---|")
    for k, v in rows:
        print(f"| {k} | {v} |")
    if common and same != len(common):
        print(f"\n**Warning:** {len(common) - same} common frames differ between the two renderers.")


if __name__ == "__main__":
    main()
