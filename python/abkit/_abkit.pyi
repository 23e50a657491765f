# Hand-written stub of the Rust extension module abkit._abkit; checked by
# `python -m mypy.stubtest abkit._abkit` in CI.
import numpy as np
import numpy.typing as npt

__all__ = [
    "abg_analyze",
    "abg_backward_gain",
    "abg_backward_gain_noise",
    "abg_coloured",
    "abg_coloured_from_noise",
    "abg_conditions",
    "abg_decoupled",
    "abg_from_noise",
    "abg_from_tracking_index",
    "abg_jury",
    "abg_noise_ratios",
    "alphabeta_analyze",
    "alphabeta_error_covariance",
    "alphabeta_from_bandwidth",
    "alphabeta_from_natural_frequency",
    "alphabeta_from_noise",
    "alphabeta_from_snr",
    "alphabeta_from_tracking_error",
    "alphabeta_from_tracking_index",
    "filter_alphabeta",
    "filter_fixed_gain",
    "plane_stride",
    "prefault",
    "kalman_gain_sequence",
    "kalman_run",
    "riccati_kalman_steady_state",
    "riccati_solve_dare",
    "singer_model",
    "singer_steady_state",
    "ABG_COLOURED_FIELDS",
    "ABG_DECOUPLED_WIDTH",
    "ABG_FIELDS",
    "ALPHABETA_FIELDS",
    "SINGER_ROW_WIDTH",
    "STATE_WIDTH",
    "MAX_STATES",
    "PAD_MIN_BYTES",
    "filter_tracks",
    "filter_tracks_f32",
    "filter_feed",
    "time_order",
    "__version__",
]

__version__: str
ABG_FIELDS: list[str]
ABG_COLOURED_FIELDS: list[str]
ABG_DECOUPLED_WIDTH: int
ALPHABETA_FIELDS: list[str]
STATE_WIDTH: int
MAX_STATES: int
PAD_MIN_BYTES: int
SINGER_ROW_WIDTH: int

_F64 = npt.NDArray[np.float64]

def abg_from_noise(sigma_p: _F64, sigma_v: _F64, sigma_a: _F64, sigma_m: _F64, h: _F64) -> _F64: ...
def abg_backward_gain_noise(sigma_p: _F64, sigma_v: _F64, sigma_a: _F64, sigma_m: _F64, h: _F64) -> _F64: ...
def abg_backward_gain(alpha: _F64, beta: _F64, gamma: _F64) -> _F64: ...
def abg_from_tracking_index(lam: _F64, continuous: bool) -> _F64: ...
def abg_jury(alpha: _F64, beta: _F64, gamma: _F64) -> _F64: ...
def abg_noise_ratios(alpha: _F64, beta: _F64, gamma: _F64, h: _F64) -> _F64: ...
def abg_conditions(alpha: _F64, beta: _F64, gamma: _F64) -> _F64: ...
def abg_analyze(alpha: _F64, beta: _F64, gamma: _F64) -> _F64: ...
def abg_coloured(alpha: _F64, beta: _F64, gamma: _F64, theta: _F64, r: _F64, h: _F64) -> _F64: ...
def abg_coloured_from_noise(sigma_p: _F64, sigma_v: _F64, sigma_a: _F64, sigma_m: _F64, r: _F64, h: _F64) -> _F64: ...
def abg_decoupled(alpha: _F64, beta: _F64, gamma: _F64, theta: _F64, r: _F64, h: _F64) -> _F64: ...

def alphabeta_from_snr(r: _F64) -> _F64: ...
def alphabeta_from_noise(sigma_w: _F64, sigma_v: _F64, T: _F64) -> _F64: ...
def alphabeta_from_tracking_index(lam: _F64) -> _F64: ...
def alphabeta_from_tracking_error(ratio: _F64) -> _F64: ...
def alphabeta_from_bandwidth(bn_t: _F64, damping: _F64) -> _F64: ...
def alphabeta_from_natural_frequency(omega_n: _F64, T: _F64, damping: _F64) -> _F64: ...
def alphabeta_analyze(alpha: _F64, beta: _F64) -> _F64: ...
def alphabeta_error_covariance(alpha: _F64, beta: _F64, r_true: _F64) -> _F64: ...

_FArr = npt.NDArray[np.float32] | npt.NDArray[np.float64]

def filter_alphabeta(
    z: _FArr,
    params: _F64,
    init: str,
    state: _F64,
    out: _FArr,
    resid: _FArr | None = None,
    threads: int | None = None,
    smoother_gain: _F64 | None = None,
    lag: int | None = None,
    f32_arith: bool = False,
) -> bool: ...
def filter_fixed_gain(
    z: _FArr,
    n: int,
    m: int,
    phi: _F64,
    h: _F64,
    k: _F64,
    h_pinv: _F64,
    t: _F64,
    init: str,
    state: _F64,
    out: _FArr,
    resid: _FArr | None = None,
    threads: int | None = None,
    smoother_gain: _F64 | None = None,
    lag: int | None = None,
) -> bool: ...
def filter_feed(
    zs: list[_FArr],
    t: _F64 | None,
    codes: npt.NDArray[np.int64],
    n: int,
    law: str,
    params: _F64,
    h: _F64,
    h_pinv: _F64,
    t_nominal: float,
    init: str,
    max_gap: float | None,
    drop_duplicates: bool,
    state: _F64,
    out: _FArr,
    counts: npt.NDArray[np.int64],
    rows: npt.NDArray[np.int64],
    resid: _FArr | None = None,
    threads: int | None = None,
) -> None: ...
def plane_stride(n: int, per: int, row: int, itemsize: int) -> int: ...
def prefault(buf: npt.NDArray[np.uint8], threads: int | None = None) -> None: ...
def time_order(t: _F64, threads: int | None = None) -> npt.NDArray[np.int64]: ...
def filter_tracks(
    z: _FArr,
    t: _F64 | None,
    offsets: npt.NDArray[np.int64],
    n: int,
    m: int,
    law: str,
    params: _F64,
    h: _F64,
    h_pinv: _F64,
    t_nominal: float,
    init: str,
    max_gap: float | None,
    drop_duplicates: bool,
    state: _F64,
    out: _FArr,
    counts: npt.NDArray[np.int64],
    resid: _FArr | None = None,
    threads: int | None = None,
    smoother: str | None = None,  # None, "const" (Phi | A rows), "ab" (rows of 5), "kin3" (rows of 10)
    smoother_params: _F64 | None = None,
    lag: int | None = None,
) -> bool: ...  # whether some started track's final state is not finite
def filter_tracks_f32(
    z: npt.NDArray[np.float32],
    offsets: npt.NDArray[np.int64],
    params: _F64,
    init: str,
    state: _F64,
    out: npt.NDArray[np.float32],
    resid: npt.NDArray[np.float32] | None = None,
    threads: int | None = None,
) -> bool: ...  # float32 arithmetic, alpha-beta, no timestamps
def kalman_gain_sequence(
    n: int, m: int, phi: _F64, h: _F64, q: _F64, r: _F64, p0: _F64, steps: int
) -> tuple[_F64, _F64, _F64]: ...
def kalman_run(
    z: _FArr,
    n: int,
    m: int,
    phi: _F64,
    h: _F64,
    q: _F64,
    r: _F64,
    x0: _F64,
    p0: _F64,
    out: _FArr,
    p_final: _F64,
    resid: _FArr | None = None,
    threads: int | None = None,
) -> None: ...
def riccati_solve_dare(
    a: _F64, b: _F64, q: _F64, r: _F64, s: _F64 | None = None
) -> tuple[_F64, _F64, float, float, int]: ...
def riccati_kalman_steady_state(
    f: _F64, h: _F64, q: _F64, r: _F64
) -> tuple[_F64, _F64, _F64, _F64, _F64, float]: ...
def singer_model(T: _F64, tau: _F64, q: _F64) -> _F64: ...
def singer_steady_state(theta: _F64, qn: _F64, rv: _F64, method: _F64) -> _F64: ...
