"""Type stubs of the native module ``calib._calib`` (use the ``calib`` package itself)."""

from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

class CalibError(Exception): ...
class DataError(CalibError): ...
class UsageError(CalibError): ...
class ArrayError(UsageError, ValueError): ...

F64 = npt.NDArray[np.float64]

def read(
    path: Any,
    channels: Optional[List[str]] = None,
    time: str = "header",
    unit: Optional[str] = None,
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Dict[str, str]] = None,
) -> Dict[str, Any]: ...
def csrr(
    a: F64,
    b: F64,
    t: Optional[F64] = None,
    sessions: Optional[npt.NDArray[np.int64]] = None,
    ref: Optional[F64] = None,
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
    latency: Union[str, float, None] = None,
) -> Dict[str, Any]: ...
def csrr_log(
    path: Any,
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
    latency: Union[str, float, None] = None,
    unit: Optional[str] = None,
    time: str = "header",
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Dict[str, str]] = None,
) -> Dict[str, Any]: ...
def reference(
    dut: F64,
    ref: F64,
    t: Optional[F64] = None,
    *,
    names: Tuple[str, str] = ("dut", "ref"),
    rate_hz: float = 1000.0,
    ref_u: Optional[float] = None,
    points: int = 3600,
    min_speed: float = 1.0,
    follow_tol: float = 5.0,
    bridge_gap: float = 5.0,
    targets: Union[int, Sequence[float], None] = None,
    approach: float = 1.0,
    latency: Union[str, float, None] = None,
    ref_kind: str = "encoder",
    pole_pairs: Optional[int] = None,
    ref_ratio: Union[str, float, None] = None,
    ref_orders: int = 16,
) -> Dict[str, Any]: ...
def reference_log(
    path: Any,
    *,
    dut: str,
    ref: str,
    ref_u: Optional[float] = None,
    points: int = 3600,
    min_speed: float = 1.0,
    follow_tol: float = 5.0,
    bridge_gap: float = 5.0,
    targets: Union[int, Sequence[float], None] = None,
    approach: float = 1.0,
    latency: Union[str, float, None] = None,
    ref_kind: str = "encoder",
    pole_pairs: Optional[int] = None,
    ref_ratio: Union[str, float, None] = None,
    ref_orders: int = 16,
    unit: Optional[str] = None,
    time: str = "header",
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Dict[str, str]] = None,
) -> Dict[str, Any]: ...
def read_table(path: str) -> Tuple[F64, Optional[F64], Optional[Tuple[float, float]]]: ...
def check_table(
    error_arcsec: F64,
    u_arcsec: Optional[F64] = None,
    range_deg: Optional[Tuple[float, float]] = None,
) -> None: ...
def write_table(
    path: str,
    error_arcsec: F64,
    u_arcsec: Optional[F64] = None,
    range_deg: Optional[Tuple[float, float]] = None,
) -> None: ...
def correct(
    error_arcsec: F64, readings: F64, range_deg: Optional[Tuple[float, float]] = None
) -> F64: ...
def export(
    error_arcsec: F64,
    format: str,
    *,
    range_deg: Optional[Tuple[float, float]] = None,
    points: Optional[int] = None,
    scale: Optional[float] = None,
    orders: Optional[List[int]] = None,
    largest: Optional[int] = None,
    min_amplitude: float = 0.01,
    moteus_source: int = 0,
    title: str = "calib correction table",
) -> Tuple[str, List[str]]: ...
def compose(
    first_arcsec: F64,
    residual_arcsec: F64,
    factor: float = 1.0,
    points: Optional[int] = None,
    first_u_arcsec: Optional[F64] = None,
    residual_u_arcsec: Optional[F64] = None,
) -> Tuple[F64, Optional[F64], float, float]: ...
def simulate(text: str, is_json: bool, points: int = 36000) -> Dict[str, Any]: ...
def inspect(
    path: Any,
    a: Optional[str] = None,
    b: Optional[str] = None,
    time: str = "header",
    unit: Optional[str] = None,
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Dict[str, str]] = None,
) -> str: ...
def tdr(
    t: F64,
    readings: F64,
    ref: Optional[F64] = None,
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
) -> Dict[str, Any]: ...
def tdr_log(
    path: Any,
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
    run: str = "auto",
    pole_pairs: Optional[int] = None,
    cogging_orders: Optional[Sequence[int]] = None,
    storage_options: Optional[Dict[str, str]] = None,
) -> Dict[str, Any]: ...
def multihead(
    names: List[str],
    readings: List[F64],
    nominal_deg: List[float],
    *,
    method: str = "joint",
    sets: Optional[List[List[str]]] = None,
    max_order: Optional[int] = None,
    points: Optional[int] = None,
    min_observability: float = 0.01,
) -> Dict[str, Any]: ...
def multihead_log(
    path: Any,
    names: List[str],
    nominal_deg: List[float],
    *,
    method: str = "joint",
    sets: Optional[List[List[str]]] = None,
    max_order: Optional[int] = None,
    points: Optional[int] = None,
    min_observability: float = 0.01,
    unit: Optional[str] = None,
    time: str = "header",
    max_gap: Optional[float] = None,
    time_column: Optional[str] = None,
    time_unit: Optional[str] = None,
    storage_options: Optional[Dict[str, str]] = None,
) -> Dict[str, Any]: ...
def shift_angle(
    path: str, *, method: str = "joint", faces: Optional[int] = None, budget: Optional[str] = None
) -> Dict[str, Any]: ...

# The options of each `*_log` function (its keywords, `path` left out) checked without a log:
# None, or UsageError naming the option (calib.map_logs calls them before sending any log).
def check_csrr_log(**options: Any) -> None: ...
def check_reference_log(**options: Any) -> None: ...
def check_tdr_log(**options: Any) -> None: ...
def check_multihead_log(names: List[str], nominal_deg: List[float], **options: Any) -> None: ...
