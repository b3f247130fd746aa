"""Flicker bias instability (``*.noise.bi_tau_max``): the construction of
components/model/flicker.py against its closed forms, and the IMU FMU's output against the
construction's Allan variance, with an Allan variance computed here and a bound from the
equivalent degrees of freedom. Never against numbers captured from the FMU."""
from __future__ import annotations

import math
from decimal import Decimal, getcontext

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from scipy.stats import chi2

from components.errors import ScenarioError, UserError
from components.model.flicker import flicker_count, flicker_terms, gm_avar, gm_avar_unit

from support import Slave

AX = "xyz"
OUT = [f"gyro.{c}" for c in AX] + [f"acc.{c}" for c in AX]
FLOOR = math.sqrt(2 * math.log(2) / math.pi)  # Allan floor of flicker noise per B, 0.664282


def g_reference(u: np.ndarray) -> np.ndarray:
    """Allan variance of a unit-variance Gauss-Markov process at u = tau / T, restated:
    2/u - (3 - 4 e^-u + e^-2u)/u^2 for u >= 0.01; below, where that form cancels, its expansion
    2u/3 - u^2/2 + 7u^3/30 - u^4/12 (relative truncation error < 3e-9)."""
    u = np.asarray(u, float)
    big = np.maximum(u, 0.01)
    closed = 2 / big - (3 - 4 * np.exp(-big) + np.exp(-2 * big)) / big**2
    series = 2 * u / 3 - u**2 / 2 + 7 * u**3 / 30 - u**4 / 12
    return np.where(u >= 0.01, closed, series)


def overlapping_avar(increments: np.ndarray, h: float, m: int) -> np.ndarray:
    """Overlapping Allan variance at tau = m h from per-sample increments (columns = series),
    through the cumulative sums theta: mean of (theta[k+2m] - 2 theta[k+m] + theta[k])^2 / (2 tau^2)."""
    theta = np.vstack([np.zeros((1, increments.shape[1])), np.cumsum(increments, axis=0)])
    d = theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]
    return np.mean(d**2, axis=0) / (2 * (m * h) ** 2)


def edf_random_walk_fm(n_phase: int, m: int) -> float:
    """Equivalent degrees of freedom of the overlapping Allan variance for random-walk FM noise
    (Howe, Allan & Barnes 1981, the 'simple' formula; n_phase phase points, averaging factor m).
    Between the corners of the sum the noise is flicker FM (EDF 5N^2 / (4m(N + 3m)), larger);
    above the highest corner, 1/(2 pi a), it turns into random-walk FM. The smaller of the two,
    this one, gives the wider (safe) bound: the exact EDF of the FMU's process, computed
    offline from its autocovariance, lies between them at every tau tested."""
    N = n_phase
    return (N - 2) / m * ((N - 1) ** 2 - 3 * m * (N - 1) + 4 * m * m) / (N - 3) ** 2


def run_at_rest(fmu, params: dict, h: float, n: int) -> np.ndarray:
    """The six outputs of n steps of h, inputs left at their start values (at rest, no gravity)."""
    s = Slave(fmu, params)
    vout = [s.vr(v) for v in OUT]
    out = np.empty((n, 6))
    try:
        for k in range(n):
            s.fmu.doStep(currentCommunicationPoint=s.time, communicationStepSize=h)
            s.time += h
            out[k] = s.fmu.getReal(vout)
    finally:
        s.close()
    return out


# ------------------------------------------------------------------------------ the construction

RANGES = [(10.0, 3600.0), (1.0, 100.0), (2.0, 50.0), (10.0, 2500.0), (1.0, 1.5), (0.3, 2.0e4),
          (1.0, 7.9e6)]


@pytest.mark.parametrize("t_lo,t_hi", RANGES)
def test_flicker_terms_follow_the_construction(t_lo, t_hi):
    B = 3e-6
    terms = flicker_terms(B, t_lo, t_hi)
    a, b = t_lo / 2, 2 * t_hi
    M = math.ceil(2 * math.log10(b / a)) + 1
    assert len(terms) == M <= 16
    sig = np.array([s for s, _ in terms])
    T = np.array([t for _, t in terms])
    np.testing.assert_allclose(T, a * (b / a) ** (np.arange(M) / (M - 1)), rtol=1e-13)
    assert np.all(sig == sig[0])
    tau = t_lo * (t_hi / t_lo) ** (np.arange(64) / 63)
    mean_sum = g_reference(tau[:, None] / T[None, :]).sum(1).mean()
    assert sig[0] ** 2 == pytest.approx(0.4412712 * B**2 / mean_sum, rel=1e-8)


def test_flicker_terms_numbers_10s_to_1h():
    """The brief's example range: a = 5 s, b = 7200 s, 2 log10(1440) = 6.32, so M = 8 and
    T_j = 5 s * 1440^(j/7)."""
    terms = flicker_terms(1.0, 10.0, 3600.0)
    assert len(terms) == 8
    np.testing.assert_allclose([t for _, t in terms], 5.0 * 1440.0 ** (np.arange(8) / 7), rtol=1e-13)
    assert terms[0][1] == 5.0 and terms[-1][1] == pytest.approx(7200.0, rel=1e-14)


def test_flicker_count_at_decades_and_limit():
    # b/a an exact power of ten: 2 log10 is an integer, ceil must not round it up
    assert flicker_count(2.0, 50.0) == 5      # b/a = 100
    assert flicker_count(10.0, 2500.0) == 7   # b/a = 1000
    assert flicker_count(20.0, 5.0e6) == 13   # b/a = 1e6
    lim = math.sqrt(1e15) / 4                  # 16 terms: (4 t_hi / t_lo)^2 <= 1e15
    assert flicker_count(1.0, lim * (1 - 1e-12)) == 16
    with pytest.raises(UserError, match="too wide.*at most 16"):
        flicker_count(1.0, lim * (1 + 1e-12))
    with pytest.raises(UserError, match="expected 0 < t_lo < t_hi"):
        flicker_count(5.0, 5.0)
    rng = np.random.default_rng(7)
    for lo, ratio in zip(10 ** rng.uniform(-2, 3, 500), 10 ** rng.uniform(1e-3, 6.8, 500)):
        assert flicker_count(lo, lo * ratio) == math.ceil(2 * math.log10(4 * (lo * ratio) / lo)) + 1


@pytest.mark.parametrize("t_lo,t_hi", RANGES)
def test_flicker_allan_deviation_is_flat(t_lo, t_hi):
    """The Allan deviation of the sum against the flicker floor 0.664282 B over [t_lo, t_hi]:
    within +-12 % from 1.4 t_lo up, and within -17 % .. +4 % over the whole range. The low edge
    rolls off by construction (a = t_lo/2 leaves the shorter correlation times out): at tau = t_lo
    the sum is 14 % under the floor for 10 s .. 1 h, down to 16 % for the widest ranges."""
    B = 1.0
    terms = flicker_terms(B, t_lo, t_hi)
    tau = np.geomspace(t_lo, t_hi, 400)
    avar = sum(s**2 * g_reference(tau / T) for s, T in terms)
    ratio = np.sqrt(avar) / (FLOOR * B)
    print(f"[{t_lo:g}, {t_hi:g}] s, M = {len(terms)}: ADEV / floor {ratio.min():.3f} .. {ratio.max():.3f}, "
          f"at t_lo {ratio[0]:.3f}")
    assert np.all((ratio > 0.83) & (ratio < 1.04))
    inner = tau >= 1.4 * t_lo
    assert np.all(np.abs(ratio[inner] - 1) < 0.12)
    # the fit: the mean Allan variance over the 64 points is the floor's square exactly
    tau64 = t_lo * (t_hi / t_lo) ** (np.arange(64) / 63)
    mean64 = sum(s**2 * g_reference(tau64 / T) for s, T in terms).mean()
    assert mean64 == pytest.approx(0.4412712 * B**2, rel=1e-8)


def test_gm_avar_against_high_precision():
    """gm_avar against the closed form at 50 digits, also where the double-precision form
    cancels (u = tau/T down to 1e-8)."""
    getcontext().prec = 50
    us = (1e-8, 1e-6, 1e-4, 0.01, 0.3, 0.4999, 0.5, 1.0, 1.89262, 7.0, 300.0, 1e6)
    refs = []
    for u in us:
        x = Decimal(u)
        refs.append(float(2 / x - (3 - 4 * (-x).exp() + (-2 * x).exp()) / (x * x)))
        assert gm_avar(2.0, 3.0, 3.0 * u) == pytest.approx(4.0 * refs[-1], rel=2e-15), u
    # the array form (the flicker construction's sums over its fit points) to the same digits
    np.testing.assert_allclose(gm_avar_unit(np.array(us)), refs, rtol=2e-15)
    # the Gauss-Markov peak used by the single-process model: sqrt(g) peaks at 0.617364 at 1.89262
    assert math.sqrt(gm_avar(1.0, 1.0, 1.89262)) == pytest.approx(0.617364, abs=1e-6)


# ------------------------------------------------------------------------------ the FMU

def test_fmu_flicker_allan_variance_matches_the_construction(imu_fmu):
    """IMU at rest, only the flicker bias instability on (bi_tau 2 s, bi_tau_max 500 s, M = 7),
    h = 0.1 s, 4 seeds x 4 h: the overlapping Allan variance of the 24 series (3 axes x 2
    sensors x 4 seeds, independent), each over B^2, averaged, against sum_j gm_avar(s, T_j, tau)
    of the construction. The mean of 24 independent estimates with nu_1 EDF each is
    ~ chi2(24 nu_1) / (24 nu_1) times the truth; the bound is its two-sided 99.9 % interval per
    tau, Bonferroni over the taus. The trapezoid integration of the FMU changes the expected
    value by < 0.07 % at tau = 2 s (exact discrete autocovariance, computed offline)."""
    B_g, B_a, t_lo, t_hi, h, n = 1e-5, 2e-4, 2.0, 500.0, 0.1, 144000
    seeds = (1, 2, 3, 4)
    runs = []
    for seed in seeds:
        p = {"gyro.noise.bi": B_g, "gyro.noise.bi_tau": t_lo, "gyro.noise.bi_tau_max": t_hi,
             "acc.noise.bi": B_a, "acc.noise.bi_tau": t_lo, "acc.noise.bi_tau_max": t_hi, "seed": seed}
        runs.append(run_at_rest(imu_fmu, p, h, n) / np.array([B_g] * 3 + [B_a] * 3))
    y = np.hstack(runs)  # (n, 24), in units of B
    terms = flicker_terms(1.0, t_lo, t_hi)
    ms = (20, 60, 200, 600, 2000, 5000)
    alpha = 1e-3 / len(ms)
    single_sigma = FLOOR / 0.617364  # what one Gauss-Markov process of T = bi_tau would give
    for m in ms:
        tau = m * h
        est = overlapping_avar(y, h, m).mean()
        expect = sum(gm_avar(s, T, tau) for s, T in terms)
        nu = y.shape[1] * edf_random_walk_fm(n + 1, m)
        lo, hi = chi2.ppf(alpha / 2, nu) / nu, chi2.ppf(1 - alpha / 2, nu) / nu
        single = gm_avar(single_sigma, t_lo, tau)
        print(f"tau {tau:6.1f} s: AVAR / expected {est / expect:.4f}, bound [{lo:.4f}, {hi:.4f}] "
              f"(EDF {nu:.0f}); ADEV {math.sqrt(est):.4f} B (floor {FLOOR:.4f} B); "
              f"a single Gauss-Markov would give {single / expect:.3f}")
        assert lo < est / expect < hi, (tau, est / expect, lo, hi)


ALL_NOISE = {"gyro.noise.arw": 1e-4, "gyro.noise.bi": 1e-5, "gyro.noise.rrw": 1e-6,
             "acc.noise.vrw": 1e-4, "acc.noise.bi": 1e-4, "acc.noise.rrw": 1e-5,
             "gyro.noise.bi_tau": 5.0, "acc.noise.bi_tau": 3.0}


@pytest.mark.parametrize("fmi_version", [2, 3])
@pytest.mark.parametrize("frac", [1.0, 0.5, 0.0, -2.0])
def test_fmu_bi_tau_max_not_above_bi_tau_is_unset(fmi_version, frac):
    """bi_tau_max <= bi_tau: the single Gauss-Markov process, the same bits as leaving it unset."""
    from fmus.build import fmu_path

    fmu = fmu_path("imu", fmi_version)
    h, n = 0.01, 300

    def outputs(extra):
        s = Slave(fmu, {**ALL_NOISE, "seed": 21, **extra})
        try:
            rows = []
            for _ in range(n):
                s.step(h)
                rows.append(s.get(*OUT))
        finally:
            s.close()
        return np.array(rows)

    unset = outputs({})
    capped = outputs({"gyro.noise.bi_tau_max": frac * 5.0, "acc.noise.bi_tau_max": frac * 3.0})
    assert np.abs(unset).max() > 0
    assert np.array_equal(unset, capped)


def test_fmu_flicker_leaves_other_draws_alone(imu_fmu):
    """The flicker terms draw from streams of their own: with B = 0 and the flicker range on,
    the white, Gauss-Markov and random-walk realisations are bit for bit those without it;
    switching the flicker on for the accelerometer leaves the gyro's bits alone."""
    h, n = 0.01, 300
    base = run_at_rest(imu_fmu, {**ALL_NOISE, "gyro.noise.bi": 0.0, "acc.noise.bi": 0.0, "seed": 5}, h, n)
    zero_b = run_at_rest(imu_fmu, {**ALL_NOISE, "gyro.noise.bi": 0.0, "acc.noise.bi": 0.0, "seed": 5,
                          "gyro.noise.bi_tau_max": 1000.0, "acc.noise.bi_tau_max": 1000.0}, h, n)
    assert np.array_equal(base, zero_b)
    off = run_at_rest(imu_fmu, {**ALL_NOISE, "seed": 5}, h, n)
    acc_on = run_at_rest(imu_fmu, {**ALL_NOISE, "seed": 5, "acc.noise.bi_tau_max": 1000.0}, h, n)
    assert np.array_equal(off[:, :3], acc_on[:, :3])
    assert not np.any(off[:, 3:] == acc_on[:, 3:])


@pytest.mark.parametrize("sensor", ["gyro", "acc"])
def test_fmu_refuses_too_wide_flicker_range(imu_fmu, sensor):
    name = f"{sensor}.noise.bi_tau_max"
    s = Slave(imu_fmu, {f"{sensor}.noise.bi_tau": 100.0, name: 1e12}, initialize=False)
    try:
        with pytest.raises(FMICallException):
            s.fmu.exitInitializationMode()
        msgs = [msg for st, msg in s.log if st >= 3]
        assert any(f"parameter {name} =" in msg and "too wide" in msg and "16" in msg for msg in msgs), s.log
    finally:
        s.fmu.freeInstance()
    # the widest range allowed (16 terms) initialises and runs
    ok = Slave(imu_fmu, {f"{sensor}.noise.bi": 1e-5, f"{sensor}.noise.bi_tau": 1.0,
                         name: math.sqrt(1e15) / 4 * (1 - 1e-12)})
    try:
        ok.step(0.01)
        assert np.all(np.isfinite(ok.get(*OUT)))
    finally:
        ok.close()


# ------------------------------------------------------------------------------ scenarios

def test_scenario_sets_and_records_the_flicker_range(tmp_path):
    """A scenario's [imu.noise] sets bi_tau_max like the other noise parameters: it reaches the
    FMU (the accelerometer's realisation changes, the gyro's does not) and the truth file."""
    from components.simulation.run import run_scenario
    from components.simulation.scenario import scenario_from_dict

    (tmp_path / "rest.toml").write_text('[[steps]]\nkind = "dwell"\nduration = 1.0\n')

    def scenario(noise):
        return scenario_from_dict({
            "scenario": {"name": "flicker", "step": 0.005, "seed": 4},
            "schedule": {"path": "rest.toml"},
            "site": {"latitude_deg": 39.9, "height_m": 50.0},
            "turntable": {"fmu": "builtin:turntable"},
            "imu": {"fmu": "builtin:imu", "noise": noise},
        }, source="test", base_dir=tmp_path)

    base = {"gyro.noise.bi": "0.01 deg/h", "acc.noise.bi": "20 ug", "acc.noise.bi_tau": "10 s"}
    sc = scenario({**base, "acc.noise.bi_tau_max": 3600.0})
    assert sc.imu_noise["acc.noise.bi_tau_max"] == 3600.0
    with_flicker = run_scenario(sc, progress=False)
    without = run_scenario(scenario(base), progress=False)
    assert with_flicker.truth["noise"]["acc.noise.bi_tau_max"] == 3600.0
    assert with_flicker.truth["imu"]["parameters"]["acc.noise.bi_tau_max"] == 3600.0
    assert "acc.noise.bi_tau_max" not in without.truth["noise"]
    assert np.array_equal(with_flicker.log.gyro, without.log.gyro)
    assert not np.array_equal(with_flicker.log.acc, without.log.acc)
    with pytest.raises(ScenarioError, match="acc.noise.bi_tau_max.*1 parsec"):
        scenario({"acc.noise.bi_tau_max": "1 parsec"})


def test_a_flicker_range_upside_down_is_refused():
    """bi_tau_max at or below bi_tau: the IMU simulated one Gauss–Markov term of bi_tau instead of
    the flicker floor asked for, and said nothing."""
    import tomllib
    from pathlib import Path

    from components.simulation.scenario import scenario_from_dict

    d = tomllib.loads((Path(__file__).resolve().parents[1] / "examples" / "scenarios" / "six_position.toml").read_text())
    d["imu"]["noise"].update({"gyro.noise.bi": "0.01 deg/h", "gyro.noise.bi_tau": 10.0, "gyro.noise.bi_tau_max": 5.0})
    with pytest.raises(ScenarioError, match="bi_tau_max = 5 s is not above bi_tau = 10 s"):
        scenario_from_dict(d, source="test")
