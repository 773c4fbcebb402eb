"""Logs read by URL from an S3 endpoint on localhost (moto's server, started here) and from file
objects: the same results as the local file, to the last digit."""

import numpy as np
import pytest

import calib
from conftest import TESTDATA, moto_server, s3_client, s3_storage_options

QUICK = TESTDATA / "examples" / "quick.mcap"


@pytest.fixture(scope="module")
def moto():
    """A moto S3 server with a bucket `fleet` holding quick.mcap as `r1/run.mcap`; its
    storage_options."""
    with moto_server() as endpoint:
        s3 = s3_client(endpoint)
        s3.create_bucket(Bucket="fleet")
        s3.upload_file(str(QUICK), "fleet", "r1/run.mcap")
        yield s3_storage_options(endpoint)


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
