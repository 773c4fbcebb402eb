#!/usr/bin/env python3
"""A floor for reading an HDF5 or Parquet file: the format's own library reading every column
in one call.

    python columns_floor.py run.h5          # h5py: each dataset read whole (`ds[()]`)
    python columns_floor.py run.parquet     # pyarrow: `pyarrow.parquet.read_table` (threaded)

Prints the values read, their sum (so that nothing is skipped) and the time of the reading
itself in seconds, the interpreter's start and the imports excluded (benches/columns.sh times
the whole process as well).
"""

import sys
import time

import numpy as np

path = sys.argv[1]
if path.endswith(".parquet"):
    import pyarrow.parquet as pq

    start = time.perf_counter()
    table = pq.read_table(path)
    columns = [table[name].to_numpy() for name in table.column_names]
else:
    import h5py

    start = time.perf_counter()
    with h5py.File(path, "r") as f:
        columns = [f[name][()] for name in f.keys()]
elapsed = time.perf_counter() - start
print(f"{sum(len(c) for c in columns)} values, sum {sum(float(np.sum(c)) for c in columns):.6e}, read in {elapsed:.4f} s")
