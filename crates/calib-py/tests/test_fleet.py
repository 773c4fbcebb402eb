"""`calib.map_logs` over a fleet of simulated logs on Dask and on a process pool, from local
files and from an S3 endpoint on localhost (moto's server), outputs written back to it: the maps
are the command line's to the last digit, a file that is not a log is a failed row, options are
checked before any work is sent, and what crosses between processes pickles."""

import concurrent.futures
import contextlib
import io
import json
import multiprocessing
import os
import pickle
import sqlite3
import struct
import subprocess

import pytest

import calib
from calib import fleet
from conftest import TESTDATA, moto_server, required_calib_binary as cli, s3_client, s3_storage_options

pd = pytest.importorskip("pandas")


def simulate(binary, scenario_text, path):
    """`calib simulate` of a scenario's text into `path` (MCAP or CSV by its extension)."""
    scenario = path.parent / f"{path.stem}.toml"
    scenario.write_text(scenario_text)
    subprocess.run([binary, "simulate", str(scenario), "-o", str(path)], check=True, capture_output=True)
    scenario.unlink()


class Cdr:
    """Little-endian CDR with its encapsulation header, alignment counted after the header
    (as ROS 2 serializes a message)."""

    def __init__(self):
        self.body = bytearray()

    def align(self, n):
        self.body += b"\0" * (-len(self.body) % n)

    def u32(self, v):
        self.align(4)
        self.body += struct.pack("<I", v)

    def string(self, s):
        data = s.encode() + b"\0"
        self.u32(len(data))
        self.body += data

    def f64s(self, values):
        self.u32(len(values))
        if values:
            self.align(8)
        for v in values:
            self.body += struct.pack("<d", v)

    def bytes(self):
        return b"\x00\x01\x00\x00" + bytes(self.body)


def joint_state(stamp_ns, names, positions):
    """A `sensor_msgs/msg/JointState` in CDR, velocity and effort empty."""
    m = Cdr()
    m.u32(stamp_ns // 1_000_000_000)
    m.u32(stamp_ns % 1_000_000_000)
    m.string("")
    m.u32(len(names))
    for n in names:
        m.string(n)
    m.f64s(positions)
    m.f64s([])
    m.f64s([])
    return m.bytes()


def write_db3(log, path):
    """A rosbag2 (Humble, sqlite3) file of `log`'s channels as one JointState topic."""
    db = sqlite3.connect(path)
    db.executescript(
        """
        CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
        INSERT INTO schema VALUES (3, 'humble');
        CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL, metadata TEXT NOT NULL);
        CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
            serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
        CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
            timestamp INTEGER NOT NULL, data BLOB NOT NULL);
        INSERT INTO topics VALUES (1, '/joint_states', 'sensor_msgs/msg/JointState', 'cdr', '');
        """
    )
    names = list(log.channels)
    rows = []
    for k, t in enumerate(log.t):
        ns = int(round(t * 1e9))
        rows.append((1, ns, joint_state(ns, names, [float(log[n][k]) for n in names])))
    db.executemany("INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)", rows)
    db.commit()
    db.close()


QUICK = (TESTDATA / "scenarios" / "quick.toml").read_text()


def with_seed(text, seed):
    assert sum(line.startswith("seed =") for line in text.splitlines()) == 1, "quick.toml sets a seed"
    lines = [f"seed = {seed}" if line.startswith("seed =") else line for line in text.splitlines()]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A fleet under `fleet/`, each robot's log named alike: MCAP, CSV, a rosbag2 .db3 file,
    and a file that is not a log."""
    binary = cli()
    root = tmp_path_factory.mktemp("fleet")
    paths = {}
    for robot, seed, name in [("r1", 1, "run.mcap"), ("r2", 2, "run.mcap"), ("r3", 3, "run.csv")]:
        (root / robot).mkdir()
        paths[robot] = root / robot / name
        simulate(binary, with_seed(QUICK, seed), paths[robot])
    (root / "r4").mkdir()
    paths["r4"] = root / "r4" / "run.db3"
    write_db3(calib.read(paths["r1"]), paths["r4"])
    (root / "r5").mkdir()
    paths["r5"] = root / "r5" / "run.mcap"
    paths["r5"].write_bytes(b"this is not a log\n" * 10)
    return paths


def in_folder(out):
    """The bytes of a file under the local folder `out` (None if there is none)."""
    return lambda name: (out / name).read_bytes() if (out / name).is_file() else None


def check_against_cli(table, paths, given, written, tmp_path):
    """Every calibrated log's tables (read back through `written(name)`) are byte for byte
    those of `calib csrr LOG` on the local file, its figures the CLI report's, and the broken
    log is a failed row naming the log as given, with nothing written."""
    binary = cli()
    assert list(table["log"]) == [str(p) for p in given]
    assert list(table["output"]) == ["r1/run.mcap", "r2/run.mcap", "r3/run.csv", "r4/run.db3", "r5/run.mcap"]
    assert list(table["status"]) == ["ok"] * 4 + ["failed"]
    broken = table.iloc[4]
    assert str(given[4]) in broken["error"], broken["error"]
    assert written("r5/run.mcap/report.json") is None
    for k, (robot, path) in enumerate(list(paths.items())[:4]):
        mine = table["output"][k]
        theirs = tmp_path / f"cli-{robot}"
        subprocess.run([binary, "csrr", str(path), "-o", str(theirs)], check=True, capture_output=True)
        for channel in ("a", "b"):
            assert written(f"{mine}/{channel}.csv") == (theirs / f"{channel}.csv").read_bytes(), (robot, channel)
        report = json.loads((theirs / "report.json").read_text())
        for channel in ("a", "b"):
            cli_channel = report["channels"][channel]
            assert table[f"peak_to_peak_arcsec[{channel}]"][k] == cli_channel["peak_to_peak_arcsec"]
            assert table[f"rms_arcsec[{channel}]"][k] == cli_channel["rms_arcsec"]
        assert table["residual_rms_arcsec"][k] == report["details"]["residual_rms_arcsec"]
        assert table["orders_kept"][k] == len(report["details"]["orders_kept"])
        assert table["latency_s"][k] == report["details"]["latency_s"]
        assert json.loads(written(f"{mine}/report.json"))["channels"] == report["channels"]
    # The three simulated runs differ (seeds 1, 2, 3); the bag is r1's run.
    pp = table["peak_to_peak_arcsec[a]"]
    assert pp[0] == pp[3] and pp[0] != pp[1]


def test_a_dask_local_cluster_gives_the_command_lines_maps(logs, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        out = tmp_path / "out"
        table = calib.map_logs("csrr", list(logs.values()), out=out, executor=client.get_executor())
        pids = set(client.run(os.getpid).values())
    assert len(pids) == 2 and os.getpid() not in pids
    check_against_cli(table, logs, list(logs.values()), in_folder(out), tmp_path)


def test_a_process_pool_gives_the_command_lines_maps_and_the_summary(logs, tmp_path):
    out = tmp_path / "out"
    spawn = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(max_workers=2, mp_context=spawn) as pool:
        table = calib.map_logs("csrr", list(logs.values()), out=out, executor=pool, summary=True)
    check_against_cli(table, logs, list(logs.values()), in_folder(out), tmp_path)
    for read in (pd.read_parquet, pd.read_csv):
        name = "summary.parquet" if read is pd.read_parquet else "summary.csv"
        back = read(out / name)
        assert list(back.columns) == list(table.columns)
        assert list(back["status"]) == list(table["status"])
        assert back["peak_to_peak_arcsec[b]"].iloc[:4].tolist() == table["peak_to_peak_arcsec[b]"].iloc[:4].tolist()


def test_a_second_run_writes_the_same_bytes_and_leaves_no_temporary_file(logs, tmp_path):
    """What an engine's retry does: the same task again, over the outputs of the first."""
    out = tmp_path / "out"
    some = [logs["r1"], logs["r3"]]
    calib.map_logs("csrr", some, out=out, executor=concurrent.futures.ThreadPoolExecutor(2))
    first = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    calib.map_logs("csrr", some, out=out, executor=concurrent.futures.ThreadPoolExecutor(2))
    second = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert first == second
    names = sorted(p.relative_to(out).as_posix() for p in second)
    assert names == [f"{d}/{f}" for d in ("r1/run.mcap", "r3/run.csv") for f in ("a.csv", "b.csv", "report.json")]


def test_the_default_executor_is_a_spawned_process_pool(logs, tmp_path):
    table = calib.map_logs("csrr", [logs["r2"], logs["r5"]])
    assert list(table["status"]) == ["ok", "failed"]
    # One log: its folder is its file name.
    table = calib.map_logs("csrr", [logs["r2"]], out=tmp_path / "one")
    assert list(table["output"]) == ["run.mcap"]
    assert (tmp_path / "one" / "run.mcap" / "a.csv").exists()


def test_gates_make_gate_failed_rows_with_their_outputs(logs, tmp_path):
    out = tmp_path / "out"
    table = calib.map_logs(
        "csrr",
        [logs["r1"], logs["r2"]],
        out=out,
        executor=concurrent.futures.ThreadPoolExecutor(2),
        max_pp=45.0,
        max_residual=1.0,
    )
    # quick.toml's maps: a 51″ peak to peak, b 38″; the fit's residual ~0.08″.
    assert list(table["status"]) == ["gate failed", "gate failed"]
    assert all(g.startswith("`a`: peak-to-peak before correction") for g in table["gate_failures"])
    assert "`b`" not in "".join(table["gate_failures"])
    assert (out / "r1" / "run.mcap" / "report.json").exists()
    after = calib.map_logs("csrr", [logs["r1"]], max_pp=100.0, gate_on="after", executor=concurrent.futures.ThreadPoolExecutor(1))
    assert after["status"][0] == "gate failed"
    assert "no peak-to-peak after correction" in after["gate_failures"][0]


class Recording(concurrent.futures.ThreadPoolExecutor):
    """An executor that records what it was sent."""

    def __init__(self):
        super().__init__(1)
        self.sent = 0

    def submit(self, fn, /, *args, **kwargs):
        self.sent += 1
        return super().submit(fn, *args, **kwargs)


@pytest.mark.parametrize(
    "method, options, named",
    [
        ("csrr", {"bogus": 1}, "unknown option bogus"),
        ("csrr", {"points": 1}, "points=1 is outside its range"),
        ("csrr", {"points": "many"}, "'points'"),
        ("csrr", {"method": "best"}, "method=`best`"),
        ("csrr", {"latency": "soon"}, "latency=\"soon\""),
        ("csrr", {"a": "x", "b": "x"}, "a and b both name `x`"),
        ("csrr", {"time_unit": "days"}, "time_unit"),
        ("tdr", {}, "give the option channel"),
        ("tdr", {"channel": "enc", "run": "walk"}, "run=\"walk\""),
        ("reference", {"dut": "d", "ref": "r", "ref_kind": "commanded"}, "pole_pairs"),
        ("multihead", {"positions": {"h1": 0.0}}, "at least 2"),
        ("csrr", {"max_pp": -1}, "max_pp=-1"),
        ("spin", {}, "method='spin'"),
    ],
)
def test_options_are_checked_before_any_log_is_sent(logs, method, options, named):
    executor = Recording()
    with pytest.raises(calib.UsageError) as e:
        calib.map_logs(method, [logs["r1"]], executor=executor, **options)
    assert named in str(e.value), str(e.value)
    assert executor.sent == 0


def test_a_log_given_twice_is_refused(logs):
    with pytest.raises(calib.UsageError, match="given twice"):
        calib.map_logs("csrr", [logs["r1"], str(logs["r1"])], executor=Recording())


def test_output_folders_are_relative_to_the_common_folder():
    assert fleet.relative_folders(["/f/r1/run.mcap", "/f/r2/run.mcap"]) == ["r1/run.mcap", "r2/run.mcap"]
    assert fleet.relative_folders(["/f/r1/run.mcap"]) == ["run.mcap"]
    assert fleet.relative_folders(
        ["s3://fleet/r1/2026-12-07/run.mcap", "s3://fleet/r2/2026-12-07/run.mcap?versionId=3"]
    ) == ["r1/2026-12-07/run.mcap", "r2/2026-12-07/run.mcap"]
    assert fleet.relative_folders(["s3://a/run.mcap", "gs://a/run.mcap"]) == ["s3/a/run.mcap", "gs/a/run.mcap"]


def test_rows_results_tasks_and_errors_pickle(logs):
    table = calib.map_logs("csrr", [logs["r1"], logs["r5"]], executor=concurrent.futures.ThreadPoolExecutor(2))
    assert pickle.loads(pickle.dumps(table)).equals(table)
    result = calib.csrr_log(logs["r1"])
    back = pickle.loads(pickle.dumps(result))
    assert back.report == result.report
    assert (back.channels["a"].error_arcsec == result.channels["a"].error_arcsec).all()
    task = fleet.Task("csrr", str(logs["r1"]), "r1", "r1/run.mcap", None, None, None, {"a": "a"}, fleet.Gates(max_pp=1.0))
    assert pickle.loads(pickle.dumps(task)) == task
    with pytest.raises(calib.CalibError) as raised:
        calib.csrr_log(logs["r5"])
    made = [raised.value] + [e("x.mcap: message 3: what to do") for e in (calib.DataError, calib.UsageError, calib.ArrayError)]
    for error in made:
        again = pickle.loads(pickle.dumps(error))
        assert type(again) is type(error) and str(again) == str(error)


def test_two_nights_of_map_logs_say_which_joint_moved(logs, tmp_path):
    """`calib compare NEW --against OLD` on two map_logs runs: the second night's robot 2 has
    B's order-6 error 0.5″ larger (the noise the same, the seeds equal), and only that joint
    moves."""
    binary = cli()
    night2 = {}
    for robot, seed, b6 in [("r1", 1, "15.0"), ("r2", 2, "15.5")]:
        (tmp_path / "night2" / robot).mkdir(parents=True)
        night2[robot] = tmp_path / "night2" / robot / "run.mcap"
        text = with_seed(QUICK, seed).replace("order = 6, amplitude_arcsec = 15.0", f"order = 6, amplitude_arcsec = {b6}")
        simulate(binary, text, night2[robot])
    pool = concurrent.futures.ThreadPoolExecutor(2)
    old, new = tmp_path / "old", tmp_path / "new"
    calib.map_logs("csrr", [logs["r1"], logs["r2"]], out=old, executor=pool)
    calib.map_logs("csrr", list(night2.values()), out=new, executor=pool)
    done = subprocess.run(
        [binary, "compare", str(new), "--against", str(old), "-o", str(tmp_path / "drift")],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 3, done.stderr
    drift = pd.read_csv(tmp_path / "drift" / "drift.csv")
    assert list(zip(drift["log"], drift["channel"], drift["status"])) == [
        ("r1/run.mcap", "a", "steady"),
        ("r1/run.mcap", "b", "steady"),
        ("r2/run.mcap", "a", "steady"),
        ("r2/run.mcap", "b", "moved"),
    ]
    assert 0.45 < drift["max_abs_difference_arcsec"][3] < 0.55


def test_ray_tasks_through_the_executor_of_docs_fleet_md(logs, tmp_path):
    """Ray through the adapter docs/fleet.md gives (Ray has no concurrent.futures.Executor of
    its own). CI does not install Ray (a 15 s install, 7 s to start): this runs where it is."""
    ray = pytest.importorskip("ray")

    class RayExecutor(concurrent.futures.Executor):
        def __init__(self, **options):
            self.options = options

        def submit(self, fn, /, *args, **kwargs):
            task = ray.remote(**self.options)(fn) if self.options else ray.remote(fn)
            return task.remote(*args, **kwargs).future()

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        out = tmp_path / "out"
        table = calib.map_logs("csrr", list(logs.values()), out=out, executor=RayExecutor(max_retries=2))
    finally:
        ray.shutdown()
    check_against_cli(table, logs, list(logs.values()), in_folder(out), tmp_path)


def test_tdr_through_map_logs_is_the_command_lines(tmp_path):
    """Another method, its own options and figures: a spin-down (testdata/scenarios/spindown.toml)
    through `tdr` with `channel`, against `calib tdr LOG --channel enc`."""
    binary = cli()
    log = tmp_path / "coast" / "run.mcap"
    log.parent.mkdir()
    simulate(binary, (TESTDATA / "scenarios" / "spindown.toml").read_text(), log)
    out = tmp_path / "out"
    table = calib.map_logs("tdr", [log], out=out, executor=concurrent.futures.ThreadPoolExecutor(1), channel="enc", ref="ref")
    assert list(table["status"]) == ["ok"], table["error"][0]
    theirs = tmp_path / "cli"
    subprocess.run([binary, "tdr", str(log), "--channel", "enc", "--ref", "ref", "-o", str(theirs)], check=True, capture_output=True)
    assert (out / "run.mcap" / "enc.csv").read_bytes() == (theirs / "enc.csv").read_bytes()
    report = json.loads((theirs / "report.json").read_text())
    assert table["orders_kept"][0] == len(report["details"]["orders"]["kept"])
    assert table["residual_rms_arcsec"][0] == report["details"]["residual_rms_arcsec"]
    assert table["after_peak_to_peak_arcsec[enc]"][0] == report["channels"]["enc"]["after_correction"]["peak_to_peak_arcsec"]


@pytest.fixture(scope="module")
def bucket(logs):
    """The fleet on a moto S3 server: bucket `fleet` holding each log at `<robot>/<name>`, an
    empty bucket `calib` for the outputs. Yields the endpoint and the logs' URLs."""
    with moto_server() as endpoint:
        s3 = s3_client(endpoint)
        s3.create_bucket(Bucket="fleet")
        s3.create_bucket(Bucket="calib")
        urls = []
        for robot, path in logs.items():
            s3.upload_file(str(path), "fleet", f"{robot}/{path.name}")
            urls.append(f"s3://fleet/{robot}/{path.name}")
        yield endpoint, urls


def fsspec_options(endpoint):
    """s3fs's storage_options for the moto endpoint (map_logs's `out_options`)."""
    return {"key": "testing", "secret": "testing", "client_kwargs": {"endpoint_url": endpoint, "region_name": "us-east-1"}}


def in_bucket(endpoint, prefix):
    """The bytes of a file under `s3://prefix/` (None if there is none), read with s3fs."""
    s3fs = pytest.importorskip("s3fs")
    fs = s3fs.S3FileSystem(skip_instance_cache=True, **fsspec_options(endpoint))

    def read(name):
        path = f"{prefix}/{name}"
        return fs.cat_file(path) if fs.exists(path) else None

    return read


def dask_executor(stack):
    distributed = pytest.importorskip("distributed")
    cluster = stack.enter_context(
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    )
    return stack.enter_context(distributed.Client(cluster)).get_executor()


def process_pool(stack):
    spawn = multiprocessing.get_context("spawn")
    return stack.enter_context(concurrent.futures.ProcessPoolExecutor(max_workers=2, mp_context=spawn))


@pytest.mark.parametrize("make_executor", [dask_executor, process_pool])
def test_a_fleet_on_s3_is_calibrated_and_written_back(logs, bucket, tmp_path, make_executor):
    """The fleet read by URL from the S3 endpoint, the outputs written back to it: the maps
    are the CLI's on the local files, byte for byte; the file that is not a log a failed row
    naming its URL; the summary beside the outputs."""
    endpoint, urls = bucket
    prefix = f"calib/{make_executor.__name__}"
    with contextlib.ExitStack() as stack:
        table = calib.map_logs(
            "csrr",
            urls,
            out=f"s3://{prefix}",
            executor=make_executor(stack),
            storage_options=s3_storage_options(endpoint),
            out_options=fsspec_options(endpoint),
            summary=True,
        )
    written = in_bucket(endpoint, prefix)
    check_against_cli(table, logs, urls, written, tmp_path)
    summary = pd.read_parquet(io.BytesIO(written("summary.parquet")))
    assert list(summary["status"]) == list(table["status"])
    assert written("summary.csv").startswith(b"log,output,status,error,")
