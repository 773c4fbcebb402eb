#!/usr/bin/env python3
"""Writes the Parquet fixtures with pyarrow (Arrow's C++ Parquet writer), not with the crate
calib reads them with, so the reader is tested against what data tools write.

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install pyarrow numpy
    target/debug/calib simulate testdata/scenarios/quick.toml -o /tmp/quick.csv
    /tmp/venv/bin/python testdata/parquet/make_fixture.py /tmp/quick.csv

Files (in this script's folder):

- quick.parquet: the run of testdata/scenarios/quick.toml (the one testdata/examples/quick.mcap
  holds) as a data platform exports it: `stamp` (timestamp[ns], the run's time from
  2025-12-01T00:00:00 UTC), `a` and `b` (double, degrees); snappy (pyarrow's default), in row
  groups of 1000 rows (4 groups). The `session` column of the CSV is left out, as the MCAP has
  none.
- shapes.parquet: what calib takes and leaves, 50 rows in 2 row groups, zstd: `t_us`
  (timestamp[us, UTC]), `f32` (float), `u16`, `u32` (the values above 2^31), `i64`, `u64`, a
  nullable `gaps` (every 7th null), a struct `pose` {`x`: double, `n`: int64}, a list `xs`, a
  string `label`, a boolean `ok`; and `legacy.parquet`, the same stamps as the INT96 Spark writes
  (`use_deprecated_int96_timestamps`), gzip.
- split_v1.parquet and split_v2.parquet: 200 rows in 2 row groups in BYTE_STREAM_SPLIT encoding
  (no dictionary), data pages v1 and v2: `t` (double, s: i/100), `d` (double: i/4 - 7), `f`
  (float: i/2), `i32` (i - 100), `i64` (3i), and a nullable `gaps` (i, null where i % 5 == 0).
"""

import csv
import os
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

HERE = os.path.dirname(os.path.abspath(__file__))
START_NS = 1_764_547_200_000_000_000  # 2025-12-01T00:00:00Z


def main():
    with open(sys.argv[1], newline="") as f:
        rows = list(csv.DictReader(f))
    # The stamps as the simulator wrote them (s, decimal), in whole nanoseconds.
    stamp = np.array([START_NS + round(float(r["t"]) * 1e9) for r in rows], dtype=np.int64)
    table = pa.table(
        {
            "stamp": pa.array(stamp, pa.timestamp("ns")),
            "a": np.array([float(r["a"]) for r in rows]),
            "b": np.array([float(r["b"]) for r in rows]),
        }
    )
    pq.write_table(table, os.path.join(HERE, "quick.parquet"), row_group_size=1000)

    n = 50
    i = np.arange(n)
    t_us = START_NS // 1000 + i * 1000
    shapes = pa.table(
        {
            "t_us": pa.array(t_us, pa.timestamp("us", tz="UTC")),
            "f32": pa.array(i * 0.5, pa.float32()),
            "u16": pa.array(i, pa.uint16()),
            "u32": pa.array(i + 2**31, pa.uint32()),
            "i64": pa.array(i - 25, pa.int64()),
            "u64": pa.array(i + 2**40, pa.uint64()),
            "gaps": pa.array([None if k % 7 == 0 else float(k) for k in i], pa.float64()),
            "pose": pa.array([{"x": float(k), "n": int(k)} for k in i]),
            "xs": pa.array([[float(k), 1.0] for k in i]),
            "label": pa.array([f"row {k}" for k in i]),
            "ok": pa.array([k % 2 == 0 for k in i]),
        }
    )
    pq.write_table(shapes, os.path.join(HERE, "shapes.parquet"), row_group_size=25, compression="zstd")
    legacy = pa.table({"t": pa.array(t_us * 1000, pa.timestamp("ns")), "x": i * 1.0})
    pq.write_table(
        legacy,
        os.path.join(HERE, "legacy.parquet"),
        compression="gzip",
        use_deprecated_int96_timestamps=True,
    )
    n = 200
    i = np.arange(n)
    split = pa.table(
        {
            "t": i / 100.0,
            "d": i / 4.0 - 7.0,
            "f": pa.array(i / 2.0, pa.float32()),
            "i32": pa.array(i - 100, pa.int32()),
            "i64": pa.array(i * 3, pa.int64()),
            "gaps": pa.array([None if k % 5 == 0 else float(k) for k in i], pa.float64()),
        }
    )
    for version in ("1", "2"):
        pq.write_table(
            split,
            os.path.join(HERE, f"split_v{version}.parquet"),
            row_group_size=100,
            use_dictionary=False,
            use_byte_stream_split=True,
            data_page_version=f"{version}.0",
        )


if __name__ == "__main__":
    main()
