"""Logs read by URL from an S3 endpoint on localhost (moto's server, started here) and from file
objects: the same results as the local file, to the last digit."""

import os
import shutil
import socket
import subprocess
import time

import numpy as np
import pytest

import calib
from conftest import TESTDATA

QUICK = TESTDATA / "examples" / "quick.mcap"
# Set to 1 to skip these tests where moto_server is not installed (locally only: CI installs it,
# and there a missing server fails them).
SKIP = "CALIB_SKIP_S3_TESTS"


@pytest.fixture(scope="module")
def moto():
    """A moto S3 server on a free port of 127.0.0.1 with a bucket `fleet` holding quick.mcap as
    `r1/run.mcap`; its storage_options."""
    server = shutil.which("moto_server")
    if server is None:
        if os.environ.get(SKIP) == "1":
            pytest.skip(f"moto_server is not on PATH and {SKIP}=1")
        pytest.fail(
            "moto_server is not on PATH: `pip install 'moto[server]'` (as .ci/run does), or set "
            f"{SKIP}=1 to skip these tests locally"
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
        endpoint = f"http://127.0.0.1:{port}"
        options = {
            "aws_endpoint": endpoint,
            "aws_access_key_id": "testing",
            "aws_secret_access_key": "testing",
            "aws_region": "us-east-1",
            "aws_allow_http": True,
        }
        import boto3  # moto's own dependency

        s3 = boto3.client(
            "s3",
            endpoint_url=endpoint,
            aws_access_key_id="testing",
            aws_secret_access_key="testing",
            region_name="us-east-1",
        )
        s3.create_bucket(Bucket="fleet")
        s3.upload_file(str(QUICK), "fleet", "r1/run.mcap")
        yield options
    finally:
        proc.kill()
        proc.wait()


def test_csrr_log_on_an_s3_url_equals_the_local_files(moto):
    local = calib.csrr_log(QUICK)
    remote = calib.csrr_log("s3://fleet/r1/run.mcap", storage_options=moto)
    for name in ("a", "b"):
        np.testing.assert_array_equal(remote.channels[name].error_arcsec, local.channels[name].error_arcsec)
    assert remote.report["inputs"] == ["s3://fleet/r1/run.mcap"]
    log = calib.read("s3://fleet/r1/run.mcap", storage_options=moto)
    assert any("fetched" in n for n in log.notes), log.notes


def test_an_s3_error_names_the_url_and_what_to_do(moto):
    with pytest.raises(calib.DataError, match=r"s3://fleet/missing\.mcap.*no object"):
        calib.csrr_log("s3://fleet/missing.mcap", storage_options=moto)
    with pytest.raises(calib.DataError, match="not an option"):
        calib.csrr_log("s3://fleet/r1/run.mcap", storage_options={**moto, "aws_colour": "blue"})


def test_a_file_object_is_read_as_its_file(tmp_path):
    local = calib.csrr_log(QUICK)
    with open(QUICK, "rb") as f:
        from_object = calib.csrr_log(f)
    for name in ("a", "b"):
        np.testing.assert_array_equal(
            from_object.channels[name].error_arcsec, local.channels[name].error_arcsec
        )
    with open(QUICK, "r", encoding="latin-1") as f, pytest.raises(calib.UsageError, match="binary"):
        calib.csrr_log(f)
