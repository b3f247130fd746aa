"""The system-level filter with noise: its reported σ against its errors.

- The Schmidt (consider-state) update, alone, on a linear problem with a closed-form answer: the
  reported variance equals the Monte-Carlo variance of its errors, the consider state is never
  moved, and a filter that ignores the consider state is overconfident by the factor the closed
  form gives.
- The ready-made seed-003 configuration on FMU runs of the seed_003 schedule (default length,
  12 min, 200 Hz) with navigation-grade white noise (ARW 0.001 deg/sqrt(h), VRW 5 ug/sqrt(Hz))
  and a 0.2 ms IMU/table time offset, 4 Monte-Carlo seeds: the mean NEES of each stage within
  its 95 % band (for 4 runs): the table-referenced time offset (1 state), the 39-state filter (30 effect
  states) and the S204 consider-state bias stage (3). (Found by this test: passes that
  re-centred the prior walked along weakly observable directions, NEES 59 mean, 132 at worst.)

- The issue's accuracy targets on the one-hour seed_003 preset are the benchmark's
  (benchmarks/kf_vs_lsq.py: every target, RMS per state against its bound over 8 one-hour
  runs; `--runs 1` is the first seed alone, ~4 min): an accuracy figure, not a unit test."""
from __future__ import annotations

import multiprocessing as mp
import sys
from pathlib import Path

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from scipy.stats import chi2

from components.navigation.kf import _schmidt_update

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from kf_vs_lsq import TARGET, scenario, stage_nees  # noqa: E402


def test_schmidt_update_reports_the_variance_of_its_errors():
    """x = [a, c], z = a + c + v (n times), c a consider state with prior variance q, a with p,
    v with r. Closed form for the Schmidt estimate of a (gain rows of c zero, the optimal gain
    of a given the full covariance): its error variance is what P_aa reports; the consider state
    keeps x_c = 0 and P_cc = q; a plain filter on a alone (c ignored) reports less."""
    p, q, r, n, runs = 4.0, 1.0, 0.5, 6, 10000
    rng = np.random.default_rng(7)
    H = np.array([[1.0, 1.0]])
    keep = np.array([[1.0], [0.0]])
    errs = np.empty(runs)
    kf = None
    for i in range(runs):
        a, c = rng.normal(0, np.sqrt(p)), rng.normal(0, np.sqrt(q))
        kf = KalmanFilter(dim_x=2, dim_z=1)
        kf.x = np.zeros((2, 1))
        kf.P = np.diag([p, q])
        for _ in range(n):
            z = np.array([[a + c + rng.normal(0, np.sqrt(r))]])
            _schmidt_update(kf, z, np.array([[r]]), H, keep)
            assert kf.x[1, 0] == 0.0
        errs[i] = kf.x[0, 0] - a
    assert kf.P[1, 1] == pytest.approx(q, rel=1e-12)
    reported = kf.P[0, 0]  # P does not depend on the data
    # Monte-Carlo: the sample variance of 10000 errors is within ±5.7 % (4σ of its spread)
    assert np.var(errs) == pytest.approx(reported, rel=4 * np.sqrt(2 / runs))
    # the plain filter that ignores c reports 1/(1/p + n/r): far below the truth
    naive = 1.0 / (1.0 / p + n / r)
    assert naive < 0.2 * np.var(errs)


def _one_run(seed: int):
    from components.navigation.configs import load_config
    from components.navigation.system import calibrate_system
    from components.simulation.run import run_scenario

    run = run_scenario(scenario(seed, {}), progress=False)  # the default 12-min seed_003
    res, outs = calibrate_system(run.log, load_config("seed_003"))
    truth = run.truth["effects"]
    return stage_nees(outs, truth), res.values["imu.time_offset"] - truth["imu.time_offset"]


def test_seed003_nees_within_its_band_over_monte_carlo_runs():
    runs = 4
    with mp.get_context("fork").Pool(2) as pool:
        res = pool.map(_one_run, range(500, 500 + runs))
    for stage, (name, _, dof) in enumerate(res[0][0]):
        nees = [r[0][stage][1] for r in res]
        lo, hi = chi2.ppf([0.025, 0.975], runs * dof) / runs
        assert lo <= np.mean(nees) <= hi, (name, np.mean(nees), (lo, hi), nees)
    # the target for the IMU/table time offset (0.2 ms injected): 0.1 ms
    tau_err = [r[1] for r in res]
    assert max(map(abs, tau_err)) <= TARGET["imu.time_offset"], tau_err
