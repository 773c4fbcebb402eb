"""calib: offline calibration of angular encoders from recorded runs.

The same library as the ``calib`` command line, from Python: numpy arrays (or the logs calib
reads) in, correction tables and reports out. Conventions are the command line's:

- readings and time stamps cross as numpy arrays, readings in **radians**, time in seconds;
- tables are on the uniform grid ``i·360°/N`` of the sensor's own reading, errors in
  **arcseconds**: ``error = reading − true angle``, ``correction = −error``, zero mean;
- options are the CLI's, as keyword arguments with the same names (``-`` written ``_``) and
  defaults, in the CLI's units (degrees, degrees per second, arcseconds);
- bad data raises :class:`DataError` (the CLI's exit status 1), a bad argument
  :class:`UsageError` (exit status 2), both with the CLI's messages; an array argument that is
  empty or holds NaN, an infinity or a value no log could hold raises :class:`ArrayError`, a
  :class:`UsageError` that is also a ``ValueError``, naming the argument and its first bad index
  (``a[17] is NaN``), as the CLI's readers refuse such a row.

Reading and solving release the GIL: several logs calibrated on threads run in parallel.
:func:`map_logs` calibrates a fleet of logs on any ``concurrent.futures`` executor (a process
pool, Dask, Ray), one row per log in a pandas DataFrame (``docs/fleet.md``).

Example::

    import calib
    res = calib.csrr_log("testdata/examples/quick.mcap", a="a", b="b")
    a = res.channels["a"]
    print(a.peak_to_peak_arcsec, a.harmonics[0])
    a.table.write("a.csv")
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _calib
from ._calib import ArrayError, CalibError, DataError, UsageError, __version__

__all__ = [
    "CalibError",
    "DataError",
    "UsageError",
    "ArrayError",
    "Log",
    "Table",
    "Channel",
    "Result",
    "Simulation",
    "read",
    "csrr",
    "csrr_log",
    "reference",
    "reference_log",
    "tdr",
    "tdr_log",
    "multihead",
    "multihead_log",
    "shift_angle",
    "inspect",
    "export",
    "compose",
    "simulate",
    "map_logs",
    "__version__",
]

PathLike = Union[str, "os.PathLike[str]"]
# A log: a path, a URL (``s3://``, ``gs://``, ``az://``, ``http(s)://``) or a binary file object
# (anything with ``.read()``, such as an ``fsspec`` file), which is read whole into memory.
LogLike = Union[str, "os.PathLike[str]", Any]


def _log(path: LogLike) -> Any:
    """A log for the native module: a file object as it is, else its path or URL as text."""
    return path if hasattr(path, "read") else os.fspath(path)


def _storage(options: Optional[Mapping[str, Any]]) -> Optional[Dict[str, str]]:
    """``storage_options`` as text, as ``object_store`` takes them (``True`` is ``"true"``)."""
    if options is None:
        return None
    return {str(k): (str(v).lower() if isinstance(v, bool) else str(v)) for k, v in options.items()}


def _f64(name: str, values: Any) -> np.ndarray:
    """``values`` as a contiguous 1-D float64 array: a view where it already is one, no copy."""
    array = np.ascontiguousarray(values, dtype=np.float64)
    if array.ndim != 1:
        raise UsageError(f"{name} must be one-dimensional, not of shape {array.shape}")
    return array


def _optional_f64(name: str, values: Any) -> Optional[np.ndarray]:
    return None if values is None else _f64(name, values)


def _pandas():
    try:
        import pandas
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("to_pandas() needs pandas: pip install pandas") from e
    return pandas


class Log:
    """A log read by :func:`read`: its time stamps and one array per channel.

    Attributes:
        t: time stamps, seconds on the log's own clock (float64).
        channels: channel name → readings in radians (float64), one per stamp.
        session: the CSV ``session`` column (-1 where a row is in no session), or None.
        alignment: how channels on separate topics were aligned on the first one's clock
            (report.json's ``details.alignment``), or None where nothing was interpolated or
            dropped.
        warnings: what the reader warns about (a truncated file, samples dropped in alignment).
        notes: parts of the log that were not read (topics of other message types).
    """

    def __init__(self, raw: Mapping[str, Any]):
        self.t: np.ndarray = raw["t"]
        self.channels: Dict[str, np.ndarray] = dict(raw["channels"])
        self.session: Optional[np.ndarray] = raw["session"]
        alignment = raw["alignment_json"]
        self.alignment: Optional[dict] = None if alignment is None else json.loads(alignment)
        self.warnings: List[str] = list(raw["warnings"])
        self.notes: List[str] = list(raw["notes"])

    def __getitem__(self, name: str) -> np.ndarray:
        return self.channels[name]

    def __len__(self) -> int:
        return len(self.t)

    def __repr__(self) -> str:
        return f"Log({len(self)} samples, channels {list(self.channels)})"

    def to_pandas(self):
        """A DataFrame indexed by ``t`` with one column per channel (radians) and ``session``."""
        pd = _pandas()
        columns = dict(self.channels)
        if self.session is not None:
            columns["session"] = self.session
        return pd.DataFrame(columns, index=pd.Index(self.t, name="t"))


def read(
    path: LogLike,
    channels: Optional[Sequence[str]] = None,
    time: str = "header",
    *,
    unit: Optional[str] = None,
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Mapping[str, Any]] = None,
) -> Log:
    """Reads a log (CSV, MCAP, a rosbag2 bag: its directory or .db3 file, a ROS 1 .bag) into arrays.

    Args:
        path: the log: a path, a URL or a binary file object.
        channels: the channels to read, in this order, the first setting the clock the others
            are aligned on (None: every channel). Named as on the command line: a CSV column,
            a joint name, ``TOPIC/NAME``, ``TOPIC.field.path``.
        time: ``"header"`` (a message's ``header.stamp``) or ``"log"`` (its log time).
        unit: unit of CSV and JSON readings: ``deg`` (default), ``rad``, ``arcsec``, ``rev``,
            ``counts:N``. JointState positions are radians whatever it says.
        max_gap: longest interval interpolated across when aligning, seconds (default: 2.5 of
            each channel's median interval).
        time_column: the CSV time column (default ``t``, ``time`` or ``timestamp``).
        time_unit: unit of the CSV time column: ``s``, ``ms``, ``us`` or ``ns``.
        storage_options: options of the object store a URL is read from (``object_store``
            keys: ``aws_endpoint``, ``aws_access_key_id``, ``aws_secret_access_key``,
            ``aws_region``, ``aws_allow_http``, …), over the credentials in the environment.

    Returns:
        A :class:`Log`; readings in radians.

    Raises:
        UsageError: no such file, an unknown or ambiguous channel, a bad option.
        DataError: the log cannot be read (the message names the file and line or message).
    """
    return Log(
        _calib.read(
            _log(path),
            None if channels is None else list(channels),
            time,
            unit,
            max_gap,
            time_column,
            time_unit,
            _storage(storage_options),
        )
    )


class Table:
    """A correction table: errors on a uniform grid, over a whole turn (``i·360°/N``) or over a
    range of readings (``lo + (hi − lo)·i/(N − 1)``, both ends grid points).

    Build one from errors in arcseconds (``Table(errors)``, or ``Table(errors,
    range_deg=(lo, hi))`` for a range), read one calib wrote (:meth:`read`), or take one from a
    result (``res.channels["a"].table``).

    Attributes:
        error_arcsec: the error ``reading − true angle`` at each grid point, arcseconds.
        u_arcsec: the standard uncertainty of each point, arcseconds, or None.
        range_deg: ``(lo, hi)``, the first and last grid readings in degrees, for a table over
            part of a turn (signed across the reading 0, e.g. ``(-40.0, 95.0)``); None for a
            whole turn.
    """

    def __init__(
        self,
        error_arcsec: Any,
        u_arcsec: Any = None,
        *,
        range_deg: Optional[Tuple[float, float]] = None,
    ):
        self.error_arcsec: np.ndarray = _f64("error_arcsec", error_arcsec)
        self.u_arcsec: Optional[np.ndarray] = _optional_f64("u_arcsec", u_arcsec)
        self.range_deg: Optional[Tuple[float, float]] = None
        if range_deg is not None:
            lo, hi = (float(x) for x in range_deg)
            self.range_deg = (lo, hi)
        # The CLI's table reader's rules, checked as the table is made: at least 2 points,
        # finite errors, finite non-negative uncertainties (one per point), a range less than a
        # turn long.
        _calib.check_table(self.error_arcsec, self.u_arcsec, self.range_deg)

    @property
    def is_range(self) -> bool:
        """Whether the table covers part of a turn only (see ``range_deg``)."""
        return self.range_deg is not None

    @property
    def angle_deg(self) -> np.ndarray:
        """The grid: the sensor's reading at each point, degrees (``i·360/N``, or from ``lo``
        to ``hi`` for a range)."""
        n = len(self.error_arcsec)
        if self.range_deg is None:
            return np.arange(n) * (360.0 / n)
        lo, hi = self.range_deg
        return lo + (hi - lo) * np.arange(n) / (n - 1)

    @property
    def correction_arcsec(self) -> np.ndarray:
        """The correction to add to a reading at each point, arcseconds (``−error``)."""
        return -self.error_arcsec

    @property
    def peak_to_peak_arcsec(self) -> float:
        """Largest minus smallest error, arcseconds."""
        return float(self.error_arcsec.max() - self.error_arcsec.min())

    @property
    def rms_arcsec(self) -> float:
        """RMS of the errors, arcseconds."""
        return float(np.sqrt(np.mean(self.error_arcsec**2)))

    def __len__(self) -> int:
        return len(self.error_arcsec)

    def __repr__(self) -> str:
        over = "" if self.range_deg is None else f" over {self.range_deg[0]:g}° to {self.range_deg[1]:g}°"
        return f"Table({len(self)} points{over}, {self.peak_to_peak_arcsec:.3f}″ peak to peak)"

    @classmethod
    def read(cls, path: PathLike) -> "Table":
        """Reads a correction table calib wrote (``angle_deg,error_arcsec,correction_arcsec``
        and optionally ``u_arcsec``; a range table with its ``# range_deg:`` line), checking its
        grid, as ``calib apply`` and ``export`` do.

        Raises:
            UsageError: no such file.
            DataError: the file is not a correction table (the message names the line and
                column).
        """
        error, u, range_deg = _calib.read_table(os.fspath(path))
        return cls(error, u, range_deg=range_deg)

    def write(self, path: PathLike) -> None:
        """Writes the table as calib does: complete, or not at all (through a temporary file)."""
        _calib.write_table(os.fspath(path), self.error_arcsec, self.u_arcsec, self.range_deg)

    def correct(self, readings: Any) -> np.ndarray:
        """Corrected readings ``r − e(r)`` (radians in and out), the table interpolated
        linearly at each reading (periodically for a whole turn), as ``calib apply`` and a
        controller do; a range table leaves readings outside its range unchanged."""
        return _calib.correct(self.error_arcsec, _f64("readings", readings), self.range_deg)

    def error_at(self, readings: Any) -> np.ndarray:
        """The table's error at ``readings`` (radians), arcseconds, interpolated as in
        :meth:`correct`."""
        r = _f64("readings", readings)
        return (r - self.correct(r)) * (180.0 / np.pi * 3600.0)

    def to_pandas(self):
        """A DataFrame with the columns of the CSV table."""
        pd = _pandas()
        columns = {
            "angle_deg": self.angle_deg,
            "error_arcsec": self.error_arcsec,
            "correction_arcsec": self.correction_arcsec,
        }
        if self.u_arcsec is not None:
            columns["u_arcsec"] = self.u_arcsec
        return pd.DataFrame(columns)


class Channel:
    """One calibrated channel of a :class:`Result`.

    Attributes:
        name: the channel's name.
        angle_deg: the table's grid, degrees (a range table's covers its range only).
        error_arcsec: the error at each grid point, arcseconds.
        u_arcsec: the standard uncertainty at each point, arcseconds, or None.
        report: the channel's entry of report.json (``peak_to_peak_arcsec``, ``rms_arcsec``,
            ``harmonics``, ``after_correction`` …).
        is_range: whether the table covers part of a turn only (a joint that never turned a
            whole revolution; reference method).
        range_deg: ``(lo, hi)``, the first and last grid readings of a range table in degrees
            (signed across the reading 0, as the CSV table), or None for a whole turn.
    """

    def __init__(self, name: str, raw: Mapping[str, Any], report: dict):
        self.name = name
        self.angle_deg: np.ndarray = raw["angle_deg"]
        self.error_arcsec: np.ndarray = raw["error_arcsec"]
        self.u_arcsec: Optional[np.ndarray] = raw["u_arcsec"]
        self.range_deg: Optional[Tuple[float, float]] = raw["range"]
        self.is_range: bool = self.range_deg is not None
        self.report: dict = report

    @property
    def correction_arcsec(self) -> np.ndarray:
        """The correction at each grid point, arcseconds (``−error``)."""
        return -self.error_arcsec

    @property
    def harmonics(self) -> List[dict]:
        """The map's largest harmonics: ``order``, ``amplitude_arcsec``, ``phase_deg`` (the
        component ``amplitude·cos(order·θ + phase)``), largest first."""
        return list(self.report.get("harmonics", []))

    @property
    def peak_to_peak_arcsec(self) -> float:
        """Peak-to-peak error, arcseconds."""
        return float(self.report["peak_to_peak_arcsec"])

    @property
    def rms_arcsec(self) -> float:
        """RMS error, arcseconds."""
        return float(self.report["rms_arcsec"])

    @property
    def table(self) -> Table:
        """The channel's :class:`Table` (to write, apply, export, compose), over its range for
        a range channel."""
        return Table(self.error_arcsec, self.u_arcsec, range_deg=self.range_deg)

    def __repr__(self) -> str:
        return f"Channel({self.name!r}, {len(self.error_arcsec)} points, {self.peak_to_peak_arcsec:.3f}″ p-p)"

    def to_pandas(self):
        """A DataFrame with the columns of the CSV table."""
        pd = _pandas()
        columns = {
            "angle_deg": self.angle_deg,
            "error_arcsec": self.error_arcsec,
            "correction_arcsec": self.correction_arcsec,
        }
        if self.u_arcsec is not None:
            columns["u_arcsec"] = self.u_arcsec
        return pd.DataFrame(columns)


class Result:
    """What a method returns.

    Attributes:
        method: ``csrr``, ``reference``, ``tdr``, ``multihead`` or ``shift-angle``.
        channels: channel name → :class:`Channel` (its table and figures).
        warnings: things to know about the result (the reader's first, then the method's).
        report: report.json as a dict (same schema; ``command_line`` absent, ``inputs`` the
            path given, or empty for arrays).
    """

    def __init__(self, raw: Mapping[str, Any]):
        self.report: dict = json.loads(raw["report_json"])
        self.method: str = self.report["method"]
        self.warnings: List[str] = list(self.report["warnings"])
        self.channels: Dict[str, Channel] = {
            name: Channel(name, table, self.report["channels"][name])
            for name, table in raw["tables"].items()
        }
        polygon = raw.get("polygon")
        #: shift-angle only: ``face`` and ``pitch_deviation_arcsec`` of the polygon's faces.
        self.polygon: Optional[Dict[str, np.ndarray]] = None if polygon is None else dict(polygon)

    def __repr__(self) -> str:
        return f"Result({self.method}, channels {list(self.channels)}, {len(self.warnings)} warning(s))"

    def to_pandas(self):
        """One DataFrame of every channel's table, with a ``channel`` column."""
        pd = _pandas()
        frames = [c.to_pandas().assign(channel=name) for name, c in self.channels.items()]
        return pd.concat(frames, ignore_index=True)


def _sessions(sessions: Any) -> Optional[np.ndarray]:
    if sessions is None:
        return None
    array = np.ascontiguousarray(sessions, dtype=np.int64)
    if array.ndim != 1:
        raise UsageError(f"sessions must be one-dimensional, not of shape {array.shape}")
    return array


def csrr(
    a: Any,
    b: Any,
    t: Any = None,
    sessions: Any = None,
    ref: Any = None,
    *,
    names: Tuple[str, str] = ("a", "b"),
    rate_hz: float = 1000.0,
    method: str = "joint",
    max_order: Optional[int] = None,
    points: Optional[int] = None,
    session_tol: Optional[float] = None,
    min_speed: float = 1.0,
    detect_sessions: bool = False,
    min_observability: float = 0.01,
    benchmarks: Tuple[float, float] = (0.0, 0.0),
    latency: Union[str, float] = "auto",
) -> Result:
    """CSRR self-calibration of two coaxial sensors from arrays (``calib csrr``).

    Record the two sensors turning together for whole revolutions (a session), stop, turn one
    rotor against the other, and repeat; 5 sessions of 3 revolutions at well-spread relative
    rotations are plenty for the joint method.

    Args:
        a, b: the readings of sensor A (the rotor turned between sessions) and B, radians,
            wrapped to one turn or accumulated.
        t: time stamps, seconds (None: samples ``1/rate_hz`` apart).
        sessions: the session of each sample (negative: in none); None: sessions found from
            the motion. Given with ``detect_sessions=True``, found from the motion all the same.
        ref: readings of a reference encoder on B's shaft, radians, to check the result against
            (its channel is named ``ref`` in the report).
        names: the names of A and B in the result and report.
        rate_hz: the sample rate where ``t`` is None.
        method: ``"joint"`` (joint least squares) or ``"paper"`` (the seed paper's method).
        max_order: highest harmonic order tested (default: 40 % of the samples per revolution
            of the densest session, at most 2000); only orders above the noise are kept.
        points: points of the tables (default: enough for linear interpolation to 0.01″).
        session_tol: largest change of `a − b` from one revolution to the next within a session,
            degrees; None (the default): from the sessions' own scatter, as the CLI does.
        min_speed: speed below which a sensor counts as stopped, degrees per second.
        detect_sessions: find sessions from the motion even where ``sessions`` is given.
        min_observability: orders less observable than this are left out of the maps.
        benchmarks: benchmark readings of A and B for ``method="paper"``, degrees.
        latency: B's lag behind A, removed by moving B's readings to A's instants: ``"auto"``
            (the default) finds it from how each session's `a − b` departs from one revolution
            earlier as the speed changes, and reads the samples again with it removed where
            significant; seconds (positive: B's sample is older) removes that lag; ``0`` none.
            ``report["details"]["latency_s"]`` is the lag removed.

    Returns:
        A :class:`Result` with channels ``names[0]`` and ``names[1]``.

    Raises:
        DataError: the samples cannot be calibrated (too few sessions, never moving …).
        UsageError: an option outside its range, arrays of different lengths.
    """
    return Result(
        _calib.csrr(
            _f64("a", a),
            _f64("b", b),
            _optional_f64("t", t),
            _sessions(sessions),
            _optional_f64("ref", ref),
            names=(str(names[0]), str(names[1])),
            rate_hz=rate_hz,
            method=method,
            max_order=max_order,
            points=points,
            session_tol=session_tol,
            min_speed=min_speed,
            detect_sessions=detect_sessions,
            min_observability=min_observability,
            benchmarks=(float(benchmarks[0]), float(benchmarks[1])),
            latency=latency,
        )
    )


def csrr_log(
    path: LogLike,
    *,
    a: str = "a",
    b: str = "b",
    ref: Optional[str] = None,
    method: str = "joint",
    max_order: Optional[int] = None,
    points: Optional[int] = None,
    session_tol: Optional[float] = None,
    min_speed: float = 1.0,
    detect_sessions: bool = False,
    min_observability: float = 0.01,
    benchmarks: Tuple[float, float] = (0.0, 0.0),
    latency: Union[str, float] = "auto",
    unit: Optional[str] = None,
    time: str = "header",
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Mapping[str, Any]] = None,
) -> Result:
    """CSRR self-calibration of channels ``a`` and ``b`` of a log, streamed through calib's
    readers (``calib csrr LOG``: the same report.json, without writing files).

    Sessions come from a CSV ``session`` column where the log has one (unless
    ``detect_sessions``), else from the motion. ``ref`` names a reference channel on B's shaft.
    The reading options are :func:`read`'s; the others :func:`csrr`'s.

    ``path`` may be a URL or a file object, with ``storage_options``, as for :func:`read`.
    """
    return Result(
        _calib.csrr_log(
            _log(path),
            a=a,
            b=b,
            ref=ref,
            method=method,
            max_order=max_order,
            points=points,
            session_tol=session_tol,
            min_speed=min_speed,
            detect_sessions=detect_sessions,
            min_observability=min_observability,
            benchmarks=(float(benchmarks[0]), float(benchmarks[1])),
            latency=latency,
            unit=unit,
            time=time,
            max_gap=max_gap,
            time_column=time_column,
            time_unit=time_unit,
            storage_options=_storage(storage_options),
        )
    )


def reference(
    dut: Any,
    ref: Any,
    t: Any = None,
    *,
    names: Tuple[str, str] = ("dut", "ref"),
    rate_hz: float = 1000.0,
    ref_u: Optional[float] = None,
    points: int = 3600,
    min_speed: float = 1.0,
    follow_tol: float = 5.0,
    bridge_gap: float = 5.0,
    targets: Union[int, Sequence[float]] = 20,
    approach: float = 1.0,
    latency: Union[str, float] = "auto",
    ref_kind: str = "encoder",
    pole_pairs: Optional[int] = None,
    ref_ratio: Union[str, float, None] = None,
    ref_orders: int = 16,
) -> Result:
    """Cross-calibration of an encoder (the DUT) against a better reference encoder on the
    same shaft, from arrays (``calib reference``); ISO 230-2 figures in ``report["details"]``.

    Args:
        dut, ref: the readings of the DUT and the reference, radians.
        t: time stamps, seconds (None: samples ``1/rate_hz`` apart).
        names: the names of the DUT and the reference in the result and report.
        ref_u: the reference's own standard uncertainty, arcseconds (added to every point's u);
            None (the default): not known, left out of u, and the result warns that u excludes
            the reference.
        points: points of the table.
        min_speed: speed below which the shaft counts as stopped, degrees per second.
        follow_tol: largest difference between the two readings, degrees (beyond: not the same
            shaft, or a slipped coupling).
        bridge_gap: largest part of the turn never reached that is bridged, degrees.
        targets: ISO 230-2 targets: a count, or readings in degrees.
        approach: travel before a target that counts as approaching it, degrees.
        latency: the DUT's lag behind the reference: ``"auto"`` (the default) fits it with the
            map and removes it where the run tells it from backlash (passes at two speeds in a
            direction); seconds (positive: the DUT's sample is older) removes that lag; ``0``
            none. ``report["details"]["latency_s"]``.
        ref_kind: ``"encoder"`` (a better encoder on the DUT's shaft) or ``"commanded"`` (a
            motor's open-loop commanded angle: the motor's ripple, periodic in the electrical
            angle, is taken out of the map and reported).
        pole_pairs: the motor's pole pairs, with ``ref_kind="commanded"``.
        ref_ratio: the reference turns this many times per turn of the DUT (an actuator's
            motor encoder before a gear, the DUT its output encoder; negative where it turns the
            other way), or ``"auto"`` to estimate it (``report["details"]["ratio"]`` and
            ``["ratio_u"]``). Both encoders' maps come from the run: the reference's, over one
            of its turns, is a second table named ``names[1]``. None (the default): one shaft.
        ref_orders: orders of the reference's own error fitted through a gear.

    Returns:
        A :class:`Result` with one channel, ``names[0]`` (a range table where the DUT never
        turned a whole revolution), and ``names[1]``'s table through a gear.
    """
    return Result(
        _calib.reference(
            _f64("dut", dut),
            _f64("ref", ref),
            _optional_f64("t", t),
            names=(str(names[0]), str(names[1])),
            rate_hz=rate_hz,
            ref_u=ref_u,
            points=points,
            min_speed=min_speed,
            follow_tol=follow_tol,
            bridge_gap=bridge_gap,
            targets=targets,
            approach=approach,
            latency=latency,
            ref_kind=ref_kind,
            pole_pairs=pole_pairs,
            ref_ratio=ref_ratio,
            ref_orders=ref_orders,
        )
    )


def reference_log(
    path: LogLike,
    *,
    dut: str,
    ref: str,
    ref_u: Optional[float] = None,
    points: int = 3600,
    min_speed: float = 1.0,
    follow_tol: float = 5.0,
    bridge_gap: float = 5.0,
    targets: Union[int, Sequence[float]] = 20,
    approach: float = 1.0,
    latency: Union[str, float] = "auto",
    ref_kind: str = "encoder",
    pole_pairs: Optional[int] = None,
    ref_ratio: Union[str, float, None] = None,
    ref_orders: int = 16,
    unit: Optional[str] = None,
    time: str = "header",
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Mapping[str, Any]] = None,
) -> Result:
    """Cross-calibration of channel ``dut`` of a log against its channel ``ref``
    (``calib reference LOG --dut --ref``). Options as :func:`reference` and :func:`read`.

    ``path`` may be a URL or a file object, with ``storage_options``, as for :func:`read`.
    """
    return Result(
        _calib.reference_log(
            _log(path),
            dut=dut,
            ref=ref,
            ref_u=ref_u,
            points=points,
            min_speed=min_speed,
            follow_tol=follow_tol,
            bridge_gap=bridge_gap,
            targets=targets,
            approach=approach,
            latency=latency,
            ref_kind=ref_kind,
            pole_pairs=pole_pairs,
            ref_ratio=ref_ratio,
            ref_orders=ref_orders,
            unit=unit,
            time=time,
            max_gap=max_gap,
            time_column=time_column,
            time_unit=time_unit,
            storage_options=_storage(storage_options),
        )
    )


def tdr(
    t: Any,
    readings: Any,
    ref: Any = None,
    *,
    name: str = "encoder",
    max_order: Optional[int] = None,
    max_drag_order: int = 16,
    motion_degree: Optional[int] = None,
    min_revolutions: float = 10.0,
    points: Optional[int] = None,
    run: str = "auto",
    pole_pairs: Optional[int] = None,
    cogging_orders: Optional[Sequence[int]] = None,
) -> Result:
    """Self-calibration of one encoder from a free spin-down or a driven run (``calib tdr``,
    Lu & Trumper's time-domain method): the shaft coasts freely, or a motor drives it at steady
    speed, many revolutions, and the encoder's error, periodic in angle, is told from the smooth
    motion.

    Args:
        t: time stamps, seconds.
        readings: the encoder's readings, radians.
        ref: readings of a reference encoder on the same shaft, radians, to check against.
        name: the channel's name in the result and report.
        max_order: highest harmonic order of the map (default: from the samples per turn).
        max_drag_order: highest order of the angle-periodic drag fitted with it.
        motion_degree: degree of the Chebyshev series of the motion (default: chosen).
        min_revolutions: the shortest coast (or driven pass) accepted, revolutions.
        points: points of the table (default: enough for linear interpolation to 0.01″,
            at least 3600).
        run: ``"coast"``, ``"driven"`` (passes at steady speed) or ``"auto"`` (a coast where
            there is one, else a driven run).
        pole_pairs: the driving motor's pole pairs: its cogging and torque ripple at orders
            k·6·pole_pairs are left out of the map at one speed, separated by their 1/ω²
            dependence over passes at two or more (``report["details"]["driven"]``).
        cogging_orders: the motor's orders as a list, instead of ``pole_pairs``.
    """
    return Result(
        _calib.tdr(
            _f64("t", t),
            _f64("readings", readings),
            _optional_f64("ref", ref),
            name=name,
            max_order=max_order,
            max_drag_order=max_drag_order,
            motion_degree=motion_degree,
            min_revolutions=min_revolutions,
            points=points,
            run=run,
            pole_pairs=pole_pairs,
            cogging_orders=None if cogging_orders is None else [int(k) for k in cogging_orders],
        )
    )


def tdr_log(
    path: LogLike,
    *,
    channel: str,
    ref: Optional[str] = None,
    max_order: Optional[int] = None,
    max_drag_order: int = 16,
    motion_degree: Optional[int] = None,
    min_revolutions: float = 10.0,
    points: Optional[int] = None,
    unit: Optional[str] = None,
    time: str = "header",
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Mapping[str, Any]] = None,
    run: str = "auto",
    pole_pairs: Optional[int] = None,
    cogging_orders: Optional[Sequence[int]] = None,
) -> Result:
    """Spin-down or driven-run self-calibration of a log's ``channel`` (``calib tdr LOG
    --channel``). Options as :func:`tdr` and :func:`read`.

    ``path`` may be a URL or a file object, with ``storage_options``, as for :func:`read`.
    """
    return Result(
        _calib.tdr_log(
            _log(path),
            channel=channel,
            ref=ref,
            max_order=max_order,
            max_drag_order=max_drag_order,
            motion_degree=motion_degree,
            min_revolutions=min_revolutions,
            points=points,
            unit=unit,
            time=time,
            max_gap=max_gap,
            time_column=time_column,
            time_unit=time_unit,
            storage_options=_storage(storage_options),
            run=run,
            pole_pairs=pole_pairs,
            cogging_orders=None if cogging_orders is None else [int(k) for k in cogging_orders],
        )
    )


def _heads(positions: Union[Mapping[str, float], Sequence[float]], names: Sequence[str]) -> List[float]:
    if isinstance(positions, Mapping):
        missing = [n for n in names if n not in positions]
        if missing:
            raise UsageError(f"positions gives no nominal angle for head(s) {', '.join(missing)}")
        return [float(positions[n]) for n in names]
    angles = [float(p) for p in positions]
    if len(angles) != len(names):
        raise UsageError(f"{len(angles)} positions for {len(names)} heads; give one angle per head")
    return angles


def multihead(
    heads: Mapping[str, Any],
    positions: Union[Mapping[str, float], Sequence[float]],
    *,
    method: str = "joint",
    sets: Optional[Sequence[Sequence[str]]] = None,
    max_order: Optional[int] = None,
    points: Optional[int] = None,
    min_observability: float = 0.01,
) -> Result:
    """Self-calibration of one scale read by several heads (``calib multihead``).

    Args:
        heads: head name → its readings, radians (all the same length, sampled together). The
            first head's map is the result's one channel.
        positions: each head's nominal angle around the scale, degrees (a dict by name, or a
            list in the order of ``heads``).
        method: ``"joint"`` (joint least squares, head angle errors included) or ``"eda"`` (the
            SelfA paper's equal-division average).
        sets: ``eda`` only: the head sets to average, as lists of names.
        max_order: highest harmonic order (default: from the heads' spacing).
        points: points of the table.
        min_observability: orders less observable than this are left out.
    """
    names = list(heads)
    return Result(
        _calib.multihead(
            names,
            [_f64(n, heads[n]) for n in names],
            _heads(positions, names),
            method=method,
            sets=None if sets is None else [list(s) for s in sets],
            max_order=max_order,
            points=points,
            min_observability=min_observability,
        )
    )


def multihead_log(
    path: LogLike,
    positions: Mapping[str, float],
    *,
    method: str = "joint",
    sets: Optional[Sequence[Sequence[str]]] = None,
    max_order: Optional[int] = None,
    points: Optional[int] = None,
    min_observability: float = 0.01,
    unit: Optional[str] = None,
    time: str = "header",
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Mapping[str, Any]] = None,
) -> Result:
    """Multi-head self-calibration of a log (``calib multihead LOG --heads NAME@DEG,...``):
    ``positions`` maps each head's channel to its nominal angle, degrees, the first setting the
    clock. Options as :func:`multihead` and :func:`read`.

    ``path`` may be a URL or a file object, with ``storage_options``, as for :func:`read`.
    """
    names = list(positions)
    return Result(
        _calib.multihead_log(
            _log(path),
            names,
            _heads(positions, names),
            method=method,
            sets=None if sets is None else [list(s) for s in sets],
            max_order=max_order,
            points=points,
            min_observability=min_observability,
            unit=unit,
            time=time,
            max_gap=max_gap,
            time_column=time_column,
            time_unit=time_unit,
            storage_options=_storage(storage_options),
        )
    )


def shift_angle(
    readings: PathLike,
    *,
    method: str = "joint",
    faces: Optional[int] = None,
    budget: Optional[PathLike] = None,
) -> Result:
    """Cross-calibration of an encoder and a polygon from autocollimator readings at every
    shift angle (``calib shift-angle``; Hsieh, Watanabe, Hsu 2022).

    Args:
        readings: the readings CSV (``shift_deg,start_face,step,reading_arcsec``).
        method: ``"joint"`` (one constrained fit) or ``"paper"`` (the paper's two steps).
        faces: the polygon's faces (default: the largest ``step``).
        budget: a GUM uncertainty budget (TOML), whose combined u then goes with every point.

    Returns:
        A :class:`Result` with the encoder's channel (points at the readings' angles) and
        ``polygon`` (each face's pitch deviation).
    """
    return Result(
        _calib.shift_angle(
            os.fspath(readings),
            method=method,
            faces=faces,
            budget=None if budget is None else os.fspath(budget),
        )
    )


def inspect(
    path: LogLike,
    *,
    a: Optional[str] = None,
    b: Optional[str] = None,
    time: str = "header",
    unit: Optional[str] = None,
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Mapping[str, Any]] = None,
) -> dict:
    """What a log holds — timing, channels, topics, segments, the methods it suits — as the dict ``calib inspect
    --json`` prints (same schema, ``docs/inspect.schema.json``). ``a`` and ``b`` name the pair
    whose sessions are looked for (default ``a`` and ``b`` where the log has them, else its
    first two channels).

    ``path`` may be a URL or a file object, with ``storage_options``, as for :func:`read`.
    """
    return json.loads(
        _calib.inspect(
            _log(path), a, b, time, unit, max_gap, time_column, time_unit, _storage(storage_options)
        )
    )


def _table(table: Union[Table, Channel]) -> Table:
    return table.table if isinstance(table, Channel) else table


def export(
    table: Union[Table, Channel],
    format: str = "moteus",
    *,
    points: Optional[int] = None,
    scale: Optional[float] = None,
    orders: Optional[Iterable[int]] = None,
    largest: Optional[int] = None,
    min_amplitude: float = 0.01,
    moteus_source: int = 0,
    title: str = "calib correction table",
) -> str:
    """The table in a controller's format, as ``calib export --format`` writes it.

    Args:
        table: a :class:`Table` (or a result's :class:`Channel`).
        format: ``lut-f32-rad``, ``lut-i16``, ``lut-u16``, ``lut-i8``, ``c-array``, ``csv``,
            ``harmonic``, ``moteus`` (``conf set`` lines), ``moteus-config``, ``simplefoc`` (its
            ``uint16_t`` table), ``simplefoc-float`` (releases before SimpleFOC's PR #75).
        points: entries of the exported table (default: the format's, else the table's).
        scale: arcseconds per LSB of the integer formats (default: the largest that fits).
        orders: keep only these harmonic orders; ``largest``: keep the largest this many.
        min_amplitude: ``harmonic`` format: leave out orders below this, arcseconds.
        moteus_source: the moteus encoder source the table is for.
        title: the title in the header lines.

    Returns:
        The text to write or send (moteus: the ``conf set`` lines).

    Raises:
        UsageError: a format calib does not know, or a table the format cannot hold (a range
            table in a format that needs a whole turn, as ``calib export``).
    """
    t = _table(table)
    text, _header = _calib.export(
        t.error_arcsec,
        format,
        range_deg=t.range_deg,
        points=points,
        scale=scale,
        orders=None if orders is None else [int(o) for o in orders],
        largest=largest,
        min_amplitude=min_amplitude,
        moteus_source=moteus_source,
        title=title,
    )
    return text


def compose(
    first: Union[Table, Channel],
    residual: Union[Table, Channel],
    factor: float = 1.0,
    *,
    points: Optional[int] = None,
) -> Table:
    """One table for a table already in use (``first``) followed by the ``residual``
    calibrated through it (``calib compose``): ``e(r) = e₁(r) + factor·e_R(r − e₁(r))``, zero
    mean, on ``points`` points (default: the larger table's). Where both tables have
    uncertainties the result has ``u = √(u₁² + (factor·u_R)²)``, ``u_R`` read where the
    residual is (the two calibrations independent, as ``calib compose``); otherwise none.

    Raises:
        UsageError: a range table (composition is over a whole turn), or a bad option.
    """
    tables = {"first": _table(first), "residual": _table(residual)}
    for name, t in tables.items():
        if t.range_deg is not None:
            raise UsageError(
                f"{name}: compose needs whole-turn tables, and this one covers "
                f"{t.range_deg[0]:g}° to {t.range_deg[1]:g}° only (calibrate a whole revolution)"
            )
    f, r = tables["first"], tables["residual"]
    error, u, _offset, _deviation = _calib.compose(
        f.error_arcsec, r.error_arcsec, factor, points, f.u_arcsec, r.u_arcsec
    )
    return Table(error, u)


class Simulation:
    """A simulated run (:func:`simulate`).

    Attributes:
        t: time stamps, seconds.
        channels: channel name → readings, radians.
        session: the session of each sample (-1: none) where the scenario marks sessions.
        truth: sensor name → its true error :class:`Table` (a function of its own reading).
    """

    def __init__(self, raw: Mapping[str, Any]):
        self.t: np.ndarray = raw["t"]
        self.channels: Dict[str, np.ndarray] = dict(raw["channels"])
        self.session: Optional[np.ndarray] = raw["session"]
        self.truth: Dict[str, Table] = {name: Table(e) for name, e in raw["truth"].items()}

    def __getitem__(self, name: str) -> np.ndarray:
        return self.channels[name]

    def __len__(self) -> int:
        return len(self.t)

    def __repr__(self) -> str:
        return f"Simulation({len(self)} samples, channels {list(self.channels)})"


def simulate(scenario: Union[PathLike, str, Mapping[str, Any]], *, points: int = 36000) -> Simulation:
    """Simulates a run with a known truth (``calib simulate``), in memory.

    Args:
        scenario: a scenario TOML file (as in ``testdata/scenarios/``), its TOML text, or the
            same as a dict.
        points: points of the truth tables.
    """
    if isinstance(scenario, Mapping):
        return Simulation(_calib.simulate(json.dumps(scenario), True, points))
    text = os.fspath(scenario)
    if "\n" not in text and "=" not in text:
        if not os.path.exists(text):
            raise UsageError(f"{text}: no such scenario file; check the path")
        with open(text, encoding="utf-8") as f:
            text = f.read()
    return Simulation(_calib.simulate(text, False, points))


# Last: the fleet module uses the classes and wrappers above.
from .fleet import map_logs  # noqa: E402
