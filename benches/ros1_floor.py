#!/usr/bin/env python3
"""A floor for reading a ROS 1 bag: the `rosbags` package's reader handing on every message.

    python ros1_floor.py run.bag          # needs `pip install rosbags`

Iterates `rosbags.rosbag1.Reader.messages()` (every connection, in time order: the index read,
each chunk decompressed, the raw message bytes handed on, not deserialized) and prints the
number of messages and bytes, so that nothing is skipped. This is what a Python user of the
reference library pays before decoding a single field.
"""

import sys

from rosbags.rosbag1 import Reader

with Reader(sys.argv[1]) as reader:
    count = size = 0
    for _, _, raw in reader.messages():
        count += 1
        size += len(raw)
print(f"{count} messages, {size} bytes")
