"""The log a chunk at a time (components.estimation.chunks): the estimates, their σ and the
diagnosis built chunk by chunk equal the whole-log ones to 1e-9 relative (issue #18's bound),
and the cuts are where the module says they may be — checked here from the blocks themselves."""
from __future__ import annotations

import copy
import tomllib
from dataclasses import replace

import numpy as np
import pytest
from forked_chunks import send_chunks_to_workers

from components.cli.demo import SCENARIO
from components.diagnosis.compare import compare
from components.diagnosis.diagnose import diagnose
from components.estimation import chunks
from components.estimation.chunks import BlockLayout
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.model.effects import DEFAULT_EFFECTS
from components.model.result import result_from_fit
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

SMALL = 5000  # samples per chunk: the demo's 60k-sample log in a dozen chunks


@pytest.fixture(scope="module")
def data():
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["scenario"]["seed"] = 31
    return LogData.from_log(run_scenario(scenario_from_dict(d, source="test_chunks"), progress=False).log)


def _same(a, b, what):
    rel = np.abs(np.asarray(a) - np.asarray(b)) / np.maximum(np.abs(np.asarray(a)), 1e-300)
    assert rel.max() <= 1e-9, (what, float(rel.max()))


def _same_fit(whole, chunked):
    assert whole.parameters == chunked.parameters
    _same(whole.value, chunked.value, "values")
    _same(whole.sigma, chunked.sigma, "sigma")
    _same(whole.chi2, chunked.chi2, "chi2")


def test_cuts_fall_between_two_rests_and_between_blocks(data):
    layout = BlockLayout.of(data, 200, SMALL)
    static = data.static
    cuts = layout.cuts
    assert cuts[0] == 0 and len(cuts) >= 6 and np.all(np.diff(cuts) >= SMALL)
    for c in cuts[1:]:
        assert static[c - 1] and static[c]
        for blocks in (layout.gyro, layout.acc):
            assert not np.any((blocks.start < c) & (blocks.stop > c)), c
    # every block lies in exactly one chunk
    for blocks in (layout.gyro, layout.acc):
        chunk_of_start = np.searchsorted(cuts, blocks.start, side="right")
        chunk_of_last = np.searchsorted(cuts, blocks.stop - 1, side="right")
        assert np.array_equal(chunk_of_start, chunk_of_last)


@pytest.mark.parametrize("extra", [[], ["gyro.drift", "acc.sf_temp", "acc.k2"],
                                   ["acc.lever", "imu.time_offset"], ["table.wobble", "table.nonorth"]])
def test_calibrate_in_chunks_equals_the_whole_log(data, extra):
    effects = list(DEFAULT_EFFECTS) + extra
    _same_fit(calibrate(data, effects), calibrate(data, effects, chunk_samples=SMALL))


def test_estimated_rest_angles_and_left_out_samples_in_chunks(data):
    # angles in encoder counts of a stated 2^-20 rev: the rest-angle σ is estimated from the
    # moves' residuals (components.estimation.lsq._estimate_rest_sigma), a whole-log statistic
    q = 2 * np.pi / 2**20
    counted = replace(data, angles=np.round(data.angles / q) * q, encoder_resolution=[q] * 3, _profiles={})
    valid = np.ones(len(data.time), bool)
    valid[20000:26000] = False  # a stretch left out across several chunks
    counted = replace(counted, valid=valid)
    whole = calibrate(counted, DEFAULT_EFFECTS)
    chunked = calibrate(counted, DEFAULT_EFFECTS, chunk_samples=SMALL)
    _same_fit(whole, chunked)
    _same(whole.rest_sigma, chunked.rest_sigma, "rest sigma")


def test_diagnose_in_chunks_equals_the_whole_log(data):
    model = result_from_fit(calibrate(data, DEFAULT_EFFECTS), DEFAULT_EFFECTS, data)
    whole = diagnose(data, model, candidates=["acc.k2", "acc.k3", "gyro.drift", "table.wobble"])
    chunked = diagnose(data, model, candidates=["acc.k2", "acc.k3", "gyro.drift", "table.wobble"],
                       chunk_samples=SMALL)
    assert whole.verdict == chunked.verdict == "acc.k2" and whole.found == chunked.found
    _same(whole.base_chi2_per_dof, chunked.base_chi2_per_dof, "chi2/dof")
    for a, b in zip(whole.ranking, chunked.ranking):
        assert a.effect == b.effect
        _same(a.statistic, b.statistic, a.effect)


def test_compare_in_chunks_equals_the_whole_log(data):
    effects = list(DEFAULT_EFFECTS) + ["gyro.drift", "acc.sf_temp"]
    model = result_from_fit(calibrate(data, effects), effects, data)
    whole = compare(data, model, fitted_parameters=len(model.values))
    chunked = compare(data, model, fitted_parameters=len(model.values), chunk_samples=SMALL)
    assert np.array_equal(whole.static, chunked.static)
    # the per-sample prediction, the block statistics and where the misfit is
    assert np.max(np.abs(whole.predicted - chunked.predicted)) <= 1e-9 * np.max(np.abs(whole.predicted))
    _same(whole.chi2, chunked.chi2, "chi2")
    assert whole.conditions.keys() == chunked.conditions.keys()
    for name, values in whole.conditions.items():
        _same([v or 0.0 for v in values], [v or 0.0 for v in chunked.conditions[name]], name)


def test_attitudes_are_numpys_unique_rows():
    """interpolate_angles' distinct rest attitudes (angles and the sides they were reached from),
    made unique over the changes only, are exactly np.unique's rows and inverse over every static
    sample (static as interpolate_angles has it: the angles of the sample before, the first
    sample at rest; the sides may change between two static samples)."""
    from components.model.motion import _attitudes

    rng = np.random.default_rng(5)
    for _ in range(300):
        n, m = int(rng.integers(1, 80)), int(rng.integers(1, 4))
        repeat = rng.integers(1, 4, size=n)
        angles = np.repeat(rng.integers(0, 3, size=(n, m)).astype(float), repeat, axis=0)
        sides = np.repeat(rng.integers(-1, 2, size=(n, m)).astype(np.int8), repeat, axis=0)
        static = np.r_[True, np.all(angles[1:] == angles[:-1], axis=1)]
        att, att_sides, inv = _attitudes(angles, static, sides)
        if static.any():
            ref, ref_inv = np.unique(np.hstack([angles[static], sides[static]]), axis=0, return_inverse=True)
            assert np.array_equal(att, ref[:, :m]) and np.array_equal(att_sides, ref[:, m:])
            assert np.array_equal(inv, ref_inv.ravel())
        else:
            assert len(att) == 0 and len(inv) == 0


def test_rows_equal_to_the_row_before_are_numpys_all():
    """same_as_before: row k + 1 equals row k in every column, as np.all over the row gives it
    (NaN equal to nothing, no columns: equal), into a given array too."""
    from components.model.motion import same_as_before

    rng = np.random.default_rng(8)
    for m in (0, 1, 3):
        rows = np.repeat(rng.integers(0, 2, size=(300, m)).astype(float), rng.integers(1, 3, size=300), axis=0)
        if m:
            rows[rng.integers(0, len(rows), 10), rng.integers(0, m, 10)] = np.nan
        want = np.all(rows[1:] == rows[:-1], axis=1)
        assert np.array_equal(same_as_before(rows), want)
        out = np.zeros(len(rows) - 1, bool)
        assert same_as_before(rows, out=out) is out and np.array_equal(out, want)
    assert same_as_before(np.zeros((0, 3))).shape == (0,)


def test_a_jittered_clock_and_pulse_counts_in_chunks(data):
    """Foreign logs: sample times with a logger's jitter (each interval its own, 50 us RMS at
    200 Hz) and outputs quantised to pulse counts (1e-6 rad, 1e-5 m/s): the chunks still give the
    whole log's estimates (each stretch keeps its own first interval and the whole log's origin)."""
    rng = np.random.default_rng(7)
    t = data.time + rng.normal(0.0, 50e-6, len(data.time))
    t = np.maximum.accumulate(t + np.arange(len(t)) * 1e-12)
    counted = replace(data, time=t, gyro=np.round(data.gyro / 1e-6) * 1e-6, acc=np.round(data.acc / 1e-5) * 1e-5,
                      count_weight=(1e-6, 1e-5), _profiles={})
    effects = list(DEFAULT_EFFECTS) + ["gyro.drift", "table.wobble"]
    _same_fit(calibrate(counted, effects), calibrate(counted, effects, chunk_samples=SMALL))


def test_ideal_increments_are_the_motions(data):
    """The table columns' fast path (rests by attitude, moving samples node by node) gives the
    full Motion's quadrature integrals of rate and specific force."""
    from components.model.motion import ideal_increments

    motion = data.motion(data.geometry)
    gyro, acc = ideal_increments(data.angle_profile(3), data.geometry)
    assert np.max(np.abs(gyro - motion.ideal_gyro)) <= 1e-13 * np.max(np.abs(motion.ideal_gyro))
    assert np.max(np.abs(acc - motion.ideal_acc)) <= 1e-13 * np.max(np.abs(motion.ideal_acc))


def test_chunks_on_two_processes_give_the_same_bits(data, monkeypatch):
    """The chunk work on forked worker processes (CALBENCH_WORKERS): every estimate, σ and
    statistic is the same bits as on one process, in the same order."""
    effects = list(DEFAULT_EFFECTS) + ["acc.k2"]
    fits, diags = [], []
    for workers in ("1", "2"):
        with pytest.MonkeyPatch.context() as mp:
            mp.setenv("CALBENCH_WORKERS", "1")
            pools = send_chunks_to_workers(mp) if workers == "2" else None
            fits.append(calibrate(data, effects, chunk_samples=SMALL))
            model = result_from_fit(fits[-1], effects, data)
            diags.append(diagnose(data, model, forward=False, chunk_samples=SMALL))
    assert pools.started >= 2  # the fit's and the diagnosis' chunks did go to workers
    assert np.array_equal(fits[0].value, fits[1].value)
    assert np.array_equal(fits[0].covariance, fits[1].covariance)
    assert [(c.effect, c.statistic) for c in diags[0].ranking] == [(c.effect, c.statistic) for c in diags[1].ranking]


@pytest.mark.parametrize("workers", ["1", "2"])
def test_the_rows_held_at_once_are_a_chunks_not_the_logs(data, monkeypatch, workers):
    """chunked_design into a spilled array: the memory this process allocates at its peak is a
    few chunks' rows, not the log's (each chunk's rows go into place as they come; on two
    processes the results were once all listed before any was put in place, and the stretches
    of every chunk made up front), while the rows equal those built in memory."""
    import tracemalloc

    from components.diagnosis.compare import model_geometry
    from components.estimation.chunks import chunked_design
    from components.model.effects import parameters_of

    pools = send_chunks_to_workers(monkeypatch) if workers == "2" else None
    if pools is None:
        monkeypatch.setenv("CALBENCH_WORKERS", "1")
    model = result_from_fit(calibrate(data, list(DEFAULT_EFFECTS)), list(DEFAULT_EFFECTS), data)
    params = parameters_of(list(DEFAULT_EFFECTS) + ["acc.k2", "acc.k3", "acc.temp", "gyro.drift", "acc.drift"])
    layout = BlockLayout.of(data, 4, 2000)  # short blocks: many rows a sample, as an 8-hour log has many samples
    geo = model_geometry(data, model)
    args = (data, layout, params, np.full(3, 1e-6), np.full(3, 1e-5), np.zeros(3), geo, [], None)
    y, H, w, rows = chunked_design(*args)
    before = pools.started if pools else 0
    tracemalloc.start()
    try:
        y2, H2, w2, rows2 = chunked_design(*args, spill=True)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert np.array_equal(H, H2) and np.array_equal(y, y2) and np.array_equal(w, w2)
    assert len(layout.cuts) >= 20 and H.nbytes > 20e6
    # beside the rows' information (sensor, axis, start, stop, moving, y, weight: 57 bytes a row
    # against H's 312) a chunk's rows and, on one process, its work arrays; every chunk's rows
    # listed (then copied into H, as before) are H's size at least
    assert peak < 0.6 * H.nbytes, (peak, H.nbytes)
    assert pools is None or pools.started > before  # the spilled rows did come from workers


def test_chunks_on_a_dask_cluster_give_the_same_bits(data, monkeypatch):
    """The chunk work sent to a Dask cluster (CALBENCH_SCHEDULER; two worker processes here):
    the same estimates, σ and ranking as on this process, the table columns included (computed
    on the workers, brought back with the rows)."""
    from distributed import Client, LocalCluster, get_task_stream

    from components.estimation import table_columns as cache

    effects = list(DEFAULT_EFFECTS) + ["acc.k2", "table.base_tilt"]
    monkeypatch.setenv("CALBENCH_WORKERS", "1")
    cache._GEOMETRY_COLUMNS.clear()
    here = calibrate(data, effects, chunk_samples=SMALL)
    model = result_from_fit(here, effects, data)
    diag_here = diagnose(data, model, forward=False, chunk_samples=SMALL)
    cache._GEOMETRY_COLUMNS.clear()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            Client(cluster) as watcher, get_task_stream(client=watcher) as stream:
        monkeypatch.setenv("CALBENCH_SCHEDULER", cluster.scheduler_address)
        monkeypatch.setattr(chunks, "PARALLEL_CHUNKS", 2)  # a dozen chunks: below it they stay here
        there = calibrate(data, effects, chunk_samples=SMALL)
        diag_there = diagnose(data, model, forward=False, chunk_samples=SMALL)
    # the chunks ran there, on both workers
    ran = [t for t in stream.data if str(t["key"]).startswith("_with_columns")]
    assert len(ran) >= 2 * len(BlockLayout.of(data, 200, SMALL).cuts)
    assert len({t["worker"] for t in ran}) == 2
    assert np.array_equal(here.value, there.value)
    assert np.array_equal(here.covariance, there.covariance)
    assert [(c.effect, c.statistic) for c in diag_here.ranking] == [(c.effect, c.statistic) for c in diag_there.ranking]
    assert len(cache.geometry_column_keys()) > 0  # the workers' columns reached this process


def test_an_unreachable_scheduler_is_one_clear_error(data, monkeypatch):
    from components.errors import UserError

    monkeypatch.setattr(chunks, "SCHEDULER_TIMEOUT", "1s")
    monkeypatch.setattr(chunks, "PARALLEL_CHUNKS", 2)
    monkeypatch.setenv("CALBENCH_SCHEDULER", "tcp://127.0.0.1:9")
    with pytest.raises(UserError, match="CALBENCH_SCHEDULER=tcp://127.0.0.1:9: no Dask scheduler answers"):
        calibrate(data, list(DEFAULT_EFFECTS), chunk_samples=SMALL)


def test_a_small_geometry_cache_gives_the_same_fit(data, monkeypatch):
    """The table effects' columns come from a cache that drops its oldest entries: with room for
    only 3, a fit whose columns are partly cached (from a fit with fewer table effects) and
    partly new equals the fit made with an empty cache."""
    from components.estimation import table_columns as cache

    effects = list(DEFAULT_EFFECTS) + ["table.base_tilt", "table.nonorth"]
    monkeypatch.setattr(cache, "GEOMETRY_CACHE", 3)
    cache._GEOMETRY_COLUMNS.clear()
    fresh = calibrate(data, effects)
    cache._GEOMETRY_COLUMNS.clear()
    calibrate(data, list(DEFAULT_EFFECTS) + ["table.base_tilt"])  # some of the columns cached
    mixed = calibrate(data, effects)
    assert np.array_equal(fresh.value, mixed.value)
    assert np.array_equal(fresh.covariance, mixed.covariance)


def _dense_cut_candidates(static, gb, ab, n):
    """The definition, a sample at a time: p - 1 and p at rest, p a boundary of a block of each
    set, no block of either set with start < p < stop."""
    ok = []
    for p in range(1, n):
        if not (static[p - 1] and static[p]):
            continue
        if all(np.any((b.start == p) | (b.stop == p)) and not np.any((b.start < p) & (b.stop > p))
               for b in (gb, ab)):
            ok.append(p)
    return np.array(ok, dtype=int)


@pytest.mark.parametrize("seed", range(6))
def test_cut_candidates_are_the_definitions(seed):
    """From the blocks' boundaries alone, the same cut points as the per-sample definition, for
    sorted or shuffled, disjoint or overlapping blocks (one set empty in one case)."""
    from components.estimation.blocks import Blocks
    from components.estimation.chunks import cut_candidates

    rng = np.random.default_rng(seed)
    n = 400
    static = rng.random(n) > 0.15

    def blocks(k, overlapping):
        if k == 0:
            return Blocks(np.zeros(0, int), np.zeros(0, int), np.zeros(0, bool), False)
        if overlapping:
            start = rng.integers(0, n - 1, k)
            stop = np.minimum(start + rng.integers(1, 40, k), n)
        else:
            edges = np.sort(rng.choice(np.arange(n + 1), 2 * k, replace=False))
            start, stop = edges[0::2], edges[1::2]
        order = rng.permutation(k) if seed % 2 else np.arange(k)
        return Blocks(start[order], stop[order], np.zeros(k, bool), False)

    gb = blocks(60, overlapping=seed >= 3)
    ab = blocks(0 if seed == 5 else 45, overlapping=seed == 4)
    # blocks of one set that share boundaries with the other, so that there are cuts to find
    ab = Blocks(np.concatenate([ab.start, gb.start[::2]]), np.concatenate([ab.stop, gb.stop[::2]]),
                np.zeros(len(ab.start) + len(gb.start[::2]), bool), False) if seed != 5 else ab
    expected = _dense_cut_candidates(static, gb, ab, n)
    got = cut_candidates(static, gb, ab, n)
    assert np.array_equal(got, expected), (got, expected)
    assert seed >= 4 or len(expected) > 0  # (both sets overlapping or one empty: no cut may exist)


def test_reversal_error_in_chunks_equals_the_whole_log(data):
    # a chunk's first rest takes the side its stages last moved to from the whole log's history
    # (LogData.approach_at): cut without it, the chunk's first move would look like a reversal
    effects = list(DEFAULT_EFFECTS) + ["table.reversal"]
    whole = calibrate(data, effects)
    chunked = calibrate(data, effects, chunk_samples=SMALL)
    _same_fit(whole, chunked)
