#!/usr/bin/env python3
"""A rosbag2 SQLite bag (a folder: `metadata.yaml` and one `.db3`) of JointStates, from a
`calib simulate` CSV.

    python gen_rosbag_db3.py run.csv BAG      # needs `pip install numpy`; writes BAG/BAG_0.db3

The bag of `benches/end-to-end.sh` (issue 26), written with Python's `sqlite3` the way
`ros2 bag record` writes one with its `sqlite3` storage plugin (ROS 2 Humble, database schema
version 3):

- the tables `schema(schema_version, ros_distro)` (one row: 3, `humble`),
  `metadata(id, metadata_version, metadata)` (the bag's metadata as YAML, written when the bag is
  closed), `topics(id, name, type, serialization_format, offered_qos_profiles)` (one row:
  `/joint_states`, `sensor_msgs/msg/JointState`, `cdr`, the QoS rosbag2 records) and
  `messages(id, topic_id, timestamp, data)` with the index `timestamp_idx` on `timestamp`, created
  before the first message as the plugin does (so the index grows beside the table, as in a
  recording);
- the write-optimized pragmas the plugin sets by default (`journal_mode = MEMORY`,
  `synchronous = OFF`); messages inserted in transactions of `--batch` rows
  (`INSERT INTO messages (timestamp, topic_id, data) VALUES (?, ?, ?)`);
- `timestamp` the recorder's receive time, `data` the CDR payload with its encapsulation header:
  the messages `gen_python_mcap.py` writes (`joint_states.py`: header stamps the simulated times
  plus `--epoch` seconds, receive times 200–250 µs later, in order);
- `metadata.yaml` (version 5) naming the storage file, the topic and its message count.

The bag is built in `BAG.part` and renamed to BAG when complete; an existing BAG is refused. The
same CSV, seed and epoch give the same rows.
"""

import os
import sqlite3
import sys
import time

import joint_states as js

BLOCK = 1_000_000

SCHEMA = """
CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL,
    metadata TEXT NOT NULL);
CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
    serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
    timestamp INTEGER NOT NULL, data BLOB NOT NULL);
CREATE INDEX timestamp_idx ON messages (timestamp ASC);
INSERT INTO schema (schema_version, ros_distro) VALUES (3, 'humble');
"""


def yaml_string(s):
    """`s` as a double-quoted YAML scalar (newlines escaped), as yaml-cpp writes the QoS."""
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def metadata_yaml(db3, topic, count, start_ns, end_ns):
    """The `metadata.yaml` rosbag2 (Humble, version 5) writes for a bag of one file and one
    topic."""
    duration = end_ns - start_ns
    return f"""rosbag2_bagfile_information:
  version: 5
  storage_identifier: sqlite3
  duration:
    nanoseconds: {duration}
  starting_time:
    nanoseconds_since_epoch: {start_ns}
  message_count: {count}
  topics_with_message_count:
    - topic_metadata:
        name: {topic}
        type: {js.JOINT_STATE}
        serialization_format: cdr
        offered_qos_profiles: {yaml_string(js.OFFERED_QOS)}
      message_count: {count}
  compression_format: ""
  compression_mode: ""
  relative_file_paths:
    - {db3}
  files:
    - path: {db3}
      starting_time:
        nanoseconds_since_epoch: {start_ns}
      duration:
        nanoseconds: {duration}
      message_count: {count}
"""


def main():
    parser = js.arguments(__doc__, "bag", "the bag folder to create")
    parser.add_argument(
        "--batch", type=int, default=1000, help="messages per transaction (default 1000)"
    )
    args = parser.parse_args()
    joints = args.joints.split(",")
    bag = os.path.normpath(args.bag)
    if os.path.exists(bag):
        raise SystemExit(f"{bag} exists; give a new folder (a bag is never written over)")
    name = os.path.basename(bag)
    db3 = f"{name}_0.db3"

    started = time.monotonic()
    t, positions = js.read_run(args.csv, joints)
    sec, nanosec = js.stamps(t, args.epoch)
    received = js.receive_times(js.stamp_ns(sec, nanosec), args.seed)

    part = f"{bag}.part"
    if os.path.exists(part):
        for f in os.listdir(part):
            os.remove(os.path.join(part, f))
    else:
        os.mkdir(part)
    db = sqlite3.connect(os.path.join(part, db3), isolation_level=None)
    db.execute("PRAGMA journal_mode = MEMORY")
    db.execute("PRAGMA synchronous = OFF")
    db.executescript(SCHEMA)
    db.execute(
        "INSERT INTO topics (name, type, serialization_format, offered_qos_profiles) "
        "VALUES (?, ?, 'cdr', ?)",
        (args.topic, js.JOINT_STATE, js.OFFERED_QOS),
    )
    insert = "INSERT INTO messages (timestamp, topic_id, data) VALUES (?, ?, ?)"
    for start in range(0, len(t), BLOCK):
        end = min(start + BLOCK, len(t))
        rows = js.pack(joints, sec[start:end], nanosec[start:end], positions[start:end])
        size = rows.shape[1]
        data = rows.tobytes()
        times = received[start:end].tolist()
        for first in range(0, end - start, args.batch):
            last = min(first + args.batch, end - start)
            db.execute("BEGIN TRANSACTION")
            db.executemany(
                insert,
                ((times[i], 1, data[i * size : (i + 1) * size]) for i in range(first, last)),
            )
            db.execute("COMMIT")
    yaml = metadata_yaml(db3, args.topic, len(t), int(received[0]), int(received[-1]))
    db.execute("INSERT INTO metadata (metadata_version, metadata) VALUES (?, ?)", (5, yaml))
    db.close()
    with open(os.path.join(part, "metadata.yaml"), "w", encoding="utf-8") as f:
        f.write(yaml)
    os.rename(part, bag)
    print(
        f"wrote {bag}/{db3}: {len(t)} JointState messages ({', '.join(joints)}), "
        f"{os.path.getsize(os.path.join(bag, db3)) / 1e6:.0f} MB, "
        f"{time.monotonic() - started:.1f} s",
        file=sys.stderr,
    )


if __name__ == "__main__":
    main()
