"""Wall time of `calib.map_logs` over many small simulated logs: a Dask LocalCluster of worker
processes against a loop in one process, and the peak memory of each worker.

    CALIB_BIN=target/release/calib python benches/fleet.py [LOGS] [WORKERS]

LOGS (default 200) copies of testdata/scenarios/quick.toml, each with its own seed, simulated
as MCAP into a temporary folder (about 3300 samples, 127 kB each), calibrated by `csrr` with
their tables and report.json written under an output folder, three ways:

- loop: one log after the other in this process (`ThreadPoolExecutor(1)`: the same code path as
  the others, run inline);
- threads: `ThreadPoolExecutor(WORKERS)` in this process (calib releases the GIL);
- dask: `LocalCluster(n_workers=WORKERS, threads_per_worker=1, processes=True)`, its start
  timed apart.

Prints each wall time, the peak resident memory of each Dask worker process before and after
the run (ru_maxrss), the bytes of the logs, and the machine's load (os.getloadavg) before and
after. Needs pandas and dask[distributed].
"""

import concurrent.futures
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time

import calib

REPO = pathlib.Path(__file__).resolve().parents[1]


def peak_rss_mib():
    """This process's peak resident set, MiB (Linux reports ru_maxrss in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def simulate(binary, folder, count):
    quick = (REPO / "testdata" / "scenarios" / "quick.toml").read_text()
    logs = []
    for k in range(count):
        robot = folder / f"r{k:04d}"
        robot.mkdir(parents=True)
        scenario = robot / "run.toml"
        scenario.write_text(quick.replace("seed = 1", f"seed = {k + 1}", 1))
        log = robot / "run.mcap"
        subprocess.run([binary, "simulate", str(scenario), "-o", str(log)], check=True, capture_output=True)
        logs.append(log)
    return logs


def timed(label, run):
    start = time.perf_counter()
    table = run()
    wall = time.perf_counter() - start
    counts = table["status"].value_counts().to_dict()
    print(f"{label:<28} {wall:8.2f} s  {counts}", flush=True)
    return wall


def main():
    import distributed

    count = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    workers = int(sys.argv[2]) if len(sys.argv) > 2 else 2
    binary = os.environ.get("CALIB_BIN") or str(REPO / "target" / "release" / "calib")
    print(f"load before: {os.getloadavg()}  cores: {os.cpu_count()}", flush=True)
    with tempfile.TemporaryDirectory(prefix="calib-fleet-bench-") as tmp:
        tmp = pathlib.Path(tmp)
        start = time.perf_counter()
        logs = simulate(binary, tmp / "fleet", count)
        size = sum(p.stat().st_size for p in logs)
        print(f"simulated {count} logs, {size / 1e6:.1f} MB ({size / count / 1e3:.0f} kB each) "
              f"in {time.perf_counter() - start:.1f} s", flush=True)
        loop = timed(
            "loop (one process)",
            lambda: calib.map_logs("csrr", logs, out=tmp / "out-loop", executor=concurrent.futures.ThreadPoolExecutor(1)),
        )
        print(f"  peak RSS of this process: {peak_rss_mib():.0f} MiB", flush=True)
        timed(
            f"threads ({workers}, one process)",
            lambda: calib.map_logs("csrr", logs, out=tmp / "out-threads", executor=concurrent.futures.ThreadPoolExecutor(workers)),
        )
        start = time.perf_counter()
        with distributed.LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster, distributed.Client(cluster) as client:
            print(f"LocalCluster start           {time.perf_counter() - start:8.2f} s", flush=True)
            before = client.run(peak_rss_mib)
            dask = timed(
                f"dask LocalCluster ({workers} procs)",
                lambda: calib.map_logs("csrr", logs, out=tmp / "out-dask", executor=client.get_executor()),
            )
            after = client.run(peak_rss_mib)
        for worker in sorted(after):
            print(f"  worker {worker}: peak RSS {before[worker]:.0f} MiB before the run, {after[worker]:.0f} MiB after", flush=True)
        print(f"speed-up of dask over the loop: {loop / dask:.2f}", flush=True)
    print(f"load after: {os.getloadavg()}", flush=True)


if __name__ == "__main__":
    main()
