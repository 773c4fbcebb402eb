#!/usr/bin/env python3
"""A ROS 2 JointState MCAP written by the official Python `mcap` writer, from a `calib simulate` CSV.

    python gen_python_mcap.py run.csv run-python.mcap      # needs `pip install mcap numpy`

The second writer of `benches/end-to-end.sh` (issue 26): the same samples as the MCAP `calib
simulate` writes (the `mcap` crate's writer), in the layout of a log the Python writer produces,
so that calib's reading speed can be measured on both and its results compared.

- The writer: `mcap.writer.Writer` with its defaults — zstd chunks of 1 MiB (`chunk_size=1048576`,
  counted on the uncompressed records), message indexes, a summary with repeated schemas and
  channels, statistics and summary offsets, chunk CRCs; profile `ros2`.
- The schema: `sensor_msgs/msg/JointState`, encoding `ros2msg`, the definition with its
  dependencies (`std_msgs/Header`, `builtin_interfaces/Time`) as ROS 2 stores it; one channel
  `/joint_states` (`cdr`) with the `offered_qos_profiles` rosbag2 records.
- Each message: CDR, little-endian; `header.stamp` the sample's time plus `--epoch` whole seconds
  (default 1,700,000,000: wall-clock stamps as a robot's driver sets them; the simulator's start
  at 0, and a zero stamp reads as "no stamp"), rounded to the nanosecond as calib's writer rounds
  it; `name` the joints (`a`, `b`, `ref`), `position` the readings in radians (from the CSV's
  degrees: within an ulp of the simulator's), `velocity` and `effort` empty.
- `log_time` and `publish_time`: the recorder's receive time, the stamp plus 200 µs and a seeded
  jitter below 50 µs (`--seed`), in order; `sequence` 0 — as `ros2 bag record` (Humble's MCAP
  storage) sets them.

The messages are packed with numpy a million at a time; what is left is the writer's own work per
message (about 6–7 µs: 10 M messages take a minute or more). The output is the same bytes for the
same CSV and seed. It is written under a temporary name beside the target and renamed at the end.
"""

import os
import sys
import time

from mcap.writer import CompressionType, Writer

import joint_states as js

BLOCK = 1_000_000


def main():
    parser = js.arguments(__doc__, "out", "the MCAP file to write")
    args = parser.parse_args()
    joints = args.joints.split(",")

    started = time.monotonic()
    t, positions = js.read_run(args.csv, joints)
    sec, nanosec = js.stamps(t, args.epoch)
    received = js.receive_times(js.stamp_ns(sec, nanosec), args.seed)
    read_s = time.monotonic() - started

    temp = f"{args.out}.part"
    with open(temp, "wb") as f:
        writer = Writer(f, chunk_size=1024 * 1024, compression=CompressionType.ZSTD)
        writer.start(profile="ros2")
        schema = writer.register_schema(js.JOINT_STATE, "ros2msg", js.JOINT_STATE_MSGDEF.encode())
        channel = writer.register_channel(
            args.topic, "cdr", schema, metadata={"offered_qos_profiles": js.OFFERED_QOS}
        )
        add = writer.add_message
        for start in range(0, len(t), BLOCK):
            end = min(start + BLOCK, len(t))
            rows = js.pack(joints, sec[start:end], nanosec[start:end], positions[start:end])
            size = rows.shape[1]
            data = rows.tobytes()
            times = received[start:end].tolist()
            for i, log_time in enumerate(times):
                add(channel, log_time, data[i * size : (i + 1) * size], log_time, 0)
        writer.finish()
    os.replace(temp, args.out)
    print(
        f"wrote {args.out}: {len(t)} JointState messages ({', '.join(joints)}), "
        f"{os.path.getsize(args.out) / 1e6:.0f} MB; CSV read in {read_s:.1f} s, "
        f"total {time.monotonic() - started:.1f} s",
        file=sys.stderr,
    )


if __name__ == "__main__":
    main()
