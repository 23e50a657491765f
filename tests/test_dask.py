"""abkit.dask on a real dask.distributed LocalCluster (two worker processes).

The claim under test is that the chunked, distributed computation equals the
in-memory ``filter.run`` bit for bit (the in-memory kernel is checked against
the independent NumPy reference in ``test_filters_compliance.py``; one case
here is also checked against that reference directly). Filters must pickle
to reach the workers: tested here too.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import abkit
from abkit import alphabeta, singer

from filterref import ab_model, run_ref

dask = pytest.importorskip("dask")
da = pytest.importorskip("dask.array")
distributed = pytest.importorskip("distributed")

from abkit import dask as adask  # noqa: E402


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None,
                                  worker_dashboard_address=None, silence_logs=40) as cluster:
        with distributed.Client(cluster) as c:
            yield c


def _eq(a, b) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)


def _z(shape, seed=0, dtype=np.float64, missed=0.1):
    rng = np.random.default_rng(seed)
    z = np.cumsum(rng.normal(size=shape), axis=-1 if len(shape) < 3 else 1).astype(dtype)
    z[rng.random(z.shape) < missed] = np.nan
    return z


FILTERS = {
    "ab": lambda: abkit.AlphaBetaFilter(0.5, 0.2, 0.5),
    "abg": lambda: abkit.AlphaBetaGammaFilter(0.5, 0.3, 0.05, 1.0),
    "design": lambda: abkit.AlphaBetaFilter.from_design(alphabeta.from_noise(1.0, 3.0, 0.1)),
    "singer": lambda: abkit.FixedGainFilter(singer.model(1.0, 10.0, 2.0)[0], [[1.0, 0.0, 0.0]],
                                            singer.steady_state(1.0, 10.0, 2.0, 5.0).K, 1.0),
}


# -- pickling ------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(FILTERS))
def test_filters_pickle_and_run_identically(name) -> None:
    f = FILTERS[name]()
    g = pickle.loads(pickle.dumps(f))
    assert type(g) is type(f) and repr(g) == repr(f)
    z = _z((4, 60), seed=1)
    a, b = f.run(z, return_residuals=True), g.run(z, return_residuals=True)
    assert _eq(a.states, b.states) and _eq(a.residuals, b.residuals)
    st = pickle.loads(pickle.dumps(a.state))
    assert np.array_equal(st.x, a.state.x) and np.array_equal(st.phase, a.state.phase)
    # the unpickled state continues the track exactly like the original
    z2 = _z((4, 30), seed=2)
    assert _eq(f.run(z2, state=st).states, f.run(z2, state=a.state).states)


def test_per_track_and_transient_filters_pickle() -> None:
    f = abkit.AlphaBetaFilter([0.3, 0.5, 0.7], [0.05, 0.2, 0.3], 1.0)
    g = pickle.loads(pickle.dumps(f))
    z = _z((3, 50), seed=3)
    assert _eq(f.run(z).states, g.run(z).states)
    np.testing.assert_array_equal(g.alpha, [0.3, 0.5, 0.7])
    k = abkit.AlphaBetaFilter.from_design(alphabeta.from_snr(0.1), T=1.0, transient="kalman")
    k2 = pickle.loads(pickle.dumps(k))
    assert _eq(k.run(z).states, k2.run(z).states)


def _misaligned_roundtrip(obj):
    """Pickle protocol 5 with out-of-band buffers (as dask.distributed sends
    arrays), each buffer handed back at an odd address."""
    bufs = []
    data = pickle.dumps(obj, protocol=5, buffer_callback=bufs.append)
    odd = [memoryview(bytearray(b"\0" + bytes(b.raw())))[1:] for b in bufs]
    return pickle.loads(data, buffers=odd)


@pytest.mark.parametrize("name", sorted(FILTERS) + ["transient"])
def test_filters_unpickled_from_misaligned_buffers_run(name) -> None:
    if name == "transient":
        f = abkit.AlphaBetaFilter.from_design(alphabeta.from_snr(0.1), T=1.0, transient="kalman")
    else:
        f = FILTERS[name]()
    bufs = []
    pickle.dumps(f, protocol=5, buffer_callback=bufs.append)
    assert bufs, "the filter's arrays should travel out of band"
    g = _misaligned_roundtrip(f)
    z = _z((3, 40), seed=11)
    assert _eq(f.run(z, return_residuals=True).states, g.run(z, return_residuals=True).states)


# -- run -------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(FILTERS))
@pytest.mark.parametrize("chunks", [(3, 17), (7, 200), (1, 41), (-1, 50)])
def test_run_equals_in_memory(client, name, chunks) -> None:
    f = FILTERS[name]()
    z = _z((7, 123), seed=4)
    want = f.run(z, return_residuals=True)
    got = adask.run(f, da.from_array(z, chunks=chunks), return_residuals=True)
    assert isinstance(got.states, da.Array) and got.states.chunks[1:] == da.from_array(z, chunks=chunks).chunks
    res = got.compute()
    assert _eq(res.states, want.states) and _eq(res.residuals, want.residuals)
    assert np.array_equal(res.state.x, want.state.x, equal_nan=True)
    assert np.array_equal(res.state.phase, want.state.phase)


def test_run_one_sample_chunks(client) -> None:
    f = FILTERS["abg"]()
    z = _z((2, 25), seed=12)
    want = f.run(z, return_residuals=True)
    res = adask.run(f, da.from_array(z, chunks=(1, 1)), return_residuals=True).compute()
    assert _eq(res.states, want.states) and _eq(res.residuals, want.residuals)


def test_run_matches_independent_reference(client) -> None:
    z = _z((5, 80), seed=5)
    ref_states, ref_res = run_ref(z, ab_model(0.5, 0.2, 0.5))[:2]
    got = adask.run(abkit.AlphaBetaFilter(0.5, 0.2, 0.5), da.from_array(z, chunks=(2, 13)), return_residuals=True).compute()
    np.testing.assert_allclose(got.states, ref_states, rtol=1e-12, atol=1e-12 * np.nanmax(np.abs(z)))
    np.testing.assert_allclose(got.residuals, ref_res, rtol=1e-12, atol=1e-12 * np.nanmax(np.abs(z)))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_run_single_track_and_dtypes(client, dtype) -> None:
    f = abkit.AlphaBetaFilter(0.4, 0.1, 1.0)
    z = _z((301,), seed=6, dtype=dtype)
    want = f.run(z, return_residuals=True)
    r = adask.run(f, da.from_array(z, chunks=40), return_residuals=True)
    assert r.states.dtype == dtype and r.states.shape == (2, 301)
    res = r.compute()
    assert _eq(res.states, want.states) and _eq(res.residuals, want.residuals)
    assert res.state.single


def test_run_vector_measurements(client) -> None:
    # position + velocity measured (m = 2): the trailing axis stays one chunk
    d = singer.steady_state(1.0, 10.0, 2.0, 5.0, 1.0)
    f = abkit.FixedGainFilter(singer.model(1.0, 10.0, 2.0)[0], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], d.K, 1.0)
    z = _z((4, 90, 2), seed=7)
    want = f.run(z, init="first", return_residuals=True)
    r = adask.run(f, da.from_array(z, chunks=(3, 25, 1)), init="first", return_residuals=True)
    res = r.compute()
    assert _eq(res.states, want.states) and _eq(res.residuals, want.residuals)


def test_run_state_and_init_array(client) -> None:
    f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    z = _z((6, 100), seed=8)
    x0 = np.column_stack([np.arange(6.0), np.ones(6)])
    want = f.run(z, init=x0)
    res = adask.run(f, da.from_array(z, chunks=(4, 30)), init=x0).compute()
    assert _eq(res.states, want.states)
    # continue from an in-memory state, and from a state computed on the cluster
    first = f.run(z[:, :40])
    want2 = f.run(z[:, 40:], state=first.state)
    got2 = adask.run(f, da.from_array(z[:, 40:], chunks=(4, 25)), state=first.state).compute()
    assert _eq(got2.states, want2.states)
    lazy = adask.run(f, da.from_array(z[:, :40], chunks=(5, 15)))
    st = lazy.state.compute()
    got3 = adask.run(f, da.from_array(z[:, 40:], chunks=(2, 60)), state=st).compute()
    assert _eq(got3.states, want2.states)


def test_run_is_lazy_and_parts_compute_separately(client) -> None:
    f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    z = _z((6, 100), seed=9)
    want = f.run(z)
    r = adask.run(f, da.from_array(z, chunks=(3, 30)))
    assert r.residuals is None
    assert _eq(r.position[2:5, 10:70].compute(), want.position[2:5, 10:70])
    assert _eq(r.velocity.compute(), want.velocity)
    states, st = dask.compute(r.states, r.state)
    assert _eq(states, want.states)
    with pytest.raises(AttributeError):
        r.acceleration


def test_run_bad_input() -> None:
    f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    z = da.zeros((4, 10), chunks=2)
    with pytest.raises(TypeError, match="filter"):
        adask.run(object(), z)
    with pytest.raises(TypeError, match="float32 or float64"):
        adask.run(f, da.zeros((4, 10), dtype=int))
    with pytest.raises(ValueError, match="out="):
        adask.run(f, z, out=np.empty((2, 4, 10)))
    with pytest.raises(ValueError, match="offsets="):
        adask.run(f, z, offsets=[0, 10])
    with pytest.raises(ValueError, match="sample axes"):
        adask.run(f, da.zeros((2, 3, 4, 5)))
    with pytest.raises(ValueError, match="init"):  # checked up front by the probe
        adask.run(f, z, init="nope")
    with pytest.raises(ValueError, match="state is for"):
        adask.run(f, z, state=f.run(np.zeros((3, 2))).state)
    with pytest.raises(TypeError, match=r"state must be a FilterState \(result.state\), got ndarray"):
        adask.run(f, z, state=np.zeros((4, 8)))
    g = abkit.AlphaBetaFilter([0.3, 0.5, 0.7, 0.5], 0.1, 1.0)
    with pytest.raises(ValueError, match="one chunk along the tracks"):
        adask.run(g, z)


def test_filter_frame_keyword_errors() -> None:
    dd = pytest.importorskip("dask.dataframe")
    ddf = dd.from_pandas(_long_frame(2), npartitions=2)
    with pytest.raises(TypeError, match="filter_frame\\(\\) missing the keyword argument 'filter'"):
        adask.filter_frame(ddf, id="id", columns="x")
    with pytest.raises(ValueError, match="return_summary is not available with Dask"):
        adask.filter_frame(ddf, id="id", columns="x", filter=abkit.AlphaBetaFilter(0.5, 0.2, 1.0), return_summary=True)


def test_per_track_parameters_in_one_track_chunk(client) -> None:
    g = abkit.AlphaBetaFilter([0.3, 0.5, 0.7, 0.5], 0.1, 1.0)
    z = _z((4, 64), seed=10)
    res = adask.run(g, da.from_array(z, chunks=(4, 20))).compute()
    assert _eq(res.states, g.run(z).states)


def test_doctests() -> None:
    import doctest

    res = doctest.testmod(adask, optionflags=doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS)
    assert res.failed == 0 and res.attempted > 0


# -- filter_frame -----------------------------------------------------------------------
def _long_frame(seed=0, n_tracks=12):
    pd = pytest.importorskip("pandas")
    rng = np.random.default_rng(seed)
    parts = []
    for i in range(n_tracks):
        n = int(rng.integers(1, 60))
        t = np.cumsum(rng.uniform(0.5, 2.0, n))
        x = np.cumsum(rng.normal(size=n))
        x[rng.random(n) < 0.1] = np.nan
        parts.append(pd.DataFrame({"id": f"s{i}", "t": t, "x": x, "y": rng.normal(size=n)}))
    df = pd.concat(parts).sample(frac=1.0, random_state=seed).reset_index(drop=True)
    df["row"] = np.arange(len(df))
    return df


def test_filter_frame_equals_in_memory(client) -> None:
    dd = pytest.importorskip("dask.dataframe")
    from abkit import frame

    df = _long_frame(1)
    f = abkit.AlphaBetaFilter.from_noise(0.5, 1.0, 1.0)
    want = frame.filter(df, id="id", time="t", columns=["x", "y"], filter=f)
    ddf = dd.from_pandas(df, npartitions=4).shuffle(on="id")
    out = adask.filter_frame(ddf, id="id", time="t", columns=["x", "y"], filter=f)
    assert list(out.columns) == list(want.columns)
    got = out.compute().sort_values("row").reset_index(drop=True)
    for c in want.columns:
        if c.endswith(("_pos", "_vel", "_res")):
            assert _eq(got[c].to_numpy(), want[c].to_numpy()), c


def test_filter_frame_indexed_by_id(client) -> None:
    dd = pytest.importorskip("dask.dataframe")
    from abkit import frame

    df = _long_frame(2)
    f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    want = frame.filter(df, id="id", time="t", columns="x", filter=f)
    ddf = dd.from_pandas(df, npartitions=3).set_index("id")
    assert ddf.known_divisions
    got = adask.filter_frame(ddf, id="id", time="t", columns="x", filter=f).compute()
    assert got.index.name == "id"
    got = got.sort_values("row")
    assert _eq(got["x_vel"].to_numpy(), want["x_vel"].to_numpy())


def test_filter_frame_track_split_across_partitions_raises(client) -> None:
    dd = pytest.importorskip("dask.dataframe")
    df = _long_frame(3)
    ddf = dd.from_pandas(df, npartitions=3)  # rows in random order: tracks span partitions
    out = adask.filter_frame(ddf, id="id", time="t", columns="x", filter=abkit.AlphaBetaFilter(0.5, 0.2, 1.0))
    with pytest.raises(ValueError, match=r"track id='s\d+' is in partitions \d and \d.*shuffle\(on='id'\)"):
        out.compute()
    with pytest.raises(ValueError, match="columns: no column 'z'"):
        adask.filter_frame(ddf, id="id", columns="z", filter=abkit.AlphaBetaFilter(0.5, 0.2, 1.0))
    with pytest.raises(ValueError, match="id: no column 'ship'"):
        adask.filter_frame(ddf, id="ship", columns="x", filter=abkit.AlphaBetaFilter(0.5, 0.2, 1.0))


def test_run_with_timestamps_axes_and_gaps(client) -> None:
    f = abkit.AlphaBetaFilter.from_noise(0.5, 2.0, 1.0)
    rng = np.random.default_rng(13)
    t = np.cumsum(rng.uniform(0.2, 3.0, (5, 120)), axis=1)
    t[2, 40] = t[2, 39]  # a duplicate, dropped
    z = _z((5, 120, 2), seed=13)
    kw = dict(axes=2, max_gap=2.5, on_duplicate="drop")
    want = f.run(z, t=t, return_residuals=True, **kw)
    assert want.n_restarts.sum() > 0 and want.n_dropped.sum() == 1
    r = adask.run(f, da.from_array(z, chunks=(2, 25, 1)), t=da.from_array(t, chunks=(5, 60)), return_residuals=True, **kw)
    assert r.states.shape == want.states.shape
    res = r.compute()
    assert _eq(res.states, want.states) and _eq(res.residuals, want.residuals)
    assert np.array_equal(res.state._packed, want.state._packed, equal_nan=True)
    with pytest.raises(ValueError, match="t must have the shape"):
        adask.run(f, da.from_array(z), t=t[:, :10], **kw)


def test_missing_dask_gives_install_advice() -> None:
    import subprocess
    import sys

    code = ("import sys; sys.modules['dask'] = None\n"
            "import numpy as np, abkit\n"
            "from abkit import dask as adask\n"
            "try:\n"
            "    adask.run(abkit.AlphaBetaFilter(0.5, 0.2, 1.0), np.zeros(3))\n"
            "except ImportError as e:\n"
            "    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "install abkit[dask]" in out.stdout
