"""The 10 M-sample figures (opt-in: CALIB_BIG_LOG names the log, e.g. the one
`benches/end-to-end.sh` simulates; CALIB_BIN a release build of the command line).

    CALIB_BIG_LOG=/tmp/big/run.mcap CALIB_BIN=target/release/calib \\
        pytest -s crates/calib-py/tests/test_big_log.py

Prints the wall time of `calib.read` and `calib.csrr_log` on the log, and of `calib csrr` on it
(median of 3 alternating runs), and checks that `csrr_log` takes at most 10 % more than the
command (which also writes the tables and report.html) and gives the same report.
"""

import json
import os
import statistics
import subprocess
import tempfile
import time

import pytest

import calib
from conftest import calib_binary

LOG = os.environ.get("CALIB_BIG_LOG")
pytestmark = pytest.mark.skipif(not LOG, reason="set CALIB_BIG_LOG to a 10 M-sample log")


def timed(f):
    start = time.perf_counter()
    value = f()
    return time.perf_counter() - start, value


def test_read_and_csrr_log_on_a_10_m_sample_log():
    binary = calib_binary()
    assert binary, "set CALIB_BIN to the command line to compare with"
    read_s, log = timed(lambda: calib.read(LOG, channels=["a", "b"]))
    samples = len(log.t)
    del log
    print(f"\ncalib.read: {samples} samples in {read_s:.2f} s ({samples / read_s / 1e6:.1f} M/s)")
    py, cli = [], []
    with tempfile.TemporaryDirectory() as out:
        for k in range(3):
            s, res = timed(lambda: calib.csrr_log(LOG))
            py.append(s)
            s, _ = timed(
                lambda: subprocess.run([binary, "csrr", LOG, "-o", f"{out}/{k}", "-q"], check=True)
            )
            cli.append(s)
        report = json.loads(open(f"{out}/0/report.json").read())
    report.pop("command_line")
    assert res.report == report
    p, c = statistics.median(py), statistics.median(cli)
    print(f"calib.csrr_log {p:.2f} s, calib csrr {c:.2f} s: {p / c:.3f}×")
    assert p <= 1.10 * c
