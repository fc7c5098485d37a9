#!/usr/bin/python3
"""bench/transfer_regions.py against a closed form. Two far-apart regions of
scene points whose transfer varies apart, each along one pattern with an
affine function of q_u as amplitude: a rank-1 basis per region (R = 2) holds
every state exactly, in sample and out, and the affine interpolant predicts
them; one rank-1 basis for all points (R = 1, the paper's model) leaves the
weaker region's variation, sigma_2 / sigma_1 of the representatives. The file
is written here with h5py in the layout docs/transfer.md gives, so the
script is also checked against the format as documented."""
import json
import subprocess
import sys

import numpy as np

from transfers_writer import write_transfers

script, work = sys.argv[1], sys.argv[2]
rng = np.random.default_rng(5)
S = 40  # points 0..19 near x = 0, 20..39 near x = 10
rest = np.zeros((S, 3), np.float32)
rest[:20, 0] = rng.uniform(0, 1, 20)
rest[20:, 0] = rng.uniform(10, 11, 20)
pattern = rng.normal(size=(2, 20, 48))
mean = rng.normal(size=(S, 48))
roles = np.array([0] * 10 + [1] * 5 + [2] * 5, np.uint8)
q_u = rng.normal(size=(len(roles), 2))
fields = np.empty((len(roles), S, 48))
for i, (a, b) in enumerate(q_u):
    fields[i] = mean
    fields[i, :20] += (0.3 + a) * pattern[0]
    fields[i, 20:] += (-0.1 + 0.5 * b) * pattern[1]

path = f"{work}/regions.transfers.h5"
write_transfers(path, fields.reshape(len(roles), S, 3, 16), roles, q_u, rest, np.ones(S), "two regions")

out = f"{work}/regions.json"
run = subprocess.run([script, path, "--rank-a", "1", "--regions", "1,2", "--json", out],
                     capture_output=True, text=True)
assert run.returncode == 0, run.stderr
assert "| 2 | 2 |" in run.stdout, run.stdout
figures = json.load(open(out))
rows = {r["regions"]: r for r in figures["rows"]}
assert figures["interpolant_alone"] < 1e-6, figures  # the amplitudes are affine in q_u

rep = fields[:10] - fields[:10].mean(0)
sigma = np.linalg.svd(rep.reshape(10, -1), compute_uv=False)
paper = rows[1]["refined"]["representatives"]
assert abs(paper - sigma[1] / sigma[0]) < 1e-4, (paper, sigma[1] / sigma[0])
assert paper > 0.1, paper  # the closed form is not vacuous
for kind in ("spatial", "refined"):
    for name, value in rows[2][kind].items():
        assert value < 1e-6, (kind, name, value)  # float32 storage: about 1e-7 of the fields
    assert rows[1][kind]["reported"] > 0.1, rows[1][kind]

bad = subprocess.run([script, script, "--rank-a", "1"], capture_output=True, text=True)
assert bad.returncode != 0 and bad.stderr.count("\n") == 1, bad.stderr
assert bad.stderr.startswith(f"{script}: expected a transfers file"), bad.stderr
print("transfer_regions: closed form held:", json.dumps({r: rows[r]["refined"] for r in rows}))
