"""Arrays and tables handed in are checked as the CLI's readers check a log's rows (issue 52):
NaN, infinities and empty arrays are named with their argument and first bad index, as an
ArrayError (a UsageError and a ValueError), rather than calibrated silently or called a sensor
that never moves; a Table is checked when it is made."""

import numpy as np
import pytest

import calib
from conftest import TESTDATA


@pytest.fixture(scope="module")
def quick():
    return calib.simulate(TESTDATA / "scenarios" / "quick.toml")


def test_array_error_is_a_usage_error_and_a_value_error():
    assert issubclass(calib.ArrayError, calib.UsageError)
    assert issubclass(calib.ArrayError, ValueError)
    assert issubclass(calib.ArrayError, calib.CalibError)


def test_one_nan_in_a_channel_is_named_with_its_index(quick):
    # Before: one NaN gave the same map as without it, two segments dropped, no word.
    a = quick["a"].copy()
    a[1234] = np.nan
    with pytest.raises(ValueError, match=r"`a\[1234\]` is NaN"):
        calib.csrr(a, quick["b"], t=quick.t)
    b = quick["b"].copy()
    b[7] = np.inf
    with pytest.raises(calib.ArrayError, match=r"`b\[7\]` is inf"):
        calib.csrr(quick["a"], b, t=quick.t)
    with pytest.raises(ValueError, match=r"`ref\[0\]` is NaN"):
        calib.reference(quick["a"], np.full(len(quick["a"]), np.nan), t=quick.t)


def test_nan_in_t_is_named(quick):
    t = quick.t.copy()
    t[99] = np.nan
    with pytest.raises(ValueError, match=r"`t\[99\]` is NaN"):
        calib.csrr(quick["a"], quick["b"], t=t)
    with pytest.raises(ValueError, match=r"`t\[99\]` is NaN"):
        calib.tdr(t, quick["a"])


def test_empty_and_all_nan_arrays_are_not_a_sensor_that_never_moves():
    # Before: both were "sensor A never moves".
    empty = np.array([])
    with pytest.raises(ValueError, match="`a` is empty") as err:
        calib.csrr(empty, empty)
    assert "never moves" not in str(err.value)
    nan = np.full(5000, np.nan)
    with pytest.raises(ValueError, match=r"`a\[0\]` is NaN") as err:
        calib.csrr(nan, nan)
    assert "never moves" not in str(err.value)
    with pytest.raises(ValueError, match="`dut` is empty"):
        calib.reference(empty, empty)


def test_a_table_is_checked_when_it_is_made():
    # Before: accepted, then ZeroDivisionError when used.
    with pytest.raises(ValueError, match="0 points; a correction table needs at least 2"):
        calib.Table(np.array([]))
    with pytest.raises(ValueError, match="1 point;"):
        calib.Table(np.array([1.0]))
    with pytest.raises(ValueError, match=r"`error_arcsec\[2\]` is NaN"):
        calib.Table(np.array([1.0, 2.0, np.nan, 3.0]))
    with pytest.raises(ValueError, match=r"`u_arcsec\[1\]` is -0.5, not a finite, non-negative"):
        calib.Table(np.zeros(4), np.array([0.1, -0.5, 0.1, 0.1]))
    with pytest.raises(ValueError, match="3 uncertainties for a table of 4 points"):
        calib.Table(np.zeros(4), np.array([0.1, 0.1, 0.1]))
    with pytest.raises(calib.UsageError, match="range_deg"):
        calib.Table(np.zeros(4), range_deg=(0.0, 400.0))
    # A good table is untouched.
    good = calib.Table(np.array([1.0, -1.0, 0.5, -0.5]), np.full(4, 0.1))
    assert len(good) == 4 and good.peak_to_peak_arcsec == 2.0
