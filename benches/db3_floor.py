#!/usr/bin/env python3
"""A floor for reading a rosbag2 `.db3` file of JointStates: Python's `sqlite3` and numpy.

    python db3_floor.py BAG/BAG_0.db3          # needs `pip install numpy`

Reads every row of `messages` in the order a bag is replayed (`ORDER BY timestamp, id`, through
rosbag2's `timestamp_idx`), joins the `data` blobs into one buffer and decodes every message's
positions at once with `numpy.frombuffer`: the CDR layout (where `position` starts, how many) is
found from the first message, and every message must have its length (as those
`gen_rosbag_db3.py` writes do; a bag of mixed layouts is refused). Prints the number of messages
and positions and their sum, so that nothing is skipped. One thread; the per-row cost is
Python's, so this floor is slower than a scan in C or Rust (`benches/end-to-end.sh` takes the
`sqlite3` command line tool's scan as its default floor; see `BAG_FLOOR`).
"""

import sqlite3
import struct
import sys

import numpy as np


def positions_at(msg):
    """(offset, count) of the `position` array of a little-endian CDR JointState."""
    if msg[:2] != b"\0\1":
        raise SystemExit("not a little-endian CDR message (encapsulation header)")
    body = 4

    def u32(at):
        return struct.unpack_from("<I", msg, body + at)[0]

    def align(at, n):
        return (at + n - 1) // n * n

    at = 8  # header.stamp
    at += 4 + u32(at)  # header.frame_id
    at = align(at, 4)
    names = u32(at)
    at += 4
    for _ in range(names):
        at = align(at, 4)
        at += 4 + u32(at)
    at = align(at, 4)
    count = u32(at)
    return body + align(at + 4, 8), count


def main():
    if len(sys.argv) != 2:
        raise SystemExit("usage: db3_floor.py FILE.db3")
    path = sys.argv[1]
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True)
    rows = db.execute("SELECT timestamp, data FROM messages ORDER BY timestamp, id")
    stamps = []
    blobs = []
    for timestamp, data in rows:
        stamps.append(timestamp)
        blobs.append(data)
    if not blobs:
        raise SystemExit(f"{path}: no messages")
    size = len(blobs[0])
    buf = b"".join(blobs)
    if len(buf) != size * len(blobs):
        raise SystemExit(f"{path}: messages of different lengths; this floor needs one layout")
    at, count = positions_at(blobs[0])
    rows = np.frombuffer(buf, dtype=np.uint8).reshape(len(blobs), size)
    values = rows[:, at : at + 8 * count].copy().view("<f8")
    print(
        f"{len(blobs)} messages, {values.size} positions (sum {values.sum():.6e}), "
        f"receive times {stamps[0]}…{stamps[-1]} ns"
    )


if __name__ == "__main__":
    main()
