"""abkit.FeedTracker: a live feed of interleaved reports, batch by batch.

Every case is compared, bit for bit, with each track run alone over all its
reports through ``filter.run(z, t=t, ...)`` (the ragged kernel, itself
checked against independent references in test_tracks_irregular.py), for
random batchings of the feed, new ids appearing in later batches, missed
detections, duplicates, gaps, 1 and 2 axes and float32.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest

import abkit
from abkit import FeedTracker

FILTERS = {
    "ab-design": lambda: abkit.AlphaBetaFilter.from_noise(0.3, 2.0, 1.0),
    "ab-fixed": lambda: abkit.AlphaBetaFilter(0.5, 0.2, 1.0),
    "abg-fixed": lambda: abkit.AlphaBetaGammaFilter(0.5, 0.3, 0.05, 1.0),
    "singer": lambda: abkit.singer.tracking_filter(1.0, tau=20.0, sigma_m=0.5, sigma_pos=2.0),
}


def make_feed(seed, n=900, n_ids=15, d=1, dup=False, dtype=np.float64):
    """Reports in time order; track j appears from report ~60 j on."""
    rng = np.random.default_rng(seed)
    born = np.arange(n_ids) * (n // (2 * n_ids))
    ids = np.empty(n, dtype=object)
    for r in range(n):
        alive = np.flatnonzero(born <= r)
        ids[r] = f"trk{int(rng.choice(alive)) * 13 % 97}"
    steps = rng.exponential(0.4, n)
    steps[rng.random(n) < 0.15] = 0.0  # simultaneous reports
    t = 10.0 + np.cumsum(steps)
    if not dup:  # no repeated time within a track
        last = {}
        for r in range(n):
            if ids[r] in last and t[r] <= last[ids[r]]:
                t[r:] += 1e-3
            last[ids[r]] = t[r]
    base = np.array([zlib.crc32(v.encode()) % 1000 for v in ids], dtype=float)  # per-track offset
    z = (3.0 * t + base)[:, None] + rng.normal(0, 1.0, (n, d)) * np.arange(1, d + 1)
    z[rng.random((n, d)) < 0.08] = np.nan
    return ids, t, z.astype(dtype) if d > 1 else z[:, 0].astype(dtype)


def per_track(f, ids, t, z, **kw):
    """Each track alone over all its reports: states (n, N[, d]), residuals,
    counts per id, final states."""
    n_s = f.n
    states = np.full((n_s,) + z.shape, np.nan, dtype=z.dtype)
    res = np.full(z.shape, np.nan, dtype=z.dtype)
    counts, last = {}, {}
    for v in dict.fromkeys(ids):
        rows = np.flatnonzero(ids == v)
        zz = z[rows]
        axes = {} if z.ndim == 1 else {"axes": z.shape[1]}
        # (without t: the track kernel too, through offsets; the rectangular
        # batch kernel of a 3-state filter rounds differently, ~1 ulp)
        timing = {"offsets": np.array([0, rows.size])} if t is None else {"t": t[rows]}
        r = f.run(zz, return_residuals=True, **timing, **axes, **kw)
        states[:, rows] = r.states
        res[rows] = r.residuals
        counts[v] = (int(r.n_dropped.sum()), int(r.n_restarts.sum()))
        last[v] = r.state
    return states, res, counts, last


def run_batches(trk, ids, t, z, cuts):
    parts = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        parts.append(trk.update(ids[a:b], None if t is None else t[a:b], z[a:b]))
    states = np.concatenate([p.states for p in parts], axis=1)
    res = np.concatenate([p.residuals for p in parts], axis=0)
    return states, res


@pytest.mark.parametrize("name", list(FILTERS))
@pytest.mark.parametrize("d", [1, 2])
@pytest.mark.parametrize("opts", [{}, {"max_gap": 1.5, "on_duplicate": "drop"}, {"init": "first"}])
def test_batches_equal_each_track_alone(name, d, opts):
    f = FILTERS[name]()
    ids, t, z = make_feed(seed=d + 3 * len(opts) + len(name), d=d, dup="on_duplicate" in opts)
    want, want_res, counts, _ = per_track(f, ids, t, z, **opts)
    rng = np.random.default_rng(1)
    for cuts in ([0, len(ids)], [0, 1, 2, 50, 51, 400, len(ids)],
                 np.unique(np.r_[0, rng.integers(0, len(ids), 25), len(ids)])):
        trk = FeedTracker(f, axes=d, **opts)
        got, res = run_batches(trk, ids, t, z, list(cuts))
        assert np.array_equal(got, want, equal_nan=True)
        assert np.array_equal(res, want_res, equal_nan=True)
        assert trk.ids == list(dict.fromkeys(ids))
        assert [tuple(c) for c in zip(trk.n_dropped, trk.n_restarts)] == [counts[v] for v in trk.ids]
    if "max_gap" in opts:
        assert trk.n_restarts.sum() > 0 and trk.n_dropped.sum() > 0


@pytest.mark.parametrize("d", [1, 3])
def test_float32_and_no_timestamps(d):
    f = FILTERS["abg-fixed"]()
    ids, _, z = make_feed(seed=9, d=d, dtype=np.float32)
    want, want_res, _, last = per_track(f, ids, None, z)
    trk = FeedTracker(f, axes=d)
    got, res = run_batches(trk, ids, None, z, [0, 100, 101, 700, len(ids)])
    assert got.dtype == np.float32
    assert np.array_equal(got, want, equal_nan=True) and np.array_equal(res, want_res, equal_nan=True)
    for v in trk.ids[:5]:  # the running estimate = the track's final state
        x = trk.estimate(v)
        ref = last[v].x if d == 1 else last[v].x.reshape(d, -1) if last[v].x.ndim == 1 else last[v].x
        assert np.array_equal(np.asarray(x), np.asarray(ref).reshape(np.shape(x)), equal_nan=True)


def test_failed_batch_changes_nothing():
    f = FILTERS["ab-design"]()
    ids, t, z = make_feed(seed=4)
    trk, ref = FeedTracker(f), FeedTracker(f)
    trk.update(ids[:300], t[:300], z[:300])
    ref.update(ids[:300], t[:300], z[:300])
    # a batch with a new id and then a report that goes back in time
    bad_ids = np.array(["newcomer", ids[10], ids[299]], dtype=object)
    bad_t = np.array([t[299] + 1, t[299] + 1, t[299] - 5.0])
    with pytest.raises(ValueError, match=rf"row 2 \(id {ids[299]!r}\): t=.* not after"):
        trk.update(bad_ids, bad_t, np.array([1.0, 2.0, 3.0]))
    assert trk.ids == ref.ids and "newcomer" not in trk.ids
    a = trk.update(ids[300:], t[300:], z[300:])
    b = ref.update(ids[300:], t[300:], z[300:])
    assert np.array_equal(a.states, b.states, equal_nan=True)
    assert np.array_equal(trk.n_dropped, ref.n_dropped) and trk.ids == ref.ids


def test_forget_starts_the_id_again():
    f = FILTERS["ab-fixed"]()
    trk = FeedTracker(f)
    trk.update(["a", "b", "a", "b"], [0.0, 0.0, 1.0, 1.0], [0.0, 5.0, 1.0, 6.0])
    trk.forget(["a"])
    assert trk.ids == ["b"]
    r = trk.update(["a", "b", "a"], [5.0, 2.0, 6.0], [50.0, 7.0, 52.0])
    alone = f.run(np.array([50.0, 52.0]), t=np.array([5.0, 6.0]))
    assert np.array_equal(r.states[:, [0, 2]], alone.states, equal_nan=True)
    assert trk.ids == ["b", "a"]
    with pytest.raises(KeyError, match="'zz'"):
        trk.forget("zz")


def test_bad_input():
    f = FILTERS["ab-fixed"]()
    trk = FeedTracker(f)
    with pytest.raises(ValueError, match="ids must be a 1-D"):
        trk.update(["a", "b"], [0.0, 1.0, 2.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="t must have the sample shape"):
        trk.update(["a", "b", "c"], [0.0, 1.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"t: row 1 .* is NaN"):
        trk.update(["a", "b"], [0.0, np.nan], [1.0, 2.0])
    assert trk.ids == []  # nothing registered by a rejected batch
    with pytest.raises(ValueError, match="z must have shape"):
        trk.update(["a"], [0.0], [[1.0, 2.0]])
    with pytest.raises(ValueError, match="row 0 .*z must be finite"):
        trk.update(["a"], [0.0], [np.inf])
    with pytest.raises(TypeError, match="float32 or float64"):
        trk.update(["a"], [0.0], np.array(["x"]))
    trk.update(["a"], [0.0], np.array([1.0]))
    with pytest.raises(TypeError, match="first batch"):
        trk.update(["a"], [1.0], np.array([1.0], dtype=np.float32))
    with pytest.raises(ValueError, match="missing id"):
        trk.update(np.array([1.0, np.nan]), [2.0, 3.0], [1.0, 2.0])
    with pytest.raises(ValueError, match="axes must be"):
        FeedTracker(f, axes=0)
    with pytest.raises(ValueError, match="scalar-measurement"):
        FeedTracker(abkit.FixedGainFilter(np.eye(2), np.eye(2), 0.5 * np.eye(2)))
    with pytest.raises(TypeError, match="abkit filter"):
        FeedTracker("ab")
    with pytest.raises(ValueError, match="max_gap must be > 0"):
        FeedTracker(f, max_gap=0.0)
