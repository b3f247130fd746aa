"""The χ², F and non-central F tails calbench's tests use, against scipy.stats (which evaluates
them independently through its own distribution classes) over the ranges the tests reach: tiny
p-values of a strongly detected effect, Holm levels down to 1e-5, large degrees of freedom."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from components.estimation.distributions import chi2_isf, chi2_sf, f_isf, f_logsf, ncf_sf

DOF = [1, 3, 9, 120, 5550, 250_000]


@pytest.mark.parametrize("dof", DOF)
def test_chi2_tail_and_its_inverse(dof):
    x = dof * np.array([0.05, 0.5, 1.0, 1.3, 3.0, 20.0])
    assert chi2_sf(x, dof) == pytest.approx(stats.chi2.sf(x, dof), rel=1e-12, abs=1e-300)
    p = np.array([0.5, 0.01, 1e-3 / 24, 1e-12])
    assert chi2_isf(p, dof) == pytest.approx(stats.chi2.isf(p, dof), rel=1e-12)


@pytest.mark.parametrize("dfn", [1, 3, 6])
@pytest.mark.parametrize("dfd", [40, 5550, 250_000])
def test_f_log_tail_and_its_inverse(dfn, dfd):
    x = np.array([0.1, 1.0, 5.0, 50.0, 247.0])
    assert f_logsf(x, dfn, dfd) == pytest.approx(stats.f.logsf(x, dfn, dfd), rel=1e-12)
    p = np.array([0.5, 0.01, 0.01 / 40])
    assert f_isf(p, dfn, dfd) == pytest.approx(stats.f.isf(p, dfn, dfd), rel=1e-10)


@pytest.mark.parametrize("dfn,dfd", [(1, 300), (3, 5550), (6, 40_000)])
def test_noncentral_f_power(dfn, dfd):
    crit = stats.f.isf(0.01 / 30, dfn, dfd)
    for nc in (1.0, 10.0, 25.0, 60.0):
        assert ncf_sf(crit, dfn, dfd, nc) == pytest.approx(stats.ncf.sf(crit, dfn, dfd, nc), abs=1e-9)
