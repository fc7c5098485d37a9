#!/usr/bin/python3
"""How far bases per region of scene points would take the paper's appearance model.

Reads a transfers file of `phasecast-precompute run|reduce --save-transfers`
(docs/transfer.md) and measures, for R regions of scene points, a basis of
rank r_a per region (clustered PCA after Sloan et al. 2003, over the scene
points instead of over transfer vectors): each point is still drawn from r_a
coordinates, as in the paper (§4.2), but each region has its own r_a, so a
state has R r_a of them. R = 1 is the paper's model. M-bar is the mean of the
representatives' fields (equal weights, the paper's), and every basis is cut
from the representatives alone.

Regions: k-means of the rest positions, then (--refine passes) each point
moves to the region whose state directions keep most of its variation
(k-subspaces). Printed per R, as relative l2 norms (the paper's relErr,
§2.3.1: the spectral norm of the residual over that of the centred truth):

  truncation at the representatives, at the picking half and at the reported
  half of the held-out nodes, for the spatial regions and after refinement;
  and at the reported half the total with a simple interpolant (an affine map
  of q_u fitted to the representatives plus inverse-distance weights of the
  k nearest representatives' remainders), which bounds what an interpolant
  adds once the truncation is small.

  bench/transfer_regions.py TRANSFERS.h5 --rank-a 7 [--regions 1,4,16] [--refine 8]
                            [--picking-as-samples] [--json OUT]
"""
import argparse
import json
import sys

import numpy as np

from transfers_file import PICKING, REPORTED, REPRESENTATIVE, open_transfers


def load(path):
    with open_transfers(path, ("fields", "roles", "q_u", "rest_positions")) as f:
        fields = f["fields"][()].astype(np.float64)  # T x S x 3 x 16
        return {
            "fields": fields.reshape(fields.shape[0], fields.shape[1], 48),
            "roles": f["roles"][()],
            "q_u": f["q_u"][()].astype(np.float64),
            "rest": f["rest_positions"][()].astype(np.float64),
        }


def l2(x):
    """Spectral norm of the rows of x (one row per state), by their Gram matrix."""
    g = x.reshape(x.shape[0], -1)
    return float(np.sqrt(max(np.linalg.eigvalsh(g @ g.T)[-1], 0.0))) if len(g) else 0.0


def kmeans(points, count, iterations=30, seed=0):
    rng = np.random.default_rng(seed)
    centres = points[rng.choice(len(points), count, replace=False)]
    for _ in range(iterations):
        labels = np.argmin(((points[:, None, :] - centres[None]) ** 2).sum(-1), 1)
        for k in range(count):
            if (labels == k).any():
                centres[k] = points[labels == k].mean(0)
    return labels


def region_bases(centred, labels, count, rank):
    """Per region: (state directions N_a x r, field directions r x 48|region|) of the representatives."""
    bases = []
    for k in range(count):
        block = centred[:, labels == k, :].reshape(centred.shape[0], -1)
        if block.shape[1] == 0:
            bases.append(None)
            continue
        u, _, vt = np.linalg.svd(block, full_matrices=False)
        bases.append((u[:, :rank], vt[:rank]))
    return bases


def residual(target, served, labels, bases):
    """target minus each region's projection of `served` on its field directions."""
    out = np.array(target)
    for k, basis in enumerate(bases):
        if basis is None:
            continue
        m = labels == k
        s = served[:, m, :].reshape(len(served), -1)
        out[:, m, :] -= ((s @ basis[1].T) @ basis[1]).reshape(len(served), m.sum(), 48)
    return out


def refine(centred, labels, count, rank, passes):
    """k-subspaces: each point to the region whose state directions keep most of it."""
    bases = region_bases(centred, labels, count, rank)
    per_point = centred.transpose(1, 0, 2)  # S x N_a x 48
    energy = (per_point ** 2).sum((1, 2))
    for _ in range(passes):
        lost = np.full((len(per_point), count), np.inf)
        for k, basis in enumerate(bases):
            if basis is not None:
                kept = np.einsum("nr,snc->src", basis[0], per_point)
                lost[:, k] = energy - (kept ** 2).sum((1, 2))
        labels = np.argmin(lost, 1)
        bases = region_bases(centred, labels, count, rank)
    return labels, bases


def simple_interpolant(q_rep, centred_rep, q, neighbours=4):
    """Affine map of q_u plus inverse-distance weights of the nearest representatives' remainders."""
    design = np.hstack([q_rep, np.ones((len(q_rep), 1))])
    flat = centred_rep.reshape(len(q_rep), -1)
    affine, *_ = np.linalg.lstsq(design, flat, rcond=None)
    remainder = flat - design @ affine
    out = []
    for x in q:
        d = np.linalg.norm(q_rep - x, axis=1)
        near = np.argsort(d)[:neighbours]
        w = 1.0 / (d[near] + 1e-12)
        out.append(np.append(x, 1.0) @ affine + (w / w.sum()) @ remainder[near])
    return np.array(out).reshape((len(q),) + centred_rep.shape[1:])


def measure(data, rank, regions, passes):
    """Yields one row of figures per region count, as it is measured."""
    roles, fields = data["roles"], data["fields"]
    rep = fields[roles == REPRESENTATIVE]
    mean = rep.mean(0)
    sets = {name: fields[roles == role] - mean
            for name, role in (("representatives", REPRESENTATIVE), ("picking", PICKING), ("reported", REPORTED))}
    predicted = simple_interpolant(data["q_u"][roles == REPRESENTATIVE], sets["representatives"],
                                   data["q_u"][roles == REPORTED])
    if len(sets["reported"]):  # what the interpolant misses of the whole field: no basis can serve better
        yield {"interpolant_alone": l2(sets["reported"] - predicted) / l2(sets["reported"])}
    for count in regions:
        spatial = kmeans(data["rest"], count) if count > 1 else np.zeros(len(data["rest"]), int)
        row = {"regions": count, "coordinates": count * rank}
        refined = refine(sets["representatives"], spatial, count, rank, passes if count > 1 else 0)
        for kind, (labels, bases) in (("spatial", (spatial, region_bases(sets["representatives"], spatial, count, rank))),
                                      ("refined", refined)):
            if kind == "refined":
                row["coordinates"] = sum(b[0].shape[1] for b in bases if b is not None)
            row[kind] = {name: l2(residual(d, d, labels, bases)) / l2(d) for name, d in sets.items() if len(d)}
            if len(sets["reported"]):
                row[kind]["reported_total"] = l2(residual(sets["reported"], predicted, labels, bases)) / l2(sets["reported"])
        yield row


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("transfers", help="transfers file of --save-transfers (.h5)")
    parser.add_argument("--rank-a", type=int, required=True, help="r_a: coordinates per scene point")
    parser.add_argument("--regions", default="1,4,16", help="region counts R to measure (comma-separated)")
    parser.add_argument("--refine", type=int, default=8, help="k-subspace passes after the spatial k-means")
    parser.add_argument("--picking-as-samples", action="store_true",
                        help="the picking half joins the representatives as samples (bases, M-bar, interpolant): "
                             "about what more clusters would give, measured at the same reported half")
    parser.add_argument("--json", help="also write the figures here")
    a = parser.parse_args()
    data = load(a.transfers)
    if a.picking_as_samples:
        data["roles"] = np.where(data["roles"] == PICKING, REPRESENTATIVE, data["roles"])
    regions = [int(r) for r in a.regions.split(",")]
    if a.rank_a < 1 or min(regions) < 1 or max(regions) > len(data["rest"]):
        sys.exit(f"expected --rank-a >= 1 and --regions in 1..{len(data['rest'])} (the scene points)")
    counts = {name: int((data["roles"] == role).sum()) for name, role in
              (("representatives", REPRESENTATIVE), ("picking", PICKING), ("reported", REPORTED))}
    print(f"{a.transfers}: {counts['representatives']} representatives, {counts['picking']} picking and "
          f"{counts['reported']} reported held-out nodes, {len(data['rest'])} scene points, r_a = {a.rank_a} per point", flush=True)
    print("| R | coordinates | truncation, spatial regions: representatives / picking / reported | "
          "after refinement | reported total with a simple interpolant (refined) |")
    print("|---|---|---|---|---|")
    pct = lambda d, k: f"{100 * d[k]:.1f} %" if k in d else "-"
    rows = []
    alone = None
    for r in measure(data, a.rank_a, regions, a.refine):
        if "interpolant_alone" in r:
            alone = r["interpolant_alone"]
            continue
        rows.append(r)
        s, f = r["spatial"], r["refined"]
        print(f"| {r['regions']} | {r['coordinates']} | {pct(s, 'representatives')} / {pct(s, 'picking')} / "
              f"{pct(s, 'reported')} | {pct(f, 'representatives')} / {pct(f, 'picking')} / {pct(f, 'reported')} | "
              f"{pct(f, 'reported_total')} |", flush=True)
    if alone is not None:
        print(f"the simple interpolant alone (the whole field, no truncation) leaves {100 * alone:.1f} % at the reported half")
    if a.json:
        with open(a.json, "w") as out:
            json.dump({"rank_a": a.rank_a, "nodes": counts, "interpolant_alone": alone, "rows": rows}, out, indent=1)


if __name__ == "__main__":
    main()
