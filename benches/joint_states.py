"""ROS 2 `sensor_msgs/msg/JointState` messages from a `calib simulate` CSV, packed with numpy.

Shared by `gen_python_mcap.py` and `gen_rosbag_db3.py`: both write the same messages, so that
calib's results on their logs can be compared with its results on the log `calib simulate` writes.

- `read_run`: the CSV `calib simulate SCENARIO -o run.csv` writes (`t,a,b,ref`, seconds and
  degrees, numbers that parse back to the simulator's `f64`) → times and positions in radians.
- `stamps`: each time plus a whole number of seconds (`EPOCH_S`: the simulator's times start
  at 0, a robot's stamps are wall-clock times) as a `builtin_interfaces/Time` (sec, nanosec),
  rounded to the nanosecond half away from zero as calib's MCAP writer rounds it. Without the
  offset the first message's stamp would be zero, which readers (calib among them) take for "no
  stamp" and replace by the receive time, later than the second message's stamp.
- `receive_times`: when a recorder on the same machine receives each message: the stamp plus a
  fixed transport latency and a seeded jitter, never earlier than the message before (a recorder
  takes messages in order). This is what `ros2 bag record` stores as the MCAP `log_time` and
  `publish_time` (Humble's storage plugins store the receive time in both) and as the SQLite
  `timestamp`.
- `pack`: the CDR (little-endian, with its 4-byte encapsulation header) of every message at
  once, one row of bytes per message: `header.frame_id` empty, `name` the joints, `position` the
  readings, `velocity` and `effort` empty — the layout calib's writer produces
  (`crates/calib-io/src/mcap_log/cdr.rs`, `JointStateEncoder`).
"""

import argparse
import struct

import numpy as np

# The message definition ROS 2 stores with a JointState topic (`ros2msg`, the `.msg` file with
# its dependencies), as rosbag2 writes it into an MCAP schema record (no newline at the end).
JOINT_STATE_MSGDEF = """\
# This is a message that holds data to describe the state of a set of torque controlled joints.
#
# The state of each joint (revolute or prismatic) is defined by:
#  * the position of the joint (rad or m),
#  * the velocity of the joint (rad/s or m/s) and
#  * the effort that is applied in the joint (Nm or N).
#
# Each joint is uniquely identified by its name
# The header specifies the time at which the joint states were recorded. All the joint states
# in one message have to be recorded at the same time.
#
# This message consists of a multiple arrays, one for each part of the joint state.
# The goal is to make each of the fields optional. When e.g. your joints have no
# effort associated with them, you can leave the effort array empty.
#
# All arrays in this message should have the same size, or be empty.
# This is the only way to uniquely associate the joint name with the correct
# states.

std_msgs/Header header

string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
# Standard metadata for higher-level stamped data types.
# This is generally used to communicate timestamped data
# in a particular coordinate frame.

# Two-integer timestamp that is expressed as seconds and nanoseconds.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id

================================================================================
MSG: builtin_interfaces/Time
# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

# The seconds component, valid over all int32 values.
int32 sec

# The nanoseconds component, valid in the range [0, 1e9), to be added to the seconds component.
# e.g.
# The time -1.7 seconds is represented as {sec: -2, nanosec: 3e8}
# The time 1.7 seconds is represented as {sec: 1, nanosec: 7e8}
uint32 nanosec"""

JOINT_STATE = "sensor_msgs/msg/JointState"

# The QoS rosbag2 (Humble) records for a publisher with the default profile (reliable,
# volatile, keep last), as it serializes it into `offered_qos_profiles`.
OFFERED_QOS = (
    "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n"
    "    sec: 9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n"
    "    nsec: 854775807\n  liveliness: 1\n  liveliness_lease_duration:\n"
    "    sec: 9223372036\n    nsec: 854775807\n  avoid_ros_namespace_conventions: false"
)

# Whole seconds added to the simulated times (which start at 0): 2023-11-14 22:13:20 UTC.
EPOCH_S = 1_700_000_000

# Transport latency from the driver's stamp to the recorder's receive time, and its jitter
# (uniform in [0, JITTER_NS)), in ns: a same-host DDS hop.
LATENCY_NS = 200_000
JITTER_NS = 50_000


def arguments(doc, output, output_help):
    """The generators' command line: the simulated CSV, the output, and the options they share."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("csv", help="the CSV `calib simulate SCENARIO -o run.csv` wrote")
    parser.add_argument(output, help=output_help)
    parser.add_argument("--joints", default="a,b,ref", help="columns to write (default a,b,ref)")
    parser.add_argument("--topic", default="/joint_states")
    parser.add_argument("--seed", type=int, default=26, help="seed of the receive-time jitter")
    parser.add_argument(
        "--epoch",
        type=int,
        default=EPOCH_S,
        help=f"whole seconds added to the simulated times (default {EPOCH_S})",
    )
    return parser


def read_run(path, joints):
    """Times (s) and positions (rad, one column per joint) of a `calib simulate` CSV."""
    try:
        with open(path, encoding="utf-8") as f:
            header = f.readline().strip().split(",")
    except OSError as e:
        raise SystemExit(f"{path}: cannot read it ({e.strerror}); give the CSV of a run") from e
    missing = [j for j in ["t", *joints] if j not in header]
    if missing:
        raise SystemExit(
            f"{path}: line 1: no column {', '.join(missing)} (columns: {', '.join(header)}); "
            "give the CSV `calib simulate SCENARIO -o run.csv` writes"
        )
    columns = [header.index(c) for c in ["t", *joints]]
    try:
        table = np.loadtxt(path, delimiter=",", skiprows=1, usecols=columns, ndmin=2)
    except ValueError as e:
        raise SystemExit(
            f"{path}: {str(e).rstrip('.')} (rows and columns counted from 0, after the header); "
            "every line after the header must hold numbers"
        ) from e
    if len(table) == 0:
        raise SystemExit(f"{path}: no samples after the header")
    # calib's CSV reader converts degrees as `value * (π / 180)`; numpy's deg2rad is the same.
    return table[:, 0], np.deg2rad(table[:, 1:])


def stamps(t, epoch_s):
    """`t` seconds after `epoch_s` (whole seconds) as (sec int32, nanosec uint32), rounded to
    the nanosecond half away from zero, a carry into the next second included (as calib's
    `mcap_log::write::stamp` rounds)."""
    if not (np.all(t >= 0) and epoch_s >= 0 and np.all(t + epoch_s < 2**31 - 1)):
        raise SystemExit("stamps must be non-negative and below 2^31 s to be JointState stamps")
    sec = np.floor(t)
    x = (t - sec) * 1e9
    nanosec = np.floor(x)
    nanosec += (x - nanosec) >= 0.5
    carry = nanosec >= 1e9
    sec[carry] += 1
    nanosec[carry] = 0
    return (sec + epoch_s).astype(np.int32), nanosec.astype(np.uint32)


def stamp_ns(sec, nanosec):
    """A stamp in nanoseconds (int64)."""
    return sec.astype(np.int64) * 1_000_000_000 + nanosec.astype(np.int64)


def receive_times(stamp, seed):
    """When a recorder receives each message stamped `stamp` (ns): the stamp plus
    `LATENCY_NS` and a jitter drawn from a generator seeded with `seed`, in order."""
    rng = np.random.default_rng(seed)
    received = stamp + LATENCY_NS + rng.integers(0, JITTER_NS, size=len(stamp))
    return np.maximum.accumulate(received)


def template(joints):
    """The CDR bytes of a JointState naming `joints` with zero stamp and positions, and the
    offset of its first position."""
    body = bytearray()

    def align(n):
        body.extend(b"\0" * (-len(body) % n))

    def u32(v):
        align(4)
        body.extend(struct.pack("<I", v))

    def string(s):
        u32(len(s) + 1)
        body.extend(s.encode() + b"\0")

    u32(0)  # header.stamp.sec
    u32(0)  # header.stamp.nanosec
    string("")  # header.frame_id
    u32(len(joints))
    for name in joints:
        string(name)
    u32(len(joints))
    align(8)
    positions_at = 4 + len(body)
    body.extend(b"\0" * (8 * len(joints)))
    u32(0)  # velocity
    u32(0)  # effort
    # Encapsulation: CDR, little-endian; CDR aligns relative to the body after it.
    return b"\0\1\0\0" + bytes(body), positions_at


def pack(joints, sec, nanosec, positions):
    """The CDR JointStates of these stamps and positions: an (n, size) uint8 array, one
    message per row."""
    base, at = template(joints)
    n, k = positions.shape
    rows = np.tile(np.frombuffer(base, dtype=np.uint8), (n, 1))
    rows[:, 4:8] = sec.astype("<i4").view(np.uint8).reshape(n, 4)
    rows[:, 8:12] = nanosec.astype("<u4").view(np.uint8).reshape(n, 4)
    rows[:, at : at + 8 * k] = (
        np.ascontiguousarray(positions, dtype="<f8").view(np.uint8).reshape(n, 8 * k)
    )
    return rows
