# Hand-written stub of the Rust extension module abkit._abkit; checked by
# `python -m mypy.stubtest abkit._abkit` in CI.
import numpy as np
import numpy.typing as npt

__all__ = [
    "alphabeta_analyze",
    "alphabeta_error_covariance",
    "alphabeta_from_bandwidth",
    "alphabeta_from_natural_frequency",
    "alphabeta_from_noise",
    "alphabeta_from_snr",
    "alphabeta_from_tracking_error",
    "alphabeta_from_tracking_index",
    "riccati_kalman_steady_state",
    "riccati_solve_dare",
    "singer_model",
    "singer_steady_state",
    "ALPHABETA_FIELDS",
    "SINGER_ROW_WIDTH",
    "__version__",
]

__version__: str
ALPHABETA_FIELDS: list[str]
SINGER_ROW_WIDTH: int

_F64 = npt.NDArray[np.float64]

def alphabeta_from_snr(r: _F64) -> _F64: ...
def alphabeta_from_noise(sigma_w: _F64, sigma_v: _F64, T: _F64) -> _F64: ...
def alphabeta_from_tracking_index(lam: _F64) -> _F64: ...
def alphabeta_from_tracking_error(ratio: _F64) -> _F64: ...
def alphabeta_from_bandwidth(bn_t: _F64, damping: _F64) -> _F64: ...
def alphabeta_from_natural_frequency(omega_n: _F64, T: _F64, damping: _F64) -> _F64: ...
def alphabeta_analyze(alpha: _F64, beta: _F64) -> _F64: ...
def alphabeta_error_covariance(alpha: _F64, beta: _F64, r_true: _F64) -> _F64: ...
def riccati_solve_dare(
    a: _F64, b: _F64, q: _F64, r: _F64, s: _F64 | None = None
) -> tuple[_F64, _F64, float, float, int]: ...
def riccati_kalman_steady_state(
    f: _F64, h: _F64, q: _F64, r: _F64
) -> tuple[_F64, _F64, _F64, _F64, _F64, float]: ...
def singer_model(T: _F64, tau: _F64, q: _F64) -> _F64: ...
def singer_steady_state(theta: _F64, qn: _F64, rv: _F64, method: _F64) -> _F64: ...
