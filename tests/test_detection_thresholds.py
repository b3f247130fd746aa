"""The thresholds diagnose reports (components.diagnosis.diagnose), each against a Monte-Carlo of
the statistic it is about, drawn with numpy (not scipy's distributions the code uses):

- detection: at the non-centrality λ found, the F test at level α rejects with 95 % power;
- naming first: at the signal-to-noise found for a look-alike of cosine ρ, the effect's
  projection beats the look-alike's in 95 % of draws.

Bounds: 4 binomial standard errors of the Monte-Carlo frequency."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from components.diagnosis.detection_thresholds import naming_snr, noncentrality

DRAWS = 40000
SE4 = 4 * math.sqrt(0.95 * 0.05 / DRAWS)


@pytest.mark.parametrize("k, dof, level", [(1, 500, 0.01 / 20), (3, 2000, 0.01 / 20), (6, 300, 0.001)])
def test_detection_threshold_has_95_percent_power(k, dof, level):
    lam = noncentrality(k, dof, level, 0.95)
    rng = np.random.default_rng(k)
    num = rng.noncentral_chisquare(k, lam, DRAWS) / k
    den = rng.chisquare(dof, DRAWS) / dof
    crit = stats.f.isf(level, k, dof)
    assert abs(np.mean(num / den > crit) - 0.95) <= SE4


@pytest.mark.parametrize("rho", [0.0, 0.6, 0.9, 0.97])
def test_naming_threshold_names_the_effect_first_in_95_percent(rho):
    m = naming_snr(rho)
    rng = np.random.default_rng(int(100 * rho))
    own = rng.normal(m, 1.0, DRAWS)
    # the look-alike's projection: correlated ρ with the effect's, its mean ρ m
    rival = rho * own + math.sqrt(1 - rho**2) * rng.normal(0.0, 1.0, DRAWS)
    assert abs(np.mean(np.abs(own) > np.abs(rival)) - 0.95) <= SE4


def test_look_alikes_need_more_signal_and_twins_cannot_be_named():
    ms = [naming_snr(r) for r in (0.0, 0.5, 0.9, 0.99)]
    assert all(a < b for a, b in zip(ms, ms[1:]))
    assert naming_snr(1.0) == math.inf


@pytest.mark.parametrize("k, dof, level", [(1, 500, 0.01 / 20), (4, 80, 0.01), (12, 100000, 1e-4)])
def test_noncentrality_is_the_root_to_full_precision(k, dof, level):
    """The threshold's λ gives 95 % power by scipy.stats' non-central F to far below the Monte
    Carlo test's resolution (the root is solved, not approximated)."""
    lam = noncentrality(k, dof, level, 0.95)
    crit = stats.f.isf(level, k, dof)
    assert abs(stats.ncf.sf(crit, k, dof, lam) - 0.95) < 1e-7
    assert abs(stats.ncf.sf(crit, k, dof, lam * (1 + 1e-6)) - 0.95) > 1e-9  # λ is pinned: the power moves
