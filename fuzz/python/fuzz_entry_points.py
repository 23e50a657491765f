"""atheris fuzzing of abkit's Python entry points (issue 8).

Every input picks an entry point of the validation table
(tests/test_validation_table.py) and replaces one of its arguments by a value
built from the fuzzer's bytes: any dtype, shape, stride pattern, special
values (NaN, +-Inf, 0, 1e+-300, subnormals), Python scalars, lists, None or
strings. The only acceptable outcomes are a result, or ``ValueError``
(including ``numpy.linalg.LinAlgError``) or ``TypeError``; anything else
(``RuntimeError`` from a caught Rust panic, ``IndexError``, ``ZeroDivisionError``,
a crash) is a bug and stops the fuzzer with the input saved.

    pip install atheris
    python fuzz/python/fuzz_entry_points.py -max_total_time=600 fuzz/python/corpus
    # replay the corpus only (no fuzzing), as CI does:
    python fuzz/python/fuzz_entry_points.py -runs=0 fuzz/python/corpus
"""

from __future__ import annotations

import os
import sys
import warnings

import atheris

with atheris.instrument_imports():
    import numpy as np

    import abkit  # noqa: F401

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests"))
import test_validation_table as table  # noqa: E402



def _available(e) -> bool:
    """False for an entry whose optional dependency (pandas, polars, dask) is
    not installed here: its clean call is skipped by the table."""
    import pytest

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            e.call(**dict(e.args))
    except pytest.skip.Exception:
        return False
    except Exception:  # the table's own tests report clean-call failures
        return True
    return True


ENTRIES = [e for e in table.ENTRIES if e.roles and e.name not in table.FIGURES and _available(e)]
SPECIAL = [np.nan, np.inf, -np.inf, 0.0, -0.0, 1e300, -1e300, 1e-300, 5e-324, 1.0, -1.0, 0.5, 2.0]
DTYPES = [np.float64, np.float32, np.float16, ">f8", np.int64, np.int8, np.uint8, bool, np.complex128, object]


def _value(fdp: atheris.FuzzedDataProvider, template: np.ndarray):
    kind = fdp.ConsumeIntInRange(0, 9)
    if kind == 0:
        return None
    if kind == 1:
        return fdp.ConsumeUnicodeNoSurrogates(4)
    if kind == 2:
        return fdp.PickValueInList(SPECIAL)
    if kind == 3:
        return [fdp.PickValueInList(SPECIAL) for _ in range(fdp.ConsumeIntInRange(0, 4))]
    # an array: the template's shape or a mutated one, values special or raw
    shape = list(template.shape)
    if fdp.ConsumeBool() and shape:
        shape[fdp.ConsumeIntInRange(0, len(shape) - 1)] = fdp.ConsumeIntInRange(0, 5)
    if fdp.ConsumeIntInRange(0, 7) == 0:
        shape = [fdp.ConsumeIntInRange(0, 3) for _ in range(fdp.ConsumeIntInRange(0, 4))]
    n = int(np.prod(shape)) if shape else 1
    if fdp.ConsumeBool():
        vals = np.array([fdp.PickValueInList(SPECIAL) for _ in range(n)], dtype=np.float64)
    else:
        vals = np.array(fdp.ConsumeFloatListInRange(n, -1e6, 1e6) + [0.0] * n, dtype=np.float64)[:n]
    if fdp.ConsumeBool() and n == template.size:
        vals = np.where(np.arange(n) % 3 == 0, vals, template.reshape(-1)) if template.size else vals
    arr = vals.reshape(shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        arr = arr.astype(fdp.PickValueInList(DTYPES))
    layout = fdp.ConsumeIntInRange(0, 4)
    if layout == 1 and arr.ndim:
        arr = np.flip(arr.copy(), axis=-1)[..., ::-1]
    elif layout == 2 and arr.ndim and arr.size:
        arr = np.broadcast_to(arr.reshape(-1)[:1].reshape((1,) * arr.ndim), arr.shape)
    elif layout == 3 and arr.ndim:
        big = np.repeat(arr, 2, axis=-1)
        arr = big[..., ::2]
    elif layout == 4:
        arr = arr.copy()
        arr.flags.writeable = False
    return arr


def TestOneInput(data: bytes) -> None:
    fdp = atheris.FuzzedDataProvider(data)
    e = ENTRIES[fdp.ConsumeIntInRange(0, len(ENTRIES) - 1)]
    args = dict(e.args)
    for _ in range(fdp.ConsumeIntInRange(1, 2)):
        name = fdp.PickValueInList(sorted(e.roles))
        args[name] = _value(fdp, np.asarray(e.args[name]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            e.call(**args)
        except (ValueError, TypeError):
            pass


def main() -> None:
    atheris.Setup(sys.argv, TestOneInput)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
