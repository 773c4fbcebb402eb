"""Reading logs, the report against the command line's, tables, and errors."""

import json
import os
import subprocess

import numpy as np
import pytest

import calib
from conftest import REPO, TESTDATA, calib_binary

QUICK = "testdata/examples/quick.mcap"


def test_read_gives_time_and_radians_per_channel():
    log = calib.read(TESTDATA / "examples" / "quick.mcap")
    assert set(log.channels) == {"a", "b"}
    assert len(log.t) == len(log["a"]) == len(log["b"]) > 3000
    assert np.all(np.diff(log.t) > 0)
    # JointState positions are radians, wrapped to one turn by the scenario (wrap = true).
    assert 0.0 <= log["a"].min() and log["a"].max() < 2 * np.pi
    assert log["a"].dtype == np.float64


def test_read_a_csv_with_its_unit_and_sessions(tmp_path):
    path = tmp_path / "run.csv"
    path.write_text("t,a,b,session\n0,10,20,0\n0.5,11,21,0\n1,12,22,-1\n")
    log = calib.read(path, channels=["b", "a"], unit="deg")
    assert list(log.channels) == ["b", "a"]
    np.testing.assert_allclose(log["a"], np.radians([10, 11, 12]))
    np.testing.assert_array_equal(log.session, [0, 0, -1])
    np.testing.assert_array_equal(log.t, [0, 0.5, 1])


def test_csrr_log_report_is_the_command_lines_apart_from_provenance(tmp_path):
    """`calib csrr testdata/examples/quick.mcap`'s report.json, key for key and number for
    number, but for `command_line` (the CLI's own invocation)."""
    binary = calib_binary()
    if binary is None:
        if os.environ.get("CI"):
            pytest.fail("CI must set CALIB_BIN (or build target/*/calib) for this test")
        pytest.skip("no calib command line built to compare with (set CALIB_BIN)")
    out = tmp_path / "out"
    subprocess.run([binary, "csrr", QUICK, "-o", str(out)], cwd=REPO, check=True, capture_output=True)
    cli = json.loads((out / "report.json").read_text())
    cwd = os.getcwd()
    os.chdir(REPO)
    try:
        res = calib.csrr_log(QUICK)
    finally:
        os.chdir(cwd)
    assert cli.pop("command_line").startswith("calib csrr")
    assert "command_line" not in res.report
    assert res.report == cli
    # The tables too: the CLI's CSV rounds to 6 decimals.
    for name in ("a", "b"):
        table = calib.Table.read(out / f"{name}.csv")
        ch = res.channels[name]
        np.testing.assert_allclose(ch.error_arcsec, table.error_arcsec, atol=1e-6)
        np.testing.assert_allclose(ch.u_arcsec, table.u_arcsec, atol=1e-6)
        np.testing.assert_allclose(ch.angle_deg, table.angle_deg, atol=1e-9)


def test_csrr_log_agrees_with_the_arrays_read():
    log = calib.read(TESTDATA / "examples" / "quick.mcap")
    from_log = calib.csrr_log(TESTDATA / "examples" / "quick.mcap")
    from_arrays = calib.csrr(log["a"], log["b"], t=log.t)
    np.testing.assert_array_equal(
        from_log.channels["a"].error_arcsec, from_arrays.channels["a"].error_arcsec
    )
    assert from_arrays.report["inputs"] == []


def test_table_write_read_round_trip_and_correct(tmp_path):
    n = 3600
    grid = np.arange(n) * 2 * np.pi / n
    error = 20.0 * np.cos(8 * grid + 0.3) + 5.0 * np.sin(3 * grid)
    u = np.full(n, 0.01)
    table = calib.Table(error, u)
    table.write(tmp_path / "a.csv")
    back = calib.Table.read(tmp_path / "a.csv")
    # Written with 6 decimals.
    np.testing.assert_allclose(back.error_arcsec, error, atol=5e-7)
    np.testing.assert_allclose(back.u_arcsec, u, atol=5e-7)
    np.testing.assert_allclose(back.angle_deg, np.arange(n) * 0.1)
    # The table is the error as a function of the reading: a reading r is of the true angle
    # r − e(r), with e interpolated linearly and periodically between the grid points, as
    # numpy's periodic interp does; `correct` gives it back to rounding (1e-6″ is thousands of
    # times the float64 spacing of angles near 2π, 2·10⁻¹⁰″).
    readings = np.linspace(-1.0, 2 * np.pi + 1.0, 1001)
    truth = readings - np.interp(readings, grid, error, period=2 * np.pi) / (180 / np.pi * 3600)
    corrected = table.correct(readings)
    assert np.max(np.abs(corrected - truth)) * 180 / np.pi * 3600 < 1e-6


def test_export_and_compose():
    n = 512
    grid = np.arange(n) * 2 * np.pi / n
    table = calib.Table(30.0 * np.cos(7 * grid))
    text = calib.export(table, "moteus")
    assert text.startswith("conf set")
    harmonic = calib.export(table, "harmonic")
    assert "7" in harmonic
    # Composing with a zero residual gives the first table back.
    zero = calib.Table(np.zeros(n))
    both = calib.compose(table, zero)
    np.testing.assert_allclose(both.error_arcsec, table.error_arcsec, atol=1e-9)


def test_compose_carries_the_uncertainty_of_both_tables():
    n = 720
    grid = np.arange(n) * 2 * np.pi / n
    first = calib.Table(40.0 * np.cos(3 * grid), np.full(n, 0.3))
    residual = calib.Table(2.0 * np.sin(11 * grid), np.full(n, 0.4))
    both = calib.compose(first, residual)
    # Constant u on both: √(0.3² + 0.4²) = 0.5 at every point, wherever u_R is read.
    np.testing.assert_allclose(both.u_arcsec, 0.5, atol=1e-12)
    half = calib.compose(first, residual, factor=0.5)
    np.testing.assert_allclose(half.u_arcsec, np.hypot(0.3, 0.2), atol=1e-12)
    # Without the residual's u there is none to give (as `calib compose`).
    assert calib.compose(first, calib.Table(residual.error_arcsec)).u_arcsec is None


def test_a_range_table_round_trips_corrects_inside_only_and_exports_where_a_range_fits(tmp_path):
    n = 271
    lo, hi = -40.0, 95.0
    angles = np.linspace(lo, hi, n)
    error = 12.0 * np.sin(np.radians(angles) * 4) + 3.0
    error -= error.mean()  # a range map is zero-mean over its range
    table = calib.Table(error, np.full(n, 0.2), range_deg=(lo, hi))
    assert table.is_range
    np.testing.assert_allclose(table.angle_deg, angles, atol=1e-12)
    table.write(tmp_path / "r.csv")
    # The signed form across the reading 0, never angles above 360°.
    assert (tmp_path / "r.csv").read_text().startswith("# range_deg: -40.000000 to 95.000000")
    back = calib.Table.read(tmp_path / "r.csv")
    assert back.range_deg == pytest.approx((lo, hi), abs=1e-9)
    np.testing.assert_allclose(back.error_arcsec, error, atol=5e-7)
    np.testing.assert_allclose(back.u_arcsec, 0.2, atol=5e-7)
    # Inside the range a reading r is corrected by the table interpolated linearly (numpy's
    # interp on the signed grid); outside it is copied unchanged, as `calib apply` does.
    inside = np.radians(np.linspace(-39.0, 94.0, 501))
    expected = inside - np.interp(np.degrees(inside), angles, error) / (180 / np.pi * 3600)
    assert np.max(np.abs(back.correct(inside) - expected)) * 180 / np.pi * 3600 < 1e-6
    # −39° is also the reading 321°: the same point of the range.
    np.testing.assert_allclose(
        back.correct(inside + 2 * np.pi) - 2 * np.pi, back.correct(inside), atol=1e-12
    )
    outside = np.radians(np.array([100.0, 180.0, 300.0]))
    np.testing.assert_array_equal(back.correct(outside), outside)
    # A controller table needs a whole turn: refused, as by `calib export`; the CSV takes it.
    with pytest.raises(calib.UsageError):
        calib.export(back, "moteus")
    assert "95" in calib.export(back, "csv")
    with pytest.raises(calib.UsageError, match="whole-turn"):
        calib.compose(back, calib.Table(np.zeros(8)))
    with pytest.raises(calib.UsageError, match="range_deg"):
        calib.Table(error, range_deg=(10.0, 5.0))


def test_errors_are_the_right_exceptions(tmp_path):
    with pytest.raises(calib.UsageError, match="no such file"):
        calib.read(tmp_path / "missing.mcap")
    with pytest.raises(calib.UsageError, match="nope"):
        calib.csrr_log(TESTDATA / "examples" / "quick.mcap", a="nope")
    with pytest.raises(calib.UsageError, match="session_tol"):
        calib.csrr_log(TESTDATA / "examples" / "quick.mcap", session_tol=-1)
    with pytest.raises(calib.UsageError, match="format"):
        calib.export(calib.Table(np.zeros(8)), "nope")
    # Data that cannot be calibrated: a sensor that never moves.
    still = np.zeros(5000)
    with pytest.raises(calib.DataError):
        calib.csrr(still, still)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,a,b\n0,1,2\n1,x,3\n")
    with pytest.raises(calib.DataError, match="bad.csv"):
        calib.read(bad)
    table = tmp_path / "t.csv"
    table.write_text("angle_deg,error_arcsec,correction_arcsec\n0,1,-1\n90,2,-2\n")
    with pytest.raises(calib.DataError, match="t.csv"):
        calib.Table.read(table)
    assert issubclass(calib.DataError, calib.CalibError)
    assert issubclass(calib.UsageError, calib.CalibError)


def _in_repo(f):
    cwd = os.getcwd()
    os.chdir(REPO)
    try:
        return f()
    finally:
        os.chdir(cwd)


def test_inspect_is_the_command_lines_json():
    binary = calib_binary()
    if binary is None:
        if os.environ.get("CI"):
            pytest.fail("CI must set CALIB_BIN (or build target/*/calib) for this test")
        pytest.skip("no calib command line built to compare with (set CALIB_BIN)")
    done = subprocess.run(
        [binary, "inspect", "--json", QUICK], cwd=REPO, check=True, capture_output=True, text=True
    )
    assert _in_repo(lambda: calib.inspect(QUICK)) == json.loads(done.stdout)


def test_a_table_from_a_result_exports_for_moteus():
    res = calib.csrr_log(TESTDATA / "examples" / "quick.mcap")
    text = calib.export(res.channels["a"], "moteus")
    assert text.count("conf set") > 10


def _cli_inspect(path):
    binary = calib_binary()
    if binary is None:
        if os.environ.get("CI"):
            pytest.fail("CI must set CALIB_BIN (or build target/*/calib) for this test")
        pytest.skip("no calib command line built to compare with (set CALIB_BIN)")
    done = subprocess.run(
        [binary, "inspect", "--json", str(path)], check=True, capture_output=True, text=True
    )
    return json.loads(done.stdout)


def test_inspect_says_a_file_is_a_point_list(tmp_path):
    """A CSV without a time column is a list of stationary points (issue 25): read as the CLI
    reads it, with the points and the directions its `direction` column states."""
    path = tmp_path / "list.csv"
    path.write_text("dut;ref;direction\n10;9.999;+\n10;10.0;-\n20;19.998;+\n20;19.999;\n")
    got = calib.inspect(path)
    assert got["point_list"] is True
    assert got["points"] == 4
    assert got["stated_directions"] == 3
    assert got == _cli_inspect(path)
    timed = calib.inspect(TESTDATA / "examples" / "quick.mcap")
    assert timed["point_list"] is False and timed["points"] is None


def test_inspect_warns_of_a_time_column_in_the_wrong_unit(tmp_path):
    """Seconds under a `time_ms` header, 200 Hz turning at 60 r/min: 200 kHz at 60,000 r/min
    as read. calib.inspect warns as `calib inspect` does, in the same words but the option's
    name (issue 33)."""
    path = tmp_path / "reversed.csv"
    rows = ["time_ms,a,b"]
    for k in range(2000):
        angle = (k * 1.8) % 360.0
        rows.append(f"{k * 0.005:.3f},{angle:.4f},{(angle + 30.0) % 360.0:.4f}")
    path.write_text("\n".join(rows) + "\n")
    got = calib.inspect(path)
    hints = [w for w in got["warnings"] if "time_unit" in w]
    assert len(hints) == 1, got["warnings"]
    assert "faster than the 30000 r/min" in hints[0]
    assert "if it is in seconds, they turn at 60 r/min (200 samples per second)" in hints[0]
    # The library names its option as Python passes it; the command line says its flag.
    assert "say `time_unit = s`" in hints[0]
    cli = _cli_inspect(path)
    assert "say `--time-unit s`" in " ".join(cli["warnings"])
    cli["warnings"] = [w.replace("`--time-unit ", "`time_unit = ") for w in cli["warnings"]]
    assert got == cli


def test_a_report_says_how_its_log_was_read(tmp_path):
    """quick.mcap's run as a CSV log with integer nanosecond epoch stamps and every 50th row
    recorded twice: the reader drops the copies and reads the stamps in ns by their magnitude,
    and the result's report says so in `details.reading`, as the command line's report.json
    does (it had no `reading` from Python)."""
    log = calib.read(TESTDATA / "examples" / "quick.mcap")
    epoch_ns = 1_765_000_000 * 10**9
    rows = ["t,a,b"]
    copies = 0
    for k, (t, a, b) in enumerate(zip(log.t, np.degrees(log["a"]), np.degrees(log["b"]))):
        row = f"{epoch_ns + round((t - log.t[0]) * 1e9)},{float(a)!r},{float(b)!r}"
        rows.append(row)
        if k % 50 == 25:
            rows.append(row)
            copies += 1
    path = tmp_path / "twice.csv"
    path.write_text("\n".join(rows) + "\n")
    res = calib.csrr_log(path)
    reading = res.report["details"]["reading"]
    assert reading["duplicates_dropped"] == copies
    assert reading["time_unit"]["column"] == "t"
    assert reading["time_unit"]["unit"] == "ns"
    binary = calib_binary()
    if binary is None:
        if os.environ.get("CI"):
            pytest.fail("CI must set CALIB_BIN (or build target/*/calib) for this test")
        pytest.skip("no calib command line built to compare with (set CALIB_BIN)")
    out = tmp_path / "out"
    subprocess.run([binary, "csrr", str(path), "-o", str(out)], check=True, capture_output=True)
    cli = json.loads((out / "report.json").read_text())
    assert cli["details"]["reading"] == reading
