#!/usr/bin/env python3
"""Compares a GPU run of phasecast-render with the OSMesa reference made by
bench/gpu/pack: the vertex dumps (largest position and radiance difference)
and every PNG frame (PSNR, largest channel difference). Standard library
only: the GPU machine has Python but none of our packages.

usage: compare.py REFERENCE_DIR GPU_DIR    (each with frames/*.png and vertices.csv)
Prints one line per check and exits 1 if a check fails."""
import math
import os
import struct
import sys
import zlib


def read_png(path):
    """8-bit RGB or RGBA, non-interlaced: (width, height, rows of RGB bytes)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG file")
    at, idat, width = 8, b"", 0
    while at < len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or colour not in (2, 6) or interlace:
                raise ValueError(f"{path}: expected 8-bit RGB(A), non-interlaced")
            channels = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
        at += 12 + length
    raw, stride, rows, prior = zlib.decompress(idat), width * channels, [], bytearray(width * channels)
    for y in range(height):
        kind, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for x in range(stride):
            left = line[x - channels] if x >= channels else 0
            up, corner = prior[x], prior[x - channels] if x >= channels else 0
            if kind == 1:
                line[x] = (line[x] + left) & 255
            elif kind == 2:
                line[x] = (line[x] + up) & 255
            elif kind == 3:
                line[x] = (line[x] + (left + up) // 2) & 255
            elif kind == 4:
                p = left + up - corner
                pa, pb, pc = abs(p - left), abs(p - up), abs(p - corner)
                line[x] = (line[x] + (left if pa <= pb and pa <= pc else up if pb <= pc else corner)) & 255
        rows.append(bytes(v for i, v in enumerate(line) if i % channels < 3))
        prior = line
    return width, height, rows


def image_difference(a, b):
    """(PSNR in dB, largest channel difference) of two same-size images."""
    if a[:2] != b[:2]:
        raise ValueError(f"sizes differ: {a[0]}x{a[1]} and {b[0]}x{b[1]}")
    squared, worst, count = 0, 0, 0
    for ra, rb in zip(a[2], b[2]):
        for x, y in zip(ra, rb):
            d = abs(x - y)
            squared += d * d
            worst = max(worst, d)
            count += 1
    mse = squared / count
    return (math.inf if mse == 0 else 10 * math.log10(255 ** 2 / mse)), worst


def read_dump(path):
    with open(path) as f:
        next(f)
        return [[float(v) for v in line.split(",")] for line in f if line.strip()]


def main(reference, gpu):
    failed = False
    a, b = read_dump(os.path.join(reference, "vertices.csv")), read_dump(os.path.join(gpu, "vertices.csv"))
    if len(a) != len(b):
        print(f"vertices: {len(a)} points in the reference, {len(b)} on the GPU: FAILED")
        return 1
    position = max(abs(x - y) for ra, rb in zip(a, b) for x, y in zip(ra[:3], rb[:3]))
    scale = max(1e-12, max(abs(v) for r in a for v in r[3:]))
    radiance = max(abs(x - y) for ra, rb in zip(a, b) for x, y in zip(ra[3:], rb[3:])) / scale
    ok = position <= 1e-5 and radiance <= 1e-5
    failed |= not ok
    print(f"vertices: {len(a)} points, largest difference {position:.3g} m in position, {radiance:.3g} in "
          f"radiance (relative): {'ok' if ok else 'FAILED (at most 1e-5)'}")
    names = sorted(n for n in os.listdir(os.path.join(reference, "frames")) if n.endswith(".png"))
    worst_psnr, worst_level, missing = math.inf, 0, []
    for n in names:
        g = os.path.join(gpu, "frames", n)
        if not os.path.exists(g):
            missing.append(n)
            continue
        psnr, level = image_difference(read_png(os.path.join(reference, "frames", n)), read_png(g))
        worst_psnr, worst_level = min(worst_psnr, psnr), max(worst_level, level)
    ok = not missing and worst_psnr >= 40
    failed |= not ok
    print(f"frames: {len(names) - len(missing)} of {len(names)} compared, worst PSNR {worst_psnr:.1f} dB, largest "
          f"channel difference {worst_level} levels: {'ok' if ok else 'FAILED (at least 40 dB, none missing)'}")
    return 1 if failed else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
