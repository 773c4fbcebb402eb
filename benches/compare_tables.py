#!/usr/bin/env python3
"""Compares the correction tables two `calib csrr` runs wrote (no third-party packages).

    python compare_tables.py OUT1 OUT2 a.csv b.csv

For each table: the same grid, then the largest difference of `error_arcsec` and of `u_arcsec`
between the two, against a quarter of the smallest `u_arcsec` of the two tables. The logs
`benches/end-to-end.sh` compares hold the same samples but for rounding (times stamped from
another origin, positions within an ulp of the simulator's after the CSV's degrees), which can
move a sample across a segment's edge or the solver's stopping test; that changes the maps by far
less than what the run cannot tell (`u`), and more would mean a writer's log was read
differently. Prints one line per table; exits 1 if a table differs beyond that.
"""

import csv
import sys


def load(path):
    with open(path, newline="", encoding="utf-8") as f:
        rows = csv.reader(line for line in f if not line.startswith("#"))
        header = next(rows)
        return header, [[float(v) for v in row] for row in rows]


def main():
    if len(sys.argv) < 4:
        raise SystemExit("usage: compare_tables.py OUT1 OUT2 TABLE.csv...")
    first, second, tables = sys.argv[1], sys.argv[2], sys.argv[3:]
    failed = False
    for table in tables:
        ha, a = load(f"{first}/{table}")
        hb, b = load(f"{second}/{table}")
        if ha != hb or len(a) != len(b) or any(x[0] != y[0] for x, y in zip(a, b)):
            print(f"{table}: different grids or columns ({len(a)} and {len(b)} rows)")
            failed = True
            continue
        err, u = ha.index("error_arcsec"), ha.index("u_arcsec")
        d_err = max(abs(x[err] - y[err]) for x, y in zip(a, b))
        d_u = max(abs(x[u] - y[u]) for x, y in zip(a, b))
        bound = 0.25 * min(min(x[u] for x in a), min(y[u] for y in b))
        same = d_err <= bound and d_u <= bound
        failed |= not same
        print(
            f"{table}: max |Δ error| {d_err:.2e}″, max |Δ u| {d_u:.2e}″ "
            f"({'within' if same else 'BEYOND'} u/4 = {bound:.2e}″)"
        )
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
