"""Paths shared by the tests: the repository's testdata and the `calib` command line."""

import os
import pathlib
import shutil

import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
TESTDATA = REPO / "testdata"


def calib_binary():
    """The `calib` command line to compare with: $CALIB_BIN, else a built one in target/, else
    one on PATH; None if there is none."""
    given = os.environ.get("CALIB_BIN")
    if given:
        return given
    for profile in ("release", "debug"):
        built = REPO / "target" / profile / "calib"
        if built.exists():
            return str(built)
    return shutil.which("calib")


@pytest.fixture
def testdata():
    return TESTDATA


def required_calib_binary():
    """`calib_binary()` for a test that compares with the command line: under CI (which sets
    CALIB_BIN) its absence fails the test, elsewhere it skips it."""
    binary = calib_binary()
    if binary is None:
        if os.environ.get("CI"):
            pytest.fail("CI must set CALIB_BIN (or build target/*/calib) for this test")
        pytest.skip("no calib command line built to compare with (set CALIB_BIN)")
    return binary
