#!/usr/bin/python3
"""Interpolants of q_a over q_u, and where the held-out error lives, on the stage's own transfers.

Reads a transfers file of `phasecast-precompute run|reduce --save-transfers`
(docs/transfer.md) and fits the paper's model to its representatives (M-bar
and the rank-r_a basis U_a of their fields, §4.2, equal weights or cluster
sizes), then measures at the held-out nodes, as relative l2 norms about M-bar
(the paper's relErr, §2.3.1): the truncation alone, and the served total with
each interpolant, its parameters picked at the picking half and reported at
the reported half. Everything is computed from the Gram matrix of the fields
(T x T, float64, cached beside the file as FILE.gram.npz), so a file of
gigabytes is read once (with --lobe, again for the lobe's fit and its own
Gram matrix, which is not cached).

  --exclude-box x0,y0,z0,x1,y1,z1   leave the static scene points inside the box
      out of the model and the measure (e.g. geometry no camera sees); prints
      their share of the variation
  --pairs   how alike the transfer is at states that q_u cannot tell apart:
      the semivariance 0.5 |M_i - M_j|^2 over the variance, for the pairs of
      nodes closest in q_u and for consecutive state nodes (node numbers one
      apart: mostly one frame of an IRF), how many scene points hold half of the
      closest pairs' difference and, with --exclude-box, the box's share of it all
  --lobe PACKAGE   first take off every field the unshadowed lobe at each point's
      deformed normal (bench/normal_lobe.py; PACKAGE: the package the file was
      reduced into, for its mesh, x-bar and U_u), then fit the model to what is
      left; errors stay relative to the paper model's variation, so the figures
      compare with those without it. Prints the lobe's share of the variation

  bench/transfer_interpolants.py TRANSFERS.h5 --rank-a 12 [--weighting equal|cluster-size]
                                 [--exclude-box ...] [--pairs] [--lobe PACKAGE] [--json OUT]
"""
import argparse
import json
import os
import sys

import numpy as np

from normal_lobe import Lobe
from transfers_file import PICKING, REPORTED, REPRESENTATIVE, open_transfers


def centred_gram(f, points=None, lobe=None):
    """Gram matrix of the fields (only `points`, when given; less the lobe, when given) about the
    representatives' plain mean, in float64 over column blocks; the file is read once, 64 fields at a time."""
    fields = f["fields"]

    def block(i):
        b = fields[i:i + 64] if lobe is None else fields[i:i + 64] - lobe.block(i, min(i + 64, len(fields)))
        return (b if points is None else b[:, points]).reshape(len(b), -1)

    rows = np.concatenate([block(i) for i in range(0, fields.shape[0], 64)])
    rep = f["roles"][()] == REPRESENTATIVE
    gram = np.zeros((len(rows), len(rows)))
    for j in range(0, rows.shape[1], 32768):
        block = rows[:, j:j + 32768].astype(np.float64)
        block -= block[rep].mean(0)
        gram += block @ block.T
    return gram


def cached_gram(path, f):
    """The Gram matrix, kept in PATH.gram.npz for the same file (size and modification time)."""
    cache, stat = path + ".gram.npz", os.stat(path)
    key = np.array([stat.st_size, stat.st_mtime_ns])
    if os.path.exists(cache):
        kept = np.load(cache)
        if np.array_equal(kept["key"], key):
            return kept["gram"]
    gram = centred_gram(f)
    try:
        np.savez(cache, key=key, gram=gram)
    except OSError as e:  # a folder this user cannot write: compute it again next time
        print(f"{cache}: not cached ({e.strerror})", file=sys.stderr)
    return gram


def box_points(f, box):
    rest, deformable = f["rest_positions"][()], f["deformable"][()].astype(bool)
    lo, hi = np.array(box[:3]), np.array(box[3:])
    return np.where(~deformable & np.all((rest >= lo) & (rest <= hi), axis=1))[0]


def largest_eigenvalue(g):
    return float(max(np.linalg.eigvalsh(g)[-1], 0.0)) if len(g) else 0.0


def representative_weights(roles, labels, weighting):
    """The representatives' weights, summing to 1: equal, or their clusters' share of the state nodes."""
    n = int((roles == REPRESENTATIVE).sum())
    w = np.ones(n) if weighting == "equal" else np.bincount(labels, minlength=n)[:n].astype(float)
    return w / w.sum()


class Model:
    """M-bar and U_a of the representatives' fields, weights w, in terms of the Gram matrix."""

    def __init__(self, gram, roles, labels, rank, weighting):
        self.rep = np.where(roles == REPRESENTATIVE)[0]
        w = representative_weights(roles, labels, weighting)
        shift = gram[:, self.rep] @ w  # (x - plain mean) . (weighted mean - plain mean)
        self.gram = gram - shift[:, None] - shift[None, :] + w @ gram[np.ix_(self.rep, self.rep)] @ w
        sw = np.sqrt(w)
        lam, v = np.linalg.eigh(sw[:, None] * self.gram[np.ix_(self.rep, self.rep)] * sw[None, :])
        order = np.argsort(lam)[::-1]
        self.sigma = np.sqrt(np.maximum(lam[order], 0.0))
        top = order[:rank]
        self.to_q_a = sw[:, None] * v[:, top] / np.sqrt(lam[top])  # q_a = (M - M-bar) . U_a

    def q_a(self, nodes):
        return self.gram[np.ix_(nodes, self.rep)] @ self.to_q_a


class HeldOut:
    """Held-out nodes: their truth about M-bar, its coordinates and what U_a leaves of it."""

    def __init__(self, model, nodes, reference=None):
        """Errors are relative to `reference`'s variation at the nodes (the paper's model), else the model's."""
        self.gram = model.gram[np.ix_(nodes, nodes)]
        self.q_a = model.q_a(nodes)
        self.truncated = self.gram - self.q_a @ self.q_a.T
        self.norm = np.sqrt(largest_eigenvalue((model if reference is None else reference).gram[np.ix_(nodes, nodes)]))

    def total(self, q_a_served):
        d = self.q_a - q_a_served  # orthogonal to what U_a leaves, so the Gram matrices add
        return np.sqrt(largest_eigenvalue(self.truncated + d @ d.T)) / self.norm

    def truncation(self):
        return np.sqrt(largest_eigenvalue(self.truncated)) / self.norm


def squared_distances(a, b):
    return np.maximum((a * a).sum(1)[:, None] + (b * b).sum(1)[None] - 2 * a @ b.T, 0.0)


def knn(xs, ys, x, k):
    """Inverse-distance weights of the k nearest samples."""
    d = np.sqrt(squared_distances(x, xs))
    near = np.argsort(d, 1)[:, :k]
    out = np.empty((len(x), ys.shape[1]))
    for i, idx in enumerate(near):
        if d[i, idx[0]] < 1e-12:
            out[i] = ys[idx[0]]
        else:
            w = 1.0 / d[i, idx]
            out[i] = (w / w.sum()) @ ys[idx]
    return out


def with_ones(x):
    return np.hstack([x, np.ones((len(x), 1))])


def affine_fit(xs, ys):
    return np.linalg.lstsq(with_ones(xs), ys, rcond=None)[0]


def affine(xs, ys, x):
    return with_ones(x) @ affine_fit(xs, ys)


def nrbf(xs, ys, x, width, ridge):
    """Normalized Gaussian RBFs (§4.3), widths = width x each sample's nearest-neighbour distance."""
    d = np.sqrt(squared_distances(xs, xs))
    np.fill_diagonal(d, np.inf)
    h = width * d.min(1)

    def phi(p):
        k = np.exp(-squared_distances(p, xs) / h[None] ** 2)
        return k / np.maximum(k.sum(1, keepdims=True), 1e-300)

    p = phi(xs)
    weights = np.linalg.solve(p.T @ p + ridge * np.eye(len(xs)), p.T @ ys)
    return phi(x) @ weights


def kernel_ridge(xs, ys, x, length, ridge, with_affine):
    """A Gaussian process's mean: Gaussian kernel of `length` x the samples' median distance,
    on q_u scaled to unit spread per coordinate, optionally about an affine map."""
    scale = xs.std(0) + 1e-12
    xs, x = xs / scale, x / scale
    base, rest = np.zeros((len(x), ys.shape[1])), ys
    if with_affine:
        w = affine_fit(xs, ys)
        base, rest = with_ones(x) @ w, ys - with_ones(xs) @ w
    d2 = squared_distances(xs, xs)
    ell2 = (length * np.median(np.sqrt(d2[np.triu_indices(len(xs), 1)]))) ** 2
    alpha = np.linalg.solve(np.exp(-d2 / (2 * ell2)) + ridge * np.eye(len(xs)), rest)
    return base + np.exp(-squared_distances(x, xs) / (2 * ell2)) @ alpha


def candidates(xs, ys):
    """Each interpolant with its grid of parameters, as (label, q_u -> q_a)."""
    grid = {
        "knn": [(f"k = {k}", lambda x, k=k: knn(xs, ys, x, k)) for k in (1, 2, 3, 4, 6, 8, 12) if k <= len(xs)],
        "affine": [("least squares", lambda x: affine(xs, ys, x))],
        "nrbf": [(f"width x {w}, ridge {r:g}", lambda x, w=w, r=r: nrbf(xs, ys, x, w, r))
                 for w in (0.5, 1, 2, 4, 8) for r in (1e-6, 1e-4, 1e-2, 1e-1)],
    }
    for with_affine in (False, True):
        grid["kernel ridge" + (" + affine" if with_affine else "")] = [
            (f"length x {l}, ridge {r:g}", lambda x, l=l, r=r, a=with_affine: kernel_ridge(xs, ys, x, l, r, a))
            for l in (0.1, 0.2, 0.35, 0.5, 1, 2) for r in (1e-6, 1e-4, 1e-2, 1e-1, 1)]
    return grid


def compare(gram, roles, q_u, labels, rank, weighting, paper_gram=None):
    """The figures of the model of `gram`; relative to the variation of `paper_gram`'s model when given."""
    model = Model(gram, roles, labels, rank, weighting)
    reference = None if paper_gram is None else Model(paper_gram, roles, labels, rank, weighting)
    rep = model.rep
    picking, reported = (np.where(roles == r)[0] for r in (PICKING, REPORTED))
    halves = HeldOut(model, picking, reference), HeldOut(model, reported, reference)
    sigma_1 = (model if reference is None else reference).sigma[0]
    result = {"clusters_sigma_ratio": float(model.sigma[rank] / sigma_1) if rank < len(model.sigma) else 0.0,
              "truncation": {"picking": halves[0].truncation(), "reported": halves[1].truncation()},
              "interpolants": {}}
    for name, options in candidates(q_u[rep], model.q_a(rep)).items():
        scored = []
        for label, f in options:
            try:
                scored.append((halves[0].total(f(q_u[picking])), label, f))
            except np.linalg.LinAlgError:
                continue
        best = min(scored, key=lambda s: s[0])
        result["interpolants"][name] = {"parameters": best[1], "picking": best[0],
                                        "reported": halves[1].total(best[2](q_u[reported]))}
    return result


def pairs_report(f, gram, q_u, excluded):
    """Semivariance of the closest pairs in q_u and of consecutive state nodes, and where the former lives."""
    nodes = f["nodes"][()]
    sq = np.diag(gram)
    variance = sq.mean()
    d2 = sq[:, None] + sq[None] - 2 * gram
    dq = np.sqrt(squared_distances(q_u, q_u))
    upper = np.triu_indices(len(q_u), 1)
    closest = np.argsort(dq[upper])[:100]
    order = np.argsort(nodes)
    step = np.where(np.diff(nodes[order]) == 1)[0]
    sets = {"closest in q_u": (upper[0][closest], upper[1][closest]),
            "consecutive state nodes": (order[step], order[step + 1])}
    out = {}
    for name, (i, j) in sets.items():
        out[name] = {"pairs": int(len(i)), "distance_q_u": float(dq[i, j].mean()) if len(i) else 0.0,
                     "semivariance_over_variance": float(0.5 * d2[i, j].mean() / variance) if len(i) else 0.0}
    i, j = sets["closest in q_u"]
    per_point = 0.0
    for a, b in zip(i, j):
        d = f["fields"][int(a)].astype(np.float64) - f["fields"][int(b)].astype(np.float64)
        per_point = per_point + (d ** 2).sum((1, 2))
    ranked = np.sort(per_point)[::-1]
    out["points_holding_half"] = int(np.searchsorted(np.cumsum(ranked), 0.5 * ranked.sum()) + 1)
    out["share_in_excluded"] = float(per_point[excluded].sum() / per_point.sum()) if len(excluded) else 0.0
    return out


def lobe_share(left, whole, roles, labels, weighting, weights):
    """How much of the variation about M-bar the lobe takes: over the representatives, weighted as
    the model weighs them, and over the reported half's nodes, all alike."""
    left, whole = (Model(g, roles, labels, 1, weighting).gram for g in (left, whole))
    rep, reported = np.where(roles == REPRESENTATIVE)[0], np.where(roles == REPORTED)[0]
    return {"representatives": 1 - float(weights @ np.diag(left)[rep] / (weights @ np.diag(whole)[rep])),
            "reported": 1 - float(np.diag(left)[reported].sum() / np.diag(whole)[reported].sum())}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("transfers", help="transfers file of --save-transfers (.h5)")
    parser.add_argument("--rank-a", type=int, required=True, help="r_a of the model")
    parser.add_argument("--weighting", default="equal", choices=["equal", "cluster-size"],
                        help="weights of the representatives in M-bar and the SVD (§4.2; docs/transfer.md)")
    parser.add_argument("--exclude-box", help="x0,y0,z0,x1,y1,z1: static scene points left out of the model")
    parser.add_argument("--pairs", action="store_true", help="also report how alike nearby states' transfers are")
    parser.add_argument("--lobe", metavar="PACKAGE",
                        help="take the unshadowed lobe at the deformed normal (bench/normal_lobe.py) off the fields "
                             "first; PACKAGE: the package the file was reduced into (for its mesh, x-bar and U_u)")
    parser.add_argument("--json", help="also write the figures here")
    a = parser.parse_args()
    if a.lobe and (a.exclude_box or a.pairs):
        sys.exit("--lobe: expected neither --exclude-box nor --pairs with it")
    f = open_transfers(a.transfers, ("fields", "nodes", "roles", "q_u", "cluster_labels", "rest_positions",
                                     "deformable"))
    roles, labels = f["roles"][()], f["cluster_labels"][()]
    q_u = f["q_u"][()].astype(np.float64)
    counts = [int((roles == r).sum()) for r in (REPRESENTATIVE, PICKING, REPORTED)]
    if not 1 <= a.rank_a < counts[0] or min(counts[1:]) < 1:
        sys.exit(f"{a.transfers}: expected --rank-a in 1..{counts[0] - 1} (the representatives less one) "
                 f"and held-out nodes in both halves, got {counts[1]} picking and {counts[2]} reported")
    gram = cached_gram(a.transfers, f)
    excluded = np.array([], int)
    figures = {"rank_a": a.rank_a, "weighting": a.weighting, "nodes": dict(zip(("representatives", "picking", "reported"), counts))}
    print(f"{a.transfers}: {counts[0]} representatives, {counts[1]} picking and {counts[2]} reported held-out "
          f"nodes, r_u = {q_u.shape[1]}, r_a = {a.rank_a}, {a.weighting} weights")
    if a.exclude_box:
        box = [float(v) for v in a.exclude_box.split(",")]
        if len(box) != 6:
            sys.exit(f"--exclude-box '{a.exclude_box}': expected six numbers x0,y0,z0,x1,y1,z1")
        excluded = box_points(f, box)
        inside = centred_gram(f, excluded) if len(excluded) else np.zeros_like(gram)
        share = float(np.trace(inside) / np.trace(gram))
        print(f"left out: {len(excluded)} static points in the box, {100 * share:.1f} % of the variation about the mean")
        figures.update(excluded_points=int(len(excluded)), excluded_share=share)
        gram_model = gram - inside
    else:
        gram_model = gram
    paper_gram = None
    if a.lobe:
        weights = representative_weights(roles, labels, a.weighting)
        lobe = Lobe(a.lobe, q_u, f["rest_positions"][()])
        lobe.fit(f["fields"], roles, weights)
        paper_gram, gram_model = gram, centred_gram(f, lobe=lobe)
        figures["lobe_share"] = lobe_share(gram_model, gram, roles, labels, a.weighting, weights)
        print(f"the lobe at the deformed normal takes {100 * figures['lobe_share']['representatives']:.1f} % of the "
              f"representatives' variation about M-bar ({a.weighting} weights; where it was fitted) and "
              f"{100 * figures['lobe_share']['reported']:.1f} % at the reported half's nodes")
    result = compare(gram_model, roles, q_u, labels, a.rank_a, a.weighting, paper_gram)
    figures.update(result)
    t = result["truncation"]
    print(f"clusters sigma_(r+1)/sigma_1 {100 * result['clusters_sigma_ratio']:.1f} %; truncation alone: picking "
          f"{100 * t['picking']:.1f} %, reported {100 * t['reported']:.1f} %")
    print("| interpolant | picked at the picking half | picking | reported |\n|---|---|---|---|")
    for name, r in result["interpolants"].items():
        print(f"| {name} | {r['parameters']} | {100 * r['picking']:.1f} % | {100 * r['reported']:.1f} % |")
    if a.pairs:
        p = pairs_report(f, gram, q_u, excluded)
        figures["pairs"] = p
        for name in ("closest in q_u", "consecutive state nodes"):
            r = p[name]
            print(f"{name}: {r['pairs']} pairs, |dq_u| {r['distance_q_u']:.3g}, "
                  f"semivariance / variance {r['semivariance_over_variance']:.3f}")
        print(f"half of the closest pairs' difference lies in {p['points_holding_half']} scene points"
              + (f"; {100 * p['share_in_excluded']:.0f} % of all of it in the box" if len(excluded) else ""))
    if a.json:
        with open(a.json, "w") as out:
            json.dump(figures, out, indent=1)


if __name__ == "__main__":
    main()
