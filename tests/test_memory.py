"""Peak memory of filtering: with the input and output already in memory, a
run may add at most 64 MiB beyond its other output, the final per-track
state (``result.state``, ``abkit._abkit.STATE_WIDTH`` float64 per track, and
the per-track counts ``n_dropped``/``n_restarts``, 2 int64 per track) (issue: peak RSS <= input +
output + 64 MiB). Measured in a subprocess from /proc (VmHWM), Linux only."""

from __future__ import annotations

import subprocess
import sys

import pytest

SCRIPT = r"""
import numpy as np, abkit
def rss(key):
    for line in open('/proc/self/status'):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
shape = {shape}
z = np.random.default_rng(0).normal(size=shape)
z[:, ::97] = np.nan
f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
out = np.empty((2,) + shape)
out.fill(0.0)
f.run(z[:1, :10])  # load everything, start the pool
before = rss('VmRSS')
f.run(z, out=out)
f.run(z, out=out, threads=1)
g = abkit.FixedGainFilter([[1, 1], [0, 1]], [[1, 0]], [[0.5], [0.2]])
g.run(z, out=out)
peak = rss('VmHWM')
per_track = 8 * int(abkit._abkit.STATE_WIDTH) + 16  # one FilterState + the two int64 counts
print((peak - before - shape[0] * per_track) / 2**20)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("shape", [(2_000_000, 8), (8, 2_000_000), (1, 16_000_000)])
def test_run_adds_at_most_64_mib(shape):
    out = subprocess.run([sys.executable, "-c", SCRIPT.format(shape=shape)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    extra = float(out.stdout.strip().splitlines()[-1])
    assert extra <= 64.0, f"run added {extra:.1f} MiB over input + output"
