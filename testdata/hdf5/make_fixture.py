#!/usr/bin/env python3
"""Writes the HDF5 and MATLAB v7.3 fixtures with h5py and hdf5storage (the HDF Group's C library
underneath), not with calib's reader's crate, so the reader is tested against the files those
libraries write.

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install h5py hdf5storage numpy
    target/debug/calib simulate testdata/scenarios/quick.toml -o /tmp/quick.csv
    /tmp/venv/bin/python testdata/hdf5/make_fixture.py /tmp/quick.csv

Files (in this script's folder):

- quick.h5: the run of testdata/scenarios/quick.toml (the one testdata/examples/quick.mcap holds)
  as h5py writes it: datasets `t` (float64, seconds, attribute `unit` = "s"), `enc/a` (float64,
  degrees, attribute `unit` = "deg") and `enc/b` (float64, degrees, attribute `units` = "deg"),
  each gzip-compressed in chunks of 1024 with the shuffle filter; a string dataset `notes`, and a
  group attribute; the `session` column of the CSV is left out, as the MCAP has none.
- quick_v73.mat: the same run as MATLAB's `save -v7.3` lays it out (hdf5storage, which writes
  the 512-byte MAT-file header and the MATLAB_class attributes): `t` a 1×N row vector, `enc` the
  2×N matrix [a; b] (an N×2 dataset, MATLAB storing matrices transposed), `label` a char array.
- shapes.h5: what calib takes and leaves, small: a 2-D float32 dataset of 3×40 (`m`, channels
  m[0..2]), big-endian int16 and uint64 datasets, a 3-D dataset, a scalar, a compound dataset and
  a group of 12 datasets stored in the newest format (`libver="latest"`: dense link storage).
"""

import csv
import os
import sys

import h5py
import hdf5storage
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return tuple(np.array([float(r[k]) for r in rows]) for k in ("t", "a", "b"))


def main():
    t, a, b = load(sys.argv[1])

    with h5py.File(os.path.join(HERE, "quick.h5"), "w") as f:
        f.attrs["source"] = "calib simulate testdata/scenarios/quick.toml"
        opts = dict(compression="gzip", chunks=(1024,), shuffle=True)
        f.create_dataset("t", data=t, **opts).attrs["unit"] = "s"
        enc = f.create_group("enc")
        enc.attrs["mount"] = "coaxial"
        enc.create_dataset("a", data=a, **opts).attrs["unit"] = "deg"
        enc.create_dataset("b", data=b, **opts).attrs["units"] = "deg"
        f.create_dataset("notes", data=np.array([b"quick.toml", b"seed 1"]))

    hdf5storage.savemat(
        os.path.join(HERE, "quick_v73.mat"),
        {"t": t[np.newaxis, :], "enc": np.stack([a, b]), "label": np.str_("quick")},
        format="7.3",
        matlab_compatible=True,
    )

    with h5py.File(os.path.join(HERE, "shapes.h5"), "w", libver="latest") as f:
        x = np.arange(40, dtype=np.float64)
        f.create_dataset("m", data=np.stack([x, 2 * x, 3 * x]).astype(np.float32))
        f.create_dataset("be_i16", data=(np.arange(40) - 20).astype(">i2"))
        f.create_dataset("u64", data=np.arange(40, dtype=np.uint64) + 2**40)
        f.create_dataset("cube", data=np.zeros((2, 3, 4)))
        f.create_dataset("scalar", data=1.5)
        rec = np.zeros(4, dtype=[("x", "f8"), ("y", "i4")])
        f.create_dataset("records", data=rec)
        many = f.create_group("many")
        for i in range(12):
            many.create_dataset(f"c{i:02}", data=x * i, compression="gzip")


if __name__ == "__main__":
    main()
