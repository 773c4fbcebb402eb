"""Paths shared by the tests: the repository's testdata, the `calib` command line, and an S3
endpoint on localhost."""

import contextlib
import os
import pathlib
import shutil
import socket
import subprocess
import time

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


# Set to 1 to skip the tests of logs on S3 where moto_server is not installed (locally only: CI
# installs it, and there a missing server fails them).
SKIP_S3 = "CALIB_SKIP_S3_TESTS"


@contextlib.contextmanager
def moto_server():
    """An S3 endpoint, moto's server, on a free port of 127.0.0.1, for the duration: yields its
    URL. Its credentials are anything (`testing`), its region `us-east-1`."""
    server = shutil.which("moto_server")
    if server is None:
        if os.environ.get(SKIP_S3) == "1":
            pytest.skip(f"moto_server is not on PATH and {SKIP_S3}=1")
        pytest.fail(
            "moto_server is not on PATH: `pip install 'moto[server]'` (as .ci/run does), or set "
            f"{SKIP_S3}=1 to skip these tests locally"
        )
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen(
        [server, "-H", "127.0.0.1", "-p", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline, "moto_server did not answer within 60 s"
                time.sleep(0.1)
        yield f"http://127.0.0.1:{port}"
    finally:
        proc.kill()
        proc.wait()


def s3_storage_options(endpoint):
    """calib's `storage_options` (object_store's keys) for the moto endpoint."""
    return {
        "aws_endpoint": endpoint,
        "aws_access_key_id": "testing",
        "aws_secret_access_key": "testing",
        "aws_region": "us-east-1",
        "aws_allow_http": True,
    }


def s3_client(endpoint):
    """boto3's S3 client of the moto endpoint (boto3: moto's own dependency)."""
    import boto3

    return boto3.client(
        "s3",
        endpoint_url=endpoint,
        aws_access_key_id="testing",
        aws_secret_access_key="testing",
        region_name="us-east-1",
    )
