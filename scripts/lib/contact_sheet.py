#!/usr/bin/env python3
"""A contact sheet of a folder of PNG frames: a grid spread evenly over them, made by ffmpeg.

  contact_sheet.py FRAMES_DIR (OUT.png | -o OUT.png) [--columns 4] [--rows 3]
  scripts/contact-sheet FRAMES_DIR -o OUT.png      (the same, for any frames folder)

Takes the PNGs of FRAMES_DIR in session order (frame_%06d.png, then
restart01_frame_%06d.png, ... after a server restart: docs/client.md), or, in
a folder without such names, every .png in natural order (frame2 before
frame10) labelled with its name; picks
columns x rows of them from the first to the last (repeating frames when there
are fewer), scales each to half the frame size, labels it with its frame number
(ffmpeg's drawtext; without labels when ffmpeg has no drawtext or no font), puts
a 2-pixel dark border around each and tiles them left to
right, top to bottom. The sheet is columns x (W/2 + 4) by rows x (H/2 + 4)
pixels for W x H frames. Prints one line saying what it made; exit status 1
with one line on stderr when it could not.
"""
import argparse
import os
import re
import shutil
import struct
import subprocess
import sys

BORDER = 2
BORDER_COLOUR = "0x0e0f12"  # darker than the renderer's backdrop background (0x1c1f24)


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    if head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        raise ValueError(f"{path} is not a PNG file")
    return struct.unpack(">II", head[16:24])


def session_order(name):
    m = re.fullmatch(r"(?:restart(\d+)_)?frame_(\d+)\.png", name)
    return (int(m.group(1) or 0), int(m.group(2))) if m else None


def label(name):
    if not session_order(name):
        return os.path.splitext(name)[0].replace("'", "").replace(":", " ")
    restart, frame = session_order(name)
    return f"restart {restart} frame {frame}" if restart else f"frame {frame}"


def natural(name):
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", name)]


def picks(names, count):
    """count names from the first to the last, evenly spaced (count <= len(names): no repeats)."""
    if count == 1:
        return [names[0]]
    return [names[round(i * (len(names) - 1) / (count - 1))] for i in range(count)]


def filter_graph(count, columns, tile, labels, names):
    tw, th = tile
    parts = []
    for i in range(count):
        chain = f"[{i}:v]scale={tw}:{th}:flags=area"
        if labels:
            size = max(8, th // 10)
            chain += (f",drawtext=text='{label(names[i])}':x={size // 2}:y={size // 2}:fontsize={size}"
                      f":fontcolor=white:box=1:boxcolor=black@0.5:boxborderw={max(1, size // 4)}")
        chain += f",pad={tw + 2 * BORDER}:{th + 2 * BORDER}:{BORDER}:{BORDER}:color={BORDER_COLOUR}[t{i}]"
        parts.append(chain)
    rows = count // columns
    for r in range(rows):
        inputs = "".join(f"[t{r * columns + c}]" for c in range(columns))
        parts.append(f"{inputs}hstack=inputs={columns}[r{r}]" if columns > 1 else f"{inputs}null[r{r}]")
    inputs = "".join(f"[r{r}]" for r in range(rows))
    parts.append(f"{inputs}vstack=inputs={rows}[sheet]" if rows > 1 else f"{inputs}null[sheet]")
    return ";".join(parts)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("frames_dir")
    parser.add_argument("out", nargs="?", help="the sheet to write (.png)")
    parser.add_argument("-o", "--output", help="the sheet to write (.png), instead of OUT")
    parser.add_argument("--columns", type=int, default=4)
    parser.add_argument("--rows", type=int, default=3)
    args = parser.parse_args()
    args.out = args.output or args.out
    if not args.out:
        sys.exit("contact_sheet: expected the sheet to write (OUT.png or -o OUT.png)")
    if not os.path.isdir(args.frames_dir):
        sys.exit(f"contact_sheet: {args.frames_dir} is not a folder of PNG frames")
    if args.columns < 1 or args.rows < 1:
        sys.exit(f"contact_sheet: --columns {args.columns} --rows {args.rows} is not a grid (expected at least 1 x 1)")
    ffmpeg = shutil.which("ffmpeg")
    if not ffmpeg:
        sys.exit("contact_sheet: ffmpeg is not on PATH (scripts/install-deps installs it)")
    names = sorted((n for n in os.listdir(args.frames_dir) if session_order(n)), key=session_order)
    if not names:
        names = sorted((n for n in os.listdir(args.frames_dir) if n.lower().endswith(".png")), key=natural)
    if not names:
        sys.exit(f"contact_sheet: {args.frames_dir} has no .png files")
    if len(names) < args.columns * args.rows:
        # Fewer frames than tiles: the widest grid of whole rows they fill, each frame at most once.
        args.columns = min(args.columns, len(names))
        args.rows = len(names) // args.columns
    count = args.columns * args.rows
    chosen = picks(names, count)
    width, height = png_size(os.path.join(args.frames_dir, chosen[0]))
    tile = (max(1, width // 2), max(1, height // 2))
    inputs = [a for n in chosen for a in ("-i", os.path.join(args.frames_dir, n))]
    error = ""
    for labels in (True, False):
        graph = filter_graph(count, args.columns, tile, labels, chosen)
        r = subprocess.run([ffmpeg, "-hide_banner", "-loglevel", "error", "-y", *inputs, "-filter_complex", graph,
                            "-map", "[sheet]", "-frames:v", "1", "-update", "1", "-pix_fmt", "rgb24", args.out],
                           capture_output=True, text=True)
        if r.returncode == 0:
            sheet = (args.columns * (tile[0] + 2 * BORDER), args.rows * (tile[1] + 2 * BORDER))
            print(f"{args.out}: {args.columns} x {args.rows} frames of {args.frames_dir}, {label(chosen[0])} to "
                  f"{label(chosen[-1])} of its {len(names)}, {sheet[0]}x{sheet[1]} pixels, "
                  f"{('labelled with their ' + ('frame numbers' if session_order(chosen[0]) else 'names')) if labels else 'without labels (no font for drawtext)'}")
            return 0
        error = (r.stderr.strip().splitlines() or ["no message"])[-1]
    sys.exit(f"contact_sheet: ffmpeg failed: {error}")


if __name__ == "__main__":
    sys.exit(main())
