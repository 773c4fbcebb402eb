"""calib over a fleet of logs on any ``concurrent.futures`` executor: :func:`map_logs`.

calib brings no scheduler of its own. :func:`map_logs` hands one task per log to the executor
it is given — a local process pool by default, Dask's ``client.get_executor()``, Ray's executor
— and gathers one row per log into a ``pandas.DataFrame``. What crosses between processes is
small and plain: the task (method, log, options, output folder) and the row (a dict of strings
and numbers); both pickle.

Each log's files go to ``out/<the log's path relative to the logs' common folder>/`` (``fleet/
r1/run.mcap`` and ``fleet/r2/run.mcap`` give ``out/r1/run.mcap/`` and ``out/r2/run.mcap/``):
its correction tables (``<channel>.csv``, as ``calib <method>`` writes them) and
``report.json``, written last, so that a folder with a ``report.json`` holds every table it
names. A local file is written to a temporary name beside it and renamed; an object store gets
one ``put`` per file. Either way a file is whole or absent, and a task the engine runs twice
(a retry, a lost worker) writes the same bytes again.
"""

from __future__ import annotations

import concurrent.futures
import inspect
import io
import json
import multiprocessing
import os
import socket
import tempfile
import time
import uuid
from dataclasses import dataclass
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

from . import _calib
from ._calib import CalibError, UsageError

__all__ = ["map_logs", "METHODS", "STATUSES"]

#: The methods that read logs, by the name :func:`map_logs` takes (``calib.<method>_log``).
METHODS = ("csrr", "reference", "tdr", "multihead")

#: The values of the ``status`` column: calibrated and within the gates; calibrated, and a gate
#: failed (the CLI's exit status 3); not calibrated (exit status 1 or 2), ``error`` says why.
STATUSES = ("ok", "gate failed", "failed")

#: The columns of every row, before the per-channel ones.
LOG_COLUMNS = (
    "log",
    "output",
    "status",
    "error",
    "gate_failures",
    "warnings",
    "residual_rms_arcsec",
    "orders_kept",
    "latency_s",
    "ratio",
    "elapsed_s",
)

#: Each calibrated channel's figures, a column ``<figure>[<channel>]`` each: peak-to-peak and
#: RMS of the map (the error before correction), the peak-to-peak after correction where the
#: method measures it, the largest standard uncertainty of the table.
CHANNEL_FIGURES = (
    "peak_to_peak_arcsec",
    "rms_arcsec",
    "after_peak_to_peak_arcsec",
    "u_max_arcsec",
)

LogPath = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True)
class Gates:
    """The CLI's gates (``--max-pp``, ``--gate-on``, ``--max-residual``,
    ``--fail-on-warning``), judged on each log as ``calib <method> LOG...`` judges them."""

    max_pp: Optional[float] = None
    gate_on: str = "before"
    max_residual: Optional[float] = None
    fail_on_warning: bool = False

    def check(self) -> None:
        """Refuses a gate the CLI would refuse, naming it."""
        for name in ("max_pp", "max_residual"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and 0 < value < float("inf")):
                raise UsageError(f"{name}={value!r}: give a positive number of arcseconds")
        if self.gate_on not in ("before", "after"):
            raise UsageError(f"gate_on={self.gate_on!r}: give \"before\" or \"after\" (correction)")
        if self.gate_on == "after" and self.max_pp is None:
            raise UsageError("gate_on is what max_pp judges: give max_pp with it")

    def failures(self, report: dict) -> List[str]:
        """The gates the report fails, one line each, in the CLI's words (its flags named by
        their keyword here)."""
        failed = []
        if self.max_pp is not None:
            after = self.gate_on == "after"
            what = "after correction" if after else "before correction"
            for name, ch in report["channels"].items():
                value = _after(ch) if after else ch["peak_to_peak_arcsec"]
                if value is None:
                    failed.append(
                        f"`{name}`: this method and its options give no peak-to-peak after "
                        "correction (gate_on=\"after\")"
                    )
                elif _exceeds(value, self.max_pp):
                    failed.append(f"`{name}`: peak-to-peak {what} {value:.3f}″ > {self.max_pp}″ (max_pp)")
        if self.max_residual is not None:
            value = report.get("details", {}).get("residual_rms_arcsec")
            if value is None:
                failed.append("this method and its options fit no residuals (max_residual)")
            elif _exceeds(value, self.max_residual):
                failed.append(f"fit residual RMS {value:.4f}″ > {self.max_residual}″ (max_residual)")
        if self.fail_on_warning:
            failed.extend(f"warning (fail_on_warning): {w}" for w in report["warnings"])
        return failed


def _exceeds(value: float, limit: float) -> bool:
    """Whether ``value`` fails a gate of ``limit``: above it, or not a number (as the CLI)."""
    return not value <= limit


def _after(channel: dict) -> Optional[float]:
    after = channel.get("after_correction")
    return None if after is None else after["peak_to_peak_arcsec"]


@dataclass(frozen=True)
class Task:
    """One log's work, as sent to a worker (it pickles: plain strings, numbers and dicts)."""

    method: str
    log: str
    shown: str
    folder: str
    out: Optional[str]
    storage_options: Optional[Dict[str, Any]]
    out_options: Optional[Dict[str, Any]]
    options: Dict[str, Any]
    gates: Gates


def map_logs(
    method: str,
    logs: Sequence[LogPath],
    /,
    *,
    out: Optional[LogPath] = None,
    executor: Optional[concurrent.futures.Executor] = None,
    storage_options: Optional[Mapping[str, Any]] = None,
    out_options: Optional[Mapping[str, Any]] = None,
    summary: bool = False,
    max_pp: Optional[float] = None,
    gate_on: str = "before",
    max_residual: Optional[float] = None,
    fail_on_warning: bool = False,
    **options: Any,
):
    """Calibrates every log of ``logs`` with ``calib.<method>_log`` on ``executor``: one row
    per log, whatever happens to the others.

    Args:
        method: ``"csrr"``, ``"reference"``, ``"tdr"`` or ``"multihead"``. It and ``logs``
            are positional, so that a method's own ``method`` option passes as a keyword
            (``map_logs("csrr", logs, method="paper")``).
        logs: the logs, each a path or a URL (``s3://``, ``gs://``, ``az://``, ``http(s)://``,
            where calib's readers take URLs), as ``calib.<method>_log`` takes them.
        out: where each log's tables and ``report.json`` go, under the log's path relative to
            the logs' common folder: a folder, or a URL prefix written through fsspec (with
            ``out_options``). None: nothing is written, the rows are all there is.
        executor: any ``concurrent.futures.Executor`` (Dask's ``client.get_executor()``, Ray's,
            a ``ProcessPoolExecutor``); None: a local process pool of one worker per core
            (spawned processes, which import calib afresh), shut down at the end.
        storage_options: credentials and settings of the object store the logs are on, passed
            to ``calib.<method>_log`` as they are (its keys, object_store's: ``aws_endpoint``
            …). None: from the environment, as the clouds' own tools take them.
        out_options: fsspec's ``storage_options`` for an ``out`` URL (s3fs's keys: ``key``,
            ``secret``, ``client_kwargs`` …). None: fsspec's defaults, credentials from the
            environment.
        summary: also write the table as ``out/summary.parquet`` and ``out/summary.csv``.
        max_pp, gate_on, max_residual, fail_on_warning: the CLI's gates (``--max-pp``,
            ``--gate-on``, ``--max-residual``, ``--fail-on-warning``): a log that fails one is a
            ``gate failed`` row, its outputs written all the same.
        **options: the method's options, as ``calib.<method>_log`` takes them (``a``, ``b``,
            ``channel``, ``max_order`` …). They are checked once, here, before any log is sent:
            an unknown option or a bad value raises :class:`UsageError` naming it.

    Returns:
        A ``pandas.DataFrame``, one row per log in the order given: ``log``, ``output`` (its
        folder under ``out``), ``status`` (:data:`STATUSES`), ``error`` (why it was not
        calibrated), ``gate_failures`` and ``warnings`` (joined by newlines), the fit's
        ``residual_rms_arcsec``, the number of harmonic ``orders_kept``, the ``latency_s``
        removed, the gear ``ratio`` (each where the method gives it), ``elapsed_s`` on its
        worker, and per channel ``peak_to_peak_arcsec[<channel>]``, ``rms_arcsec[…]``,
        ``after_peak_to_peak_arcsec[…]`` and ``u_max_arcsec[…]``.

    Raises:
        UsageError: an unknown method or option, a bad value, a log given twice, ``summary``
            without ``out``. Nothing is sent to the executor then.
    """
    if method not in METHODS:
        raise UsageError(f"method={method!r}: give one of {', '.join(METHODS)} (the methods that read logs)")
    if isinstance(logs, (str, bytes, os.PathLike)):
        raise UsageError("logs is one path: give a list of logs (e.g. [path])")
    gates = Gates(max_pp, gate_on, max_residual, fail_on_warning)
    gates.check()
    if summary and out is None:
        raise UsageError("summary=True writes the table beside the outputs: give out as well")
    check_options(method, options, remote=storage_options is not None)
    given = [os.fspath(log) for log in logs]
    located = [log if _is_url(log) else os.path.abspath(log) for log in given]
    folders = relative_folders(located)
    seen: Dict[str, str] = {}
    for log, folder in zip(given, folders):
        if folder in seen:
            raise UsageError(f"{log}: given twice (as {seen[folder]} before); give each log once")
        seen[folder] = log
    target = None if out is None else os.fspath(out)
    if target is not None and not _is_url(target):
        target = os.path.abspath(target)
    so = None if storage_options is None else dict(storage_options)
    oo = None if out_options is None else dict(out_options)
    tasks = [
        Task(method, log, shown, folder, target, so, oo, dict(options), gates)
        for log, shown, folder in zip(located, given, folders)
    ]
    own = executor is None
    if own:
        executor = concurrent.futures.ProcessPoolExecutor(mp_context=multiprocessing.get_context("spawn"))
    try:
        futures = [executor.submit(run_task, task) for task in tasks]
        rows = [_gathered(future, task) for future, task in zip(futures, tasks)]
    finally:
        if own:
            executor.shutdown()
    table = frame(rows)
    if summary:
        write_summary(table, target, oo)
    return table


def check_options(method: str, options: Mapping[str, Any], remote: bool = False) -> None:
    """Checks ``options`` of ``calib.<method>_log`` without a log: unknown or missing keywords
    by the function's signature, values by the checks the method runs before it reads (the
    same Rust functions); with ``remote``, that it takes ``storage_options``. Raises
    :class:`UsageError` naming the option."""
    calib = _package()
    params = inspect.signature(getattr(calib, f"{method}_log")).parameters
    if remote and "storage_options" not in params:
        raise UsageError("storage_options: this build of calib reads local logs only; leave it out")
    takes = [name for name in params if name not in ("path", "storage_options")]
    unknown = [name for name in options if name not in takes]
    if unknown:
        raise UsageError(
            f"{method}: unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
            f"calib.{method}_log takes {', '.join(takes)}"
        )
    missing = [
        name
        for name in takes
        if params[name].default is inspect.Parameter.empty and name not in options
    ]
    if missing:
        raise UsageError(f"{method}: give the option{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
    kwargs = dict(options)
    try:
        if method == "multihead":
            positions = kwargs.pop("positions")
            if not isinstance(positions, Mapping):
                raise UsageError("positions: give a dict of each head's channel → its nominal angle, degrees")
            names = list(positions)
            _calib.check_multihead_log(names, calib._heads(positions, names), **kwargs)
            return
        if method == "csrr" and "benchmarks" in kwargs:
            kwargs["benchmarks"] = tuple(float(x) for x in kwargs["benchmarks"])
        if method == "tdr" and kwargs.get("cogging_orders") is not None:
            kwargs["cogging_orders"] = [int(k) for k in kwargs["cogging_orders"]]
        getattr(_calib, f"check_{method}_log")(**kwargs)
    except (TypeError, ValueError) as e:
        if isinstance(e, CalibError):
            raise
        # pyo3's words name the argument: "argument 'points': 'str' object cannot be …".
        raise UsageError(f"{method}: {e}") from None


def _package():
    """The ``calib`` package, whose wrappers a task calls (imported when first needed: this
    module is imported by the package's ``__init__``)."""
    import calib

    return calib


def _is_url(log: str) -> bool:
    return "://" in log


def _parts(log: str) -> List[str]:
    """A log's location as path components: a URL's scheme, host and path (its query left
    out), or a local path's components."""
    if _is_url(log):
        scheme, rest = log.split("://", 1)
        rest = rest.split("?", 1)[0].split("#", 1)[0]
        return [scheme] + [p for p in rest.split("/") if p]
    return [p for p in log.split(os.sep) if p]


def relative_folders(logs: Sequence[str]) -> List[str]:
    """Each log's output folder: its path relative to the folder all the logs share,
    ``/``-separated (``["f/r1/run.mcap", "f/r2/run.mcap"]`` → ``["r1/run.mcap",
    "r2/run.mcap"]``; one log → its file name)."""
    parts = [_parts(log) for log in logs]
    common = os.path.commonprefix([p[:-1] for p in parts]) if parts else []
    return ["/".join(p[len(common) :]) for p in parts]


def _gathered(future: concurrent.futures.Future, task: Task) -> Dict[str, Any]:
    """The row of a finished task; a task the engine itself lost (a worker killed, a pool
    broken) is a ``failed`` row too."""
    try:
        return future.result()
    except Exception as e:  # noqa: BLE001 - whatever the engine raises is this log's row
        return _row(task, "failed", error=f"{type(e).__name__}: {e}")


def _row(task: Task, status: str, **values: Any) -> Dict[str, Any]:
    row: Dict[str, Any] = {name: None for name in LOG_COLUMNS}
    row.update(log=task.shown, output=task.folder, status=status, gate_failures="", warnings="")
    row.update(values)
    return row


def run_task(task: Task) -> Dict[str, Any]:
    """Calibrates one log and writes its outputs: the function the workers run. Never raises:
    a log that cannot be calibrated or written is a ``failed`` row naming why."""
    start = time.perf_counter()
    kwargs = dict(task.options)
    if task.storage_options is not None:
        kwargs["storage_options"] = task.storage_options
    try:
        result = getattr(_package(), f"{task.method}_log")(task.log, **kwargs)
    except Exception as e:  # noqa: BLE001 - one log's failure is its row, never the run's end
        message = str(e) if isinstance(e, CalibError) else f"{type(e).__name__}: {e}"
        return _row(task, "failed", error=message, elapsed_s=time.perf_counter() - start)
    report = result.report
    failures = task.gates.failures(report)
    try:
        if task.out is not None:
            write_outputs(result, task.out, task.folder, task.out_options)
    except Exception as e:  # noqa: BLE001 - a write that fails is this log's row
        return _row(
            task,
            "failed",
            error=f"writing {task.folder} under {task.out}: {type(e).__name__}: {e}",
            elapsed_s=time.perf_counter() - start,
        )
    details = report.get("details") or {}
    orders = details.get("orders_kept")
    if orders is None and isinstance(details.get("orders"), dict):
        orders = details["orders"].get("kept")
    row = _row(
        task,
        "gate failed" if failures else "ok",
        gate_failures="\n".join(failures),
        warnings="\n".join(report["warnings"]),
        residual_rms_arcsec=details.get("residual_rms_arcsec"),
        orders_kept=None if orders is None else len(orders),
        latency_s=details.get("latency_s"),
        ratio=details.get("ratio"),
        elapsed_s=time.perf_counter() - start,
    )
    for name, ch in result.channels.items():
        row[f"peak_to_peak_arcsec[{name}]"] = ch.report["peak_to_peak_arcsec"]
        row[f"rms_arcsec[{name}]"] = ch.report["rms_arcsec"]
        row[f"after_peak_to_peak_arcsec[{name}]"] = _after(ch.report)
        row[f"u_max_arcsec[{name}]"] = None if ch.u_arcsec is None else float(ch.u_arcsec.max())
    return row


def frame(rows: Sequence[Mapping[str, Any]]):
    """The rows as a DataFrame: :data:`LOG_COLUMNS`, then each channel's figures in the order
    the channels first appear."""
    from . import _pandas

    pd = _pandas()
    channel_columns: List[str] = []
    for row in rows:
        channel_columns.extend(c for c in row if c not in LOG_COLUMNS and c not in channel_columns)
    return pd.DataFrame(list(rows), columns=list(LOG_COLUMNS) + channel_columns)


def _table_file(name: str, channel_report: dict) -> str:
    """The file name of a channel's table: the report's ``table`` entry (calib's own safe
    name for the channel)."""
    return channel_report.get("table") or f"{name}.csv"


def write_outputs(result, out: str, folder: str, out_options: Optional[Dict[str, Any]]) -> None:
    """Writes a result's tables and then its ``report.json`` to ``out/folder/``, each file
    whole or not at all."""
    files = []
    with tempfile.TemporaryDirectory(prefix="calib-fleet-") as tmp:
        for name, ch in result.channels.items():
            file = _table_file(name, ch.report)
            # calib's own table writer: the bytes `calib <method>` writes.
            ch.table.write(os.path.join(tmp, file))
            with open(os.path.join(tmp, file), "rb") as f:
                files.append((file, f.read()))
    report = json.dumps(result.report, indent=2, ensure_ascii=False) + "\n"
    files.append(("report.json", report.encode("utf-8")))
    put_files(out, folder, files, out_options)


def put_files(out: str, folder: str, files: Sequence[tuple], out_options: Optional[Dict[str, Any]]) -> None:
    """Writes ``(name, bytes)`` pairs under ``out/folder/`` in order: locally to a temporary
    name and renamed over the file, to an object store with one put per file (a put is whole
    or absent)."""
    if _is_url(out):
        import fsspec

        fs, root = fsspec.core.url_to_fs(out, **(out_options or {}))
        base = "/".join(p for p in (root.rstrip("/"), folder) if p)
        for name, data in files:
            fs.pipe_file(f"{base}/{name}", data)
        return
    base = os.path.join(out, *folder.split("/")) if folder else out
    os.makedirs(base, exist_ok=True)
    for name, data in files:
        path = os.path.join(base, name)
        temp = os.path.join(base, f".{name}.{socket.gethostname()}-{os.getpid()}-{uuid.uuid4().hex[:8]}.tmp")
        try:
            with open(temp, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            os.replace(temp, path)
        finally:
            if os.path.exists(temp):
                os.remove(temp)


def write_summary(table, out: str, out_options: Optional[Dict[str, Any]]) -> None:
    """Writes the fleet's table as ``summary.parquet`` and ``summary.csv`` in ``out``."""
    parquet = io.BytesIO()
    table.to_parquet(parquet, index=False)
    csv = table.to_csv(index=False).encode("utf-8")
    put_files(out, "", [("summary.parquet", parquet.getvalue()), ("summary.csv", csv)], out_options)
