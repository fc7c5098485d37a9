"""A transfers file of `--save-transfers` written with h5py, in the layout docs/transfer.md gives:
an independent writer for the bench scripts' checks."""
import h5py
import numpy as np


def write_transfers(path, fields, roles, q_u, rest, deformable, scene, labels=None):
    """fields (T, S, 3, 16); labels: each state node's cluster (default: every node its own); returns path."""
    with h5py.File(path, "w") as f:
        f["fields"] = np.asarray(fields).astype(np.float32)
        f["nodes"] = np.arange(len(roles), dtype=np.int32)
        f["roles"] = np.asarray(roles, np.uint8)
        f["q_u"] = np.asarray(q_u).astype(np.float32)
        f["cluster_labels"] = np.asarray(np.arange(len(roles)) if labels is None else labels, np.int32)
        f["rest_positions"] = np.asarray(rest).astype(np.float32)
        f["deformable"] = np.asarray(deformable, np.uint8)
        f.attrs["format"] = "phasecast-stage-transfers"
        f.attrs["format_version"] = np.int32(1)
        f.attrs["scene"] = scene
        f.attrs["rays"] = np.int32(0)
        f.attrs["bounces"] = np.int32(0)
    return path
