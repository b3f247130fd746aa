"""Is a system-level filter's answer to be trusted? The checks a run must pass before its
estimates are used; each failure names the stage, the statistic, where, and how far out.

- **Numbers**: every estimate and σ finite; none beyond what a real IMU has
  (components.model.plausibility) — a filter printing 1e13 has diverged.
- **Innovations** (data with noise; noise-free data run on the filter's numerical floors, where
  the innovations measure its linearisation): under a consistent filter the normalised
  innovation squared ν²/S of each
  velocity component is χ²(1); summed over a window of W updates, χ²(3W). A window above its
  upper point at 0.1 % (Bonferroni over the windows) is a stretch of the run the filter's model
  does not explain — a missing effect (a gyro–accelerometer time offset, a lever arm), noise
  settings of the wrong grade, a wrong sign — even when the run's overall RMS looks healthy.
- **Against the prior**: an estimate more than ``PRIOR_SIGMAS`` prior σ from where the filter
  started is a parameter pulled far outside what it was told to expect (the prior's grade is
  wrong, or the data are).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from components.estimation.distributions import autocorrelation, ljung_box
from components.model.effects import effect_of
from components.model.plausibility import implausible

WINDOW_S = 10.0       # s of updates per innovation window
LEVEL = 1e-3          # family-wise level of the window test
PRIOR_SIGMAS = 20.0   # an estimate this many prior σ from its start is suspect
# the normalised innovations' autocorrelation is tested from this lag to that (updates): the first
# two lags carry the filter's own structure (~0.25 and ~0.07 on consistent runs of seed_003),
# beyond them a consistent filter's innovations are white (Ljung–Box p 0.001-0.8 over 3 seeds)
# and a slow noise it has no state for is not (flicker bias instability: p below 1e-30)
WHITE_LAGS = (3, 60)
# and the correlation must be worth it: a mean autocorrelation over lags 3-10 of at least this
# (bias instability gave 0.07-0.16, consistent runs 0.00-0.03; without it a long run's tiny
# structural correlation would turn significant by its length alone)
WHITE_MIN_CORRELATION = 0.05


@dataclass
class Consistency:
    """The checks' outcome for one filter stage."""

    stage: str
    problems: list[str] = field(default_factory=list)
    nis_mean: float | None = None         # mean ν²/S over all updates and components
    windows: int = 0
    windows_out: int = 0
    whiteness_p: float | None = None      # the innovations' worst Ljung–Box p (lags WHITE_LAGS)

    @property
    def ok(self) -> bool:
        return not self.problems


def check_stage(so, kf_interval: float, prior_values: np.ndarray | None = None,
                prior_sigmas: np.ndarray | None = None) -> Consistency:
    """The checks of one stage output (components.navigation.system.StageOutput)."""
    c = Consistency(so.stage.name)
    vals = np.asarray(so.values, float)
    sig = np.sqrt(np.abs(np.diag(so.covariance))) if so.covariance is not None else np.full(len(vals), np.nan)
    bad = [p for p, v, s in zip(so.parameters, vals, sig) if not (math.isfinite(v) and math.isfinite(s))]
    if bad:
        c.problems.append(f"stage {so.stage.name!r}: non-finite estimate or σ for {', '.join(bad[:6])}"
                          + (" ..." if len(bad) > 6 else "") + ": the filter diverged")
        return c
    absurd = implausible(dict(zip(so.parameters, so.totals if so.totals is not None else vals)))
    if absurd:
        worst = list(absurd.items())[:3]
        c.problems.append(f"stage {so.stage.name!r}: estimates beyond any real IMU: " + "; ".join(
            f"{p} ({why})" for p, why in worst) + (f" and {len(absurd) - 3} more" if len(absurd) > 3 else ""))
    if prior_values is not None and prior_sigmas is not None and len(prior_sigmas) == len(vals):
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.abs(vals - prior_values) / prior_sigmas
        far = [(p, float(x)) for p, x in zip(so.parameters, z) if np.isfinite(x) and x > PRIOR_SIGMAS]
        if far:
            far.sort(key=lambda t: -t[1])
            c.problems.append(f"stage {so.stage.name!r}: estimates far outside their prior: " + ", ".join(
                f"{p} {x:.0f} prior σ" for p, x in far[:4]) + " (is the grade of the prior right? --grade)")
    f = so.filter
    if f is not None and getattr(so, "noise_free", False):
        # no noise to hold the innovations to: they measure the filter's linearisation
        return c
    if f is not None and len(f.innovations):
        _whiteness(c, so.stage.name, f.innovations / np.sqrt(np.maximum(f.innovation_var, 1e-300)))
        nis = f.innovations ** 2 / np.maximum(f.innovation_var, 1e-300)
        c.nis_mean = float(np.mean(nis))
        per = max(1, int(round(WINDOW_S / kf_interval)))
        n = len(nis) // per
        c.windows = n
        if n:
            sums = nis[:n * per].reshape(n, per * nis.shape[1]).sum(axis=1)
            dof = per * nis.shape[1]
            limit = stats.chi2.isf(LEVEL / n, dof)
            out = np.nonzero(sums > limit)[0]
            c.windows_out = len(out)
            if len(out):
                k = int(out[np.argmax(sums[out])])
                t = f.history_t[min((k + 1) * per, len(f.history_t)) - 1] if len(f.history_t) else float("nan")
                c.problems.append(
                    f"stage {so.stage.name!r}: the velocity innovations exceed what the filter predicts in "
                    f"{len(out)} of {n} windows of {WINDOW_S:g} s (worst ending t = {t:.1f} s: "
                    f"{sums[k] / dof:.3g} times their predicted variance, limit {limit / dof:.3g}): its model "
                    "misses something there (an effect not among the states, e.g. acc.time_offset; noise "
                    "settings of another grade; a wrong sign or axis)")
    return c


def _whiteness(c: Consistency, stage: str, z: np.ndarray) -> None:
    """The normalised innovations z (updates × components) against white noise beyond the
    filter's own first lags (Ljung–Box over :data:`WHITE_LAGS`, Bonferroni over the components at
    :data:`LEVEL`): correlated innovations are a slow noise or effect the filter has no state for,
    and then its σ are too small, whatever their size says."""
    lo, hi = WHITE_LAGS
    n = len(z)
    if n < 4 * hi:
        return
    worst, flagged = None, []
    for k in range(z.shape[1]):
        p = ljung_box(z[:, k], hi - lo + 1, first=lo)
        got = (p, k, float(autocorrelation(z[:, k], lo, lo + 7).mean()))
        worst = got if worst is None or p < worst[0] else worst
        if p * z.shape[1] < LEVEL and got[2] >= WHITE_MIN_CORRELATION:
            flagged.append(got)
    if worst is not None:
        c.whiteness_p = worst[0]
    if flagged:
        p, k, r = min(flagged)
        c.problems.append(
            f"stage {stage!r}: the velocity innovations are correlated in time beyond the filter's own lags (component "
            f"{'xyz'[k] if z.shape[1] == 3 else k}: autocorrelation {r:.2f} over lags {lo}-{lo + 7}, Ljung–Box p "
            f"{p:.2g} over lags {lo}-{hi}): a slow noise (bias instability, random walk) or a slowly varying effect "
            "the filter has no state for; its σ are too small: give the filters the sensor's noise (kf --noise, "
            "e.g. a datasheet's gyro.noise.bi='0.005 deg/h', or a noise file of calbench noise on a table log of "
            "this IMU), whose slow terms become states")


def prior_of(so, settings) -> tuple[np.ndarray, np.ndarray]:
    """Where a kf stage's filter started and with what σ (its settings' prior)."""
    from components.navigation.kf import prior_sigmas

    start = np.array([settings.initial.get(p, 0.0) for p in so.parameters])
    return start, prior_sigmas(so.parameters, settings)


def describe_effects(params: list[str]) -> str:
    return ", ".join(dict.fromkeys(effect_of(p).name for p in params))
