"""Each method on simulated data against its truth, with the Rust tests' tolerances."""

import numpy as np
import pytest

import calib
from conftest import TESTDATA

ARCSEC_PER_RAD = 180.0 / np.pi * 3600.0


def max_abs_diff(estimate: calib.Table, truth: calib.Table) -> float:
    """Largest |estimate − truth| in arcseconds on the truth's grid, both with zero mean
    (the estimate interpolated linearly, as calib's `ErrorMap::minus` does)."""
    grid = np.radians(truth.angle_deg)
    e = estimate.error_at(grid)
    d = e - truth.error_arcsec
    return float(np.max(np.abs(d - d.mean())))


def test_csrr_on_arrays_finds_the_72_pole_pair_maps_within_0_2_arcsec():
    # The bar of calib-core's tests/it/csrr_accuracy.rs (table_ii_72_pole_pairs_within_0_2_arcsec):
    # the joint fit is exact for these orders, and what is left is the noise (0.05″ per sample)
    # averaged over ~36 000 samples and the interpolation of the table.
    sim = calib.simulate(TESTDATA / "scenarios" / "csrr72.toml")
    res = calib.csrr(sim["a"], sim["b"], t=sim.t)
    assert len(res.report["sessions"]) == 5
    for name in ("a", "b"):
        ch = res.channels[name]
        err = max_abs_diff(ch.table, sim.truth[name])
        assert err <= 0.2, f"{name}: max |map − truth| {err:.4f}″"
        # The uncertainty covers the error: |map − truth| ≤ 2u at 90–99.9 % of the points, as
        # in the Rust test (the truth on the table's own grid).
        on_grid = calib.simulate(TESTDATA / "scenarios" / "csrr72.toml", points=len(ch.error_arcsec))
        d = ch.error_arcsec - on_grid.truth[name].error_arcsec
        d -= d.mean()
        inside = np.mean(np.abs(d) <= 2 * ch.u_arcsec)
        assert 0.90 <= inside <= 0.999, f"{name}: coverage {inside}"
    # The largest harmonic of A is its order 72 of 23.87″ (the scenario's).
    top = res.channels["a"].harmonics[0]
    assert top["order"] == 72
    assert abs(top["amplitude_arcsec"] - 23.87) < 0.05


def test_csrr_sessions_given_as_an_array_are_used():
    sim = calib.simulate(TESTDATA / "scenarios" / "quick.toml")
    assert sim.session is not None
    res = calib.csrr(sim["a"], sim["b"], t=sim.t, sessions=sim.session)
    assert len(res.report["sessions"]) == 5
    for name in ("a", "b"):
        # quick.toml's harmonics at 0.05″ noise and 0.09″ quantization over 3300 samples:
        # the CLI's own figures on this run are within 0.01″ of the amplitudes; 0.1″ is loose.
        assert max_abs_diff(res.channels[name].table, sim.truth[name]) < 0.1


REFERENCE_SCENARIO = """
seed = 3
rate_hz = 1000.0
speed_rpm = 60.0
[[sensor]]
name = "b"
harmonics = [
  { order = 6, amplitude_arcsec = 15.0, phase_deg = -120.0 },
  { order = 2, amplitude_arcsec = 2.0, phase_deg = 60.0 },
]
quantization_arcsec = 0.09
noise_arcsec = 0.05
[[sensor]]
name = "ref"
harmonics = [{ order = 1, amplitude_arcsec = 0.45, phase_deg = 30.0 }]
quantization_arcsec = 0.001
noise_arcsec = 0.01
[procedure]
relative_deg = [0.0]
revolutions = 5.0
ramp_s = 0.25
pause_s = 0.2
turn_s = 0.5
"""


def test_reference_finds_the_dut_minus_reference_within_0_2_arcsec():
    # calib-core's examples/reference.rs, same scenario and bar: the map is DUT − reference,
    # each point the mean of ~14 passes of 0.05″ noise and 0.09″ quantization.
    sim = calib.simulate(REFERENCE_SCENARIO, points=3600)
    res = calib.reference(sim["b"], sim["ref"], t=sim.t, names=("b", "ref"))
    ch = res.channels["b"]
    assert not ch.is_range
    truth = calib.Table(sim.truth["b"].error_arcsec - sim.truth["ref"].error_arcsec)
    err = max_abs_diff(ch.table, truth)
    assert err < 0.2, f"max |map − truth| {err:.4f}″"
    assert res.report["method"] == "reference"
    assert np.all(ch.u_arcsec > 0)


def test_a_joint_that_never_turns_gives_a_range_table_in_its_own_reading_convention(tmp_path):
    # The backlash scenario: a joint swept −40…95°, readings wrapped to [0°, 360°), 30″ of play.
    # cli/tests/it/reference_setups_cli.rs finds the CLI's map within 0.11″ of the truth on it.
    sim = calib.simulate(TESTDATA / "scenarios" / "backlash.toml", points=36000)
    res = calib.reference(sim["dut"], sim["ref"], t=sim.t, names=("dut", "ref"), ref_u=0.01)
    ch = res.channels["dut"]
    assert ch.is_range
    lo, hi = ch.range_deg
    assert -40.5 < lo < -39.0 and 94.0 < hi < 95.5, ch.range_deg
    np.testing.assert_allclose(ch.angle_deg[[0, -1]], [lo, hi])
    table = ch.table
    assert table.is_range and table.range_deg == ch.range_deg
    # Against the truth over the range, both zero-mean there (a range map's mean is its own).
    truth = calib.Table(sim.truth["dut"].error_arcsec - sim.truth["ref"].error_arcsec)
    at = np.radians(table.angle_deg)
    expected = truth.error_at(at)
    expected -= expected.mean()
    err = np.max(np.abs(table.error_arcsec - expected))
    assert err < 0.2, f"max |map − truth| {err:.4f}″"
    table.write(tmp_path / "dut.csv")
    assert calib.Table.read(tmp_path / "dut.csv").range_deg == pytest.approx(ch.range_deg, abs=1e-6)


def test_simulate_takes_a_dict_and_gives_the_same_run_as_its_toml():
    as_dict = {
        "seed": 3,
        "rate_hz": 1000.0,
        "speed_rpm": 60.0,
        "sensor": [
            {
                "name": "b",
                "harmonics": [
                    {"order": 6, "amplitude_arcsec": 15.0, "phase_deg": -120.0},
                    {"order": 2, "amplitude_arcsec": 2.0, "phase_deg": 60.0},
                ],
                "quantization_arcsec": 0.09,
                "noise_arcsec": 0.05,
            },
            {
                "name": "ref",
                "harmonics": [{"order": 1, "amplitude_arcsec": 0.45, "phase_deg": 30.0}],
                "quantization_arcsec": 0.001,
                "noise_arcsec": 0.01,
            },
        ],
        "procedure": {
            "relative_deg": [0.0],
            "revolutions": 5.0,
            "ramp_s": 0.25,
            "pause_s": 0.2,
            "turn_s": 0.5,
        },
    }
    a = calib.simulate(as_dict, points=3600)
    b = calib.simulate(REFERENCE_SCENARIO, points=3600)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a["b"], b["b"])
    np.testing.assert_array_equal(a.truth["b"].error_arcsec, b.truth["b"].error_arcsec)


def test_threads_run_in_parallel_and_give_the_same_result():
    from concurrent.futures import ThreadPoolExecutor

    sim = calib.simulate(TESTDATA / "scenarios" / "quick.toml")
    one = calib.csrr(sim["a"], sim["b"], t=sim.t)
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda _: calib.csrr(sim["a"], sim["b"], t=sim.t), range(4)))
    for r in results:
        np.testing.assert_array_equal(r.channels["a"].error_arcsec, one.channels["a"].error_arcsec)


def test_tdr_recovers_the_encoder_map_from_a_free_coast():
    # calib-core's tests/it/tdr.rs (air_bearing_coast_recovers_the_encoder_map), same scenario and
    # bar: σ ≈ 0.057″ per sample over 60 000 samples and 64 unknowns give a map rms ≈ 0.002″;
    # 0.02″ bounds its maximum over 3600 points (measured there: 0.0044″).
    sim = calib.simulate(TESTDATA / "scenarios" / "spindown.toml", points=3600)
    name = "enc"
    res = calib.tdr(sim.t, sim[name], sim["ref"], name=name)
    ch = res.channels[name]
    d = ch.error_arcsec - sim.truth[name].error_arcsec
    err = float(np.max(np.abs(d - d.mean())))
    assert err < 0.02, f"max |map − truth| {err:.4f}″"
    assert res.method == "tdr"
    # Checked against the reference encoder on the shaft.
    assert "after_correction" in ch.report


def test_tdr_takes_a_driven_run_and_names_the_motor_orders():
    # calib-core's tests/it/tdr.rs (a_driven_run_recovers_the_map_off_the_motor_orders), same
    # scenario: one speed, so the motor's orders 42, 84, 126 are left out of the map and listed;
    # the map's orders 1 and 2 (600″, 250″) come back within the noise of each coefficient
    # (0.17″) and the cross terms below the detection limit (0.75″).
    sim = calib.simulate(TESTDATA / "scenarios" / "driven.toml", points=3600)
    res = calib.tdr(sim.t, sim["enc"], name="enc", pole_pairs=7)
    driven = res.report["details"]["driven"]
    assert [m["order"] for m in driven["motor_orders"]] == [42, 84, 126]
    assert not any(m["in_map"] for m in driven["motor_orders"])
    top = {h["order"]: h["amplitude_arcsec"] for h in res.channels["enc"].report["harmonics"]}
    assert abs(top[1] - 600.0) < 1.0 and abs(top[2] - 250.0) < 1.0
    # A coast is what run="coast" asks for; this run holds none.
    with pytest.raises(calib.DataError, match="release the drive"):
        calib.tdr(sim.t, sim["enc"], run="coast")
    with pytest.raises(calib.UsageError, match="one way"):
        calib.tdr(sim.t, sim["enc"], pole_pairs=7, cogging_orders=[42])


def test_multihead_twelve_heads_meet_the_bar():
    # calib-core's tests/it/multihead.rs (selfa_twelve_heads_joint_meets_the_bar): 0.05″ (measured
    # there: 0.0075″).
    text = (TESTDATA / "scenarios" / "multihead.toml").read_text()
    sim = calib.simulate(text)
    # Each head's nominal angle is its scenario's `head_deg`.
    positions = {}
    name = None
    for line in text.splitlines():
        line = line.split("#")[0].strip()
        if line.startswith("name"):
            name = line.split("=")[1].strip().strip('"')
        if line.startswith("head_deg"):
            positions[name] = float(line.split("=")[1])
    assert list(positions) == list(sim.channels)
    res = calib.multihead({n: sim[n] for n in positions}, positions)
    first = list(positions)[0]
    err = max_abs_diff(res.channels[first].table, sim.truth[first])
    assert err < 0.05, f"max |map − truth| {err:.4f}″"


def test_shift_angle_recovers_the_visible_truth_of_the_fixture():
    # calib-core's tests/it/shift_angle.rs: the committed fixture is the paper's design with
    # σ = 0.03″; the largest of 360 errors of ≤ 1.1σ each stays below 5σ = 0.15″.
    folder = TESTDATA / "shift-angle"
    res = calib.shift_angle(folder / "readings.csv")
    (ch,) = res.channels.values()
    truth = np.loadtxt(folder / "truth_encoder.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(ch.angle_deg, truth[:, 0])
    d = ch.error_arcsec - truth[:, 2]
    assert np.max(np.abs(d - d.mean())) < 0.15
    assert res.polygon is not None and len(res.polygon["face"]) == 24


def test_csrr_finds_and_removes_a_lag_between_the_channels():
    # B read 5 ms late (the CLI's and calib-core's csrr_latency tests use the same scenario).
    sim = calib.simulate(TESTDATA / "scenarios" / "csrr-latency.toml")
    res = calib.csrr(sim["a"], sim["b"], t=sim.t)
    lag = res.report["details"]["latency_s"]
    assert abs(lag - 0.005) < 0.005 * 0.01, lag
    assert res.report["details"]["latency"]["mode"] == "auto"
    # Left in, the lag breaks the solve, and the error names it.
    with pytest.raises(calib.DataError, match="older than A's"):
        calib.csrr(sim["a"], sim["b"], t=sim.t, latency=0)
    with pytest.raises(calib.UsageError, match="latency"):
        calib.csrr(sim["a"], sim["b"], t=sim.t, latency="soon")


def test_reference_takes_a_commanded_reference_and_its_pole_pairs():
    # A motor of 21 pole pairs driven open loop: its ripple at orders 126 and 252 (700″, 150″)
    # is the motor's, not the encoder's (cli/tests/it/reference_setups_cli.rs, same scenario).
    sim = calib.simulate(TESTDATA / "scenarios" / "commanded.toml", points=3600)
    res = calib.reference(
        sim["encoder"], sim["commanded"], t=sim.t, names=("encoder", "commanded"),
        ref_u=0.0, ref_kind="commanded", pole_pairs=21,
    )
    ripple = res.report["details"]["ripple"]
    assert ripple["pole_pairs"] == 21
    by_order = {t["order"]: t["amplitude_arcsec"] for t in ripple["terms"]}
    assert abs(by_order[126] - 700.0) < 35.0, by_order
    orders = [h["order"] for h in res.channels["encoder"].harmonics]
    assert 126 not in orders[:3], orders
    with pytest.raises(calib.UsageError, match="pole_pairs"):
        calib.reference(sim["encoder"], sim["commanded"], t=sim.t, ref_kind="commanded")


def test_reference_through_a_gear_estimates_the_ratio_and_both_maps():
    # An 11.35:1 actuator over two whole output turns each way (cli/tests/it/gear_cli.rs, same
    # scenario: ratio within 2e-5, the motor's map within 17″ of its truth at 1200″/500″/120″).
    sim = calib.simulate(TESTDATA / "scenarios" / "actuator-turns.toml", points=3600)
    res = calib.reference(
        sim["out"], sim["motor"], t=sim.t, names=("out", "motor"), ref_ratio="auto"
    )
    details = res.report["details"]
    assert abs(details["ratio"] - 11.35) < 2e-5, details["ratio"]
    assert details["ratio_u"] > 0
    motor = res.channels["motor"]
    assert not motor.is_range
    err = max_abs_diff(motor.table, sim.truth["motor"])
    assert err < 17.0, f"max |motor map − truth| {err:.3f}″"
    with pytest.raises(calib.UsageError, match="ref_ratio"):
        calib.reference(sim["out"], sim["motor"], t=sim.t, ref_ratio=0)
