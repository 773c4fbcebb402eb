#!/usr/bin/env python3
"""Writes the MATLAB fixtures with scipy.io.savemat (an independent implementation of the MAT-file
formats), so calib's reader is tested against files it did not write.

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install scipy numpy
    calib simulate testdata/scenarios/quick.toml -o /tmp/quick.csv
    /tmp/venv/bin/python testdata/mat/make_fixture.py /tmp/quick.csv

The run is the bundled example (`quick.toml`, the same as testdata/examples/quick.mcap): 3301
samples at 200 Hz, t from 0 s, readings a and b in degrees (a .mat file has no place for units).

- quick_v4.mat (`format="4"`, Level 1.0, as MATLAB's `save -v4` writes): `data_1`, a 3 × 3301
  double matrix whose rows are t, a, b (laid out as the real recording in docs/recordings.md, one
  row per signal); the row vectors `t`, `a`, `b` (1 × 3301 double); `note`, a text matrix.
- quick_v5.mat (`format="5"`, `do_compression=True`: each variable zlib-compressed, as MATLAB's
  default `save -v7` writes): the same, plus a struct `info` with `rate_hz` (a scalar) and
  `index` (1 × 3301 int32).
"""

import csv
import os
import sys

import numpy as np
from scipy.io import savemat

HERE = os.path.dirname(os.path.abspath(__file__))


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return tuple(np.array([float(r[k]) for r in rows]) for k in ("t", "a", "b"))


def write(v4, v5, t, a, b, compress=True):
    """quick_v4.mat at `v4` and quick_v5.mat at `v5`."""
    variables = {
        "data_1": np.vstack([t, a, b]),
        "t": t,
        "a": a,
        "b": b,
        "note": "quick.toml run, degrees",
    }
    savemat(v4, variables, format="4")
    variables["info"] = {"rate_hz": 200.0, "index": np.arange(len(t), dtype=np.int32)}
    savemat(v5, variables, format="5", do_compression=compress)


def main():
    t, a, b = load(sys.argv[1] if len(sys.argv) > 1 else "quick.csv")
    write(os.path.join(HERE, "quick_v4.mat"), os.path.join(HERE, "quick_v5.mat"), t, a, b)
    seeds = os.path.join(HERE, "..", "..", "fuzz", "corpus", "mat_reader")
    os.makedirs(seeds, exist_ok=True)
    names = [os.path.join(seeds, n) for n in ("v4", "v5", "v5_uncompressed")]
    write(names[0], names[1], t[:16], a[:16], b[:16])
    write(os.path.join(seeds, "unused"), names[2], t[:16], a[:16], b[:16], compress=False)
    os.remove(os.path.join(seeds, "unused"))
    for name in names:
        with open(name, "rb") as f:
            data = f.read()
        with open(name, "wb") as f:
            f.write(b"\0" + data)


if __name__ == "__main__":
    main()
