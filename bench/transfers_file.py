"""Opening a transfers file of `phasecast-precompute run|reduce --save-transfers`
(docs/transfer.md, "The transfers file"), for the bench scripts that read one."""
import sys

import h5py

FORMAT = "phasecast-stage-transfers"
REPRESENTATIVE, PICKING, REPORTED = 0, 1, 2  # /roles


def open_transfers(path, datasets):
    """The file, open for reading; exits with one line when it is not a transfers file with `datasets`."""
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        sys.exit(f"{path}: expected a transfers file of --save-transfers (HDF5): {e}")
    if f.attrs.get("format") != FORMAT:
        sys.exit(f"{path}: /@format: expected {FORMAT} (a file of --save-transfers)")
    for name in datasets:
        if name not in f:
            sys.exit(f"{path}: /{name}: missing dataset (docs/transfer.md, 'The transfers file')")
    return f
