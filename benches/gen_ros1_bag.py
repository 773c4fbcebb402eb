#!/usr/bin/env python3
"""A ROS 1 bag (format 2.0) of JointStates, from a `calib simulate` CSV, written by `rosbags`.

    python gen_ros1_bag.py run.csv run.bag [--compression none|bz2|lz4]
    # needs `pip install numpy rosbags`

The bag of the ROS 1 figures in benches/README.md (issue 50): one `sensor_msgs/JointState` per
sample on `--topic`, the joints `--joints` (radians), `header.stamp` the simulated time plus
`--epoch` seconds and the record time the receive time 200–250 µs later (as
`gen_rosbag_db3.py`'s rows, through `joint_states.py`), chunks closed at rosbag's 768 KiB.
The messages are packed with numpy in the ROS 1 wire format (no alignment, strings without
their NUL, `uint32 seq` first in the header) and written with `rosbags.rosbag1.Writer`, whose
ROS 1 type store gives the connection's definition and MD5 sum. An existing output is refused.
"""

import struct

import joint_states as js
import numpy as np
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

CHUNK_BYTES = 768 * 1024


def template(joints):
    """The ROS 1 bytes of a JointState naming `joints` with zero seq, stamp and positions, and
    the offset of its first position."""
    body = bytearray(struct.pack("<III", 0, 0, 0))  # seq, stamp.secs, stamp.nsecs
    body += struct.pack("<I", 0)  # frame_id
    body += struct.pack("<I", len(joints))
    for name in joints:
        body += struct.pack("<I", len(name)) + name.encode()
    body += struct.pack("<I", len(joints))
    at = len(body)
    body += b"\0" * (8 * len(joints))
    body += struct.pack("<II", 0, 0)  # velocity, effort
    return bytes(body), at


def main():
    parser = js.arguments(__doc__, "bag", "the .bag file to create")
    parser.add_argument("--compression", choices=["none", "bz2", "lz4"], default="none")
    args = parser.parse_args()
    joints = args.joints.split(",")
    t, positions = js.read_run(args.csv, joints)
    sec, nanosec = js.stamps(t, args.epoch)
    received = js.receive_times(js.stamp_ns(sec, nanosec), args.seed)
    base, at = template(joints)
    n, k = positions.shape
    rows = np.tile(np.frombuffer(base, dtype=np.uint8), (n, 1))
    rows[:, 0:4] = np.arange(n, dtype="<u4").view(np.uint8).reshape(n, 4)
    rows[:, 4:8] = sec.astype("<u4").view(np.uint8).reshape(n, 4)
    rows[:, 8:12] = nanosec.astype("<u4").view(np.uint8).reshape(n, 4)
    rows[:, at : at + 8 * k] = (
        np.ascontiguousarray(positions, dtype="<f8").view(np.uint8).reshape(n, 8 * k)
    )
    ros1 = get_typestore(Stores.ROS1_NOETIC)
    writer = Writer(args.bag)
    if args.compression != "none":
        writer.set_compression(Writer.CompressionFormat[args.compression.upper()])
    writer.chunk_threshold = CHUNK_BYTES
    with writer:
        conn = writer.add_connection(args.topic, "sensor_msgs/msg/JointState", typestore=ros1)
        for row, time in zip(rows, received.tolist()):
            writer.write(conn, time, row.tobytes())
    print(f"{args.bag}: {n} messages ({args.compression})")


if __name__ == "__main__":
    main()
