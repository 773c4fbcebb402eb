"""Writes the ROS 1 bag fixtures of testdata/ros1/ with the `rosbags` package's ROS 1 writer.

Each holds the bundled example run, testdata/examples/quick.mcap (`quick.toml`'s run: joints
`a` and `b`, 3301 samples at 200 Hz, as `calib simulate` writes it in CDR), moved to 1.7e9 s
(2023-11-14, a whole number of seconds, so calib's times from the first stamp's whole second
are the MCAP's own):

- quick-bz2.bag, quick-lz4.bag: every message as sensor_msgs/JointState on /joint_states,
  chunks compressed with bz2 and lz4;
- quick-none.bag: every other message (1651, 100 Hz), uncompressed (the whole run would be
  380 kB);
- quick-scalars.bag: every other sample as std_msgs/Float64 on /a and /b (one value each),
  lz4-compressed.

Header stamps and record times are the MCAP's log times (ns) plus the offset. Chunks close at
32 KiB (rosbag's default is 768 KiB) so that each bag has several. Run from the repository root
(Python with `pip install rosbags mcap`, rosbags 0.11.9 here):

    python testdata/ros1/make_fixture.py
"""

from pathlib import Path

import numpy as np

from mcap.reader import make_reader
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

OFFSET_NS = 1_700_000_000 * 10**9
CHUNK_BYTES = 32 * 1024
HERE = Path(__file__).resolve().parent
RUN = HERE.parent / "examples" / "quick.mcap"

ros1 = get_typestore(Stores.ROS1_NOETIC)
ros2 = get_typestore(Stores.ROS2_HUMBLE)
JointState = ros1.types["sensor_msgs/msg/JointState"]
Header = ros1.types["std_msgs/msg/Header"]
Time = ros1.types["builtin_interfaces/msg/Time"]
Float64 = ros1.types["std_msgs/msg/Float64"]


def samples():
    """(log time ns, joint names, positions) of each message of the run, in order."""
    with RUN.open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=True):
            assert channel.topic == "/joint_states" and channel.message_encoding == "cdr"
            js = ros2.deserialize_cdr(message.data, "sensor_msgs/msg/JointState")
            yield message.log_time, list(js.name), [float(p) for p in js.position]


def writer(name, compression):
    path = HERE / name
    path.unlink(missing_ok=True)
    w = Writer(path)
    if compression:
        w.set_compression(compression)
    w.chunk_threshold = CHUNK_BYTES
    return w


def joint_states(name, compression, step):
    with writer(name, compression) as w:
        conn = w.add_connection("/joint_states", JointState.__msgtype__, typestore=ros1)
        for n, (t, names, positions) in enumerate(samples()):
            if n % step:
                continue
            t += OFFSET_NS
            msg = JointState(
                header=Header(
                    seq=n, stamp=Time(sec=t // 10**9, nanosec=t % 10**9), frame_id=""
                ),
                name=names,
                position=np.array(positions, dtype="float64"),
                velocity=np.array([], dtype="float64"),
                effort=np.array([], dtype="float64"),
            )
            w.write(conn, t, ros1.serialize_ros1(msg, JointState.__msgtype__))


def scalars(name, compression, step):
    with writer(name, compression) as w:
        conns = {
            j: w.add_connection(f"/{j}", Float64.__msgtype__, typestore=ros1) for j in ("a", "b")
        }
        for n, (t, names, positions) in enumerate(samples()):
            if n % step:
                continue
            for j, p in zip(names, positions):
                data = ros1.serialize_ros1(Float64(data=p), Float64.__msgtype__)
                w.write(conns[j], t + OFFSET_NS, data)


joint_states("quick-bz2.bag", Writer.CompressionFormat.BZ2, 1)
joint_states("quick-lz4.bag", Writer.CompressionFormat.LZ4, 1)
joint_states("quick-none.bag", None, 2)
scalars("quick-scalars.bag", Writer.CompressionFormat.LZ4, 2)
for p in sorted(HERE.glob("*.bag")):
    print(f"{p.name}: {p.stat().st_size} bytes")
