#!/usr/bin/env python3
"""An HDF5 and a Parquet file of the same run, from a `calib simulate` CSV, written by h5py and
pyarrow: the inputs of the HDF5 and Parquet figures in benches/README.md (issue 50).

    python gen_columns.py run.csv run.h5 run.parquet     # needs `pip install h5py pyarrow`

The CSV's `t`, `a` and `b` columns (seconds, degrees): the HDF5 file holds three float64
datasets `t` (attribute `unit` = "s"), `a` and `b` (`unit` = "deg"), each gzip-compressed with
the shuffle filter in chunks of 65536; the Parquet file the three float64 columns in one row
group, snappy-compressed (pyarrow's default), no units (calib reads degrees by default). An
existing output is refused.
"""

import os
import sys

import h5py
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq


def main():
    csv, h5, parquet = sys.argv[1:4]
    for out in (h5, parquet):
        if os.path.exists(out):
            sys.exit(f"{out} exists: remove it first")
    table = pacsv.read_csv(csv).select(["t", "a", "b"])
    columns = {name: table[name].to_numpy().astype("float64") for name in ("t", "a", "b")}
    with h5py.File(h5, "w") as f:
        for name, values in columns.items():
            ds = f.create_dataset(name, data=values, compression="gzip", shuffle=True, chunks=(65536,))
            ds.attrs["unit"] = "s" if name == "t" else "deg"
    pq.write_table(pa.table(columns), parquet, row_group_size=len(columns["t"]), compression="snappy")
    print(f"{len(columns['t'])} samples: {h5} {os.path.getsize(h5)} bytes, {parquet} {os.path.getsize(parquet)} bytes")


if __name__ == "__main__":
    main()
