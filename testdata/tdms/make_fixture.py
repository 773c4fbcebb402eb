#!/usr/bin/env python3
"""Writes the TDMS fixtures with nptdms (npTDMS, an independent implementation of NI's format), so
calib's reader is tested against files it did not write.

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install nptdms numpy
    calib simulate testdata/scenarios/quick.toml -o /tmp/quick.csv
    /tmp/venv/bin/python testdata/tdms/make_fixture.py /tmp/quick.csv

The run is the bundled example (`quick.toml`, the same as testdata/examples/quick.mcap): 3301
samples at 200 Hz, t from 0 s, readings a and b in degrees (the unit `calib simulate` writes to
CSV; given as each channel's `unit_string`).

- waveform.tdms: group `Encoders`, channels `a` and `b` (float64) as LabVIEW waveforms:
  `wf_increment` 0.005 s, `wf_start_time` 2023-11-14 22:13:20 UTC, `wf_start_offset` 0,
  `wf_samples`; written in three segments (the samples in thirds), the first also holding a group
  `Notes` with a string channel `operator` (which calib lists and does not take).
- timed.tdms: group `Run`, channels `t` (TDMS time stamps: 2023-11-14 22:13:20 UTC + t) and
  `a`, `b` (float64, `unit_string` deg), in two segments.

It also writes the fuzz seeds fuzz/corpus/tdms_reader/{waveform,timed}: the same files of the
first 16 samples, after the fuzz target's one byte of read options (0).
"""

import csv
import os
import sys

import numpy as np
from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

START = np.datetime64("2023-11-14T22:13:20", "us")  # 1,700,000,000 s since 1970
HERE = os.path.dirname(os.path.abspath(__file__))


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return tuple(np.array([float(r[k]) for r in rows]) for k in ("t", "a", "b"))


def write(path, t, a, b, parts):
    """waveform.tdms (`parts` segments) or timed.tdms (two segments) at `path`."""
    root = RootObject(properties={"title": "calib quick.toml run", "author": "make_fixture.py"})
    waveform = {
        "unit_string": "deg",
        "wf_increment": 0.005,
        "wf_start_time": START,
        "wf_start_offset": 0.0,
        "wf_samples": len(t),
    }
    with TdmsWriter(path["waveform"]) as w:
        for k, part in enumerate(np.array_split(np.arange(len(t)), parts)):
            objects = [
                root,
                GroupObject("Encoders", properties={"description": "quick.toml, 200 Hz"}),
                ChannelObject("Encoders", "a", a[part], properties=waveform),
                ChannelObject("Encoders", "b", b[part], properties=waveform),
            ]
            if k == 0:
                objects += [
                    GroupObject("Notes"),
                    ChannelObject("Notes", "operator", np.array(["bench 1", "calib"])),
                ]
            w.write_segment(objects)

    stamps = START + (np.round(t * 1e6)).astype("timedelta64[us]")
    deg = {"unit_string": "deg"}
    with TdmsWriter(path["timed"]) as w:
        for part in np.array_split(np.arange(len(t)), 2):
            w.write_segment(
                [
                    root,
                    GroupObject("Run"),
                    ChannelObject("Run", "t", stamps[part]),
                    ChannelObject("Run", "a", a[part], properties=deg),
                    ChannelObject("Run", "b", b[part], properties=deg),
                ]
            )


def main():
    t, a, b = load(sys.argv[1] if len(sys.argv) > 1 else "quick.csv")
    write({k: os.path.join(HERE, f"{k}.tdms") for k in ("waveform", "timed")}, t, a, b, 3)
    seeds = os.path.join(HERE, "..", "..", "fuzz", "corpus", "tdms_reader")
    os.makedirs(seeds, exist_ok=True)
    tmp = {k: os.path.join(seeds, f"{k}.tdms") for k in ("waveform", "timed")}
    write(tmp, t[:16], a[:16], b[:16], 2)
    for k, file in tmp.items():
        with open(file, "rb") as f:
            data = f.read()
        os.remove(file)
        with open(os.path.join(seeds, k), "wb") as f:
            f.write(b"\0" + data)


if __name__ == "__main__":
    main()
