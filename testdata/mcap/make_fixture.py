#!/usr/bin/env python3
"""Writes fixture.mcap with the official Python MCAP packages (not with calib's own writer), so
calib's reader is tested against an independent implementation.

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install mcap mcap-ros2-support
    /tmp/venv/bin/python testdata/mcap/make_fixture.py

Contents (zstd chunks, profile ros2, with a summary):

- /joint_states  sensor_msgs/msg/JointState (cdr), 300 messages, i = 0..299:
  stamp = T0 + i * 10 ms, name = [a, b], position = [i / 64, 1 - i / 32] rad,
  velocity = [1, 2], effort = [] (so the decoder sees a non-empty and an empty sequence).
- /reference     JSON (json), {"ref": i / 4 (degrees), "status": "ok"} with log time = the same
  stamp, for every i except 100..=104; plus two messages 5 ms off the grid (after i = 10 and
  i = 20) that match no JointState stamp.
- /status        std_msgs/msg/String (cdr), 10 messages: a topic calib must ignore.

So a reader joining /joint_states and /reference gets 295 samples and 7 unjoined messages
(5 JointState messages without a partner, 2 stray JSON messages).
"""

import json
import os

from mcap.writer import CompressionType, Writer
from mcap_ros2._dynamic import serialize_dynamic

T0 = 1_700_000_000_000_000_000  # ns

JOINT_STATE = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""

STRING = "string data\n"


def main():
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fixture.mcap")
    encode_js = serialize_dynamic("sensor_msgs/msg/JointState", JOINT_STATE)[
        "sensor_msgs/msg/JointState"
    ]
    encode_str = serialize_dynamic("std_msgs/msg/String", STRING)["std_msgs/msg/String"]
    with open(out, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="ros2", library="calib make_fixture.py")
        js_schema = w.register_schema(
            "sensor_msgs/msg/JointState", "ros2msg", JOINT_STATE.encode()
        )
        str_schema = w.register_schema("std_msgs/msg/String", "ros2msg", STRING.encode())
        js = w.register_channel("/joint_states", "cdr", js_schema)
        ref = w.register_channel("/reference", "json", 0)
        status = w.register_channel("/status", "cdr", str_schema)
        seq = {js: 0, ref: 0, status: 0}

        def put(channel, t, data):
            w.add_message(channel, log_time=t, data=data, publish_time=t, sequence=seq[channel])
            seq[channel] += 1

        for i in range(300):
            t = T0 + i * 10_000_000
            msg = {
                "header": {
                    "stamp": {"sec": t // 1_000_000_000, "nanosec": t % 1_000_000_000},
                    "frame_id": "encoders",
                },
                "name": ["a", "b"],
                "position": [i / 64, 1 - i / 32],
                "velocity": [1.0, 2.0],
                "effort": [],
            }
            put(js, t, encode_js(msg))
            if not 100 <= i <= 104:
                put(ref, t, json.dumps({"ref": i / 4, "status": "ok"}).encode())
            if i in (10, 20):
                put(ref, t + 5_000_000, json.dumps({"ref": -1.0, "status": "stray"}).encode())
            if i % 30 == 0:
                put(status, t, encode_str({"data": f"running {i}"}))
        w.add_metadata("fixture", {"generator": "make_fixture.py"})
        w.finish()
    print(f"wrote {out} ({os.path.getsize(out)} bytes)")


if __name__ == "__main__":
    main()
