"""The remainder of a pulse output's count as it turns through a rest: the quantization term's
discrete form when the phase advance of each block is known.

A pulse output of count weight w reports floor(φ_end) − floor(φ_start) counts over a block, φ the
accumulated input in counts; the block sum is the true one plus w (r_start − r_end), with
r = frac(φ) − ½ = −Σₙ sin(2πnφ) / (πn). Taken as independent at every block boundary (the
plain quantization term, components.model.noise), r is what a sensor turning fast gives. At rest
a channel advances by a fraction of a count per block (Earth's rate on a 2″ gyro count: ~7 counts
a second, any fraction of one per block): r then runs along a sawtooth fixed by that advance, and
a slow one (an advance near a whole count per block) is a ramp over many blocks, which a fit
taking the remainders as independent reads as a rate error several of its σ wide.

Each harmonic n of r is a pair of states (cos 2πnφ, sin 2πnφ), variance ½ each at a uniform
phase, which a block with advance Δ (counts) turns by 2πnΔ and the noise within it dithers (the
white noise, and the slow terms' wander about the rest's mean rate:
components.model.rest_wander): a phase spread s² (counts²) damps the pair by ρ = exp(−2π²n²s²), and the process noise
(1 − ρ²)/2 per state keeps it stationary. A block where the advance is not known (a move: the
phase after it is anybody's) damps every harmonic to nothing. Harmonics that no block damps less
than :data:`KEPT_DAMPING` (fine counts, or the high harmonics of any count under noise) forget
their phase within a block and stay in the independent term, with the variance w²/12 minus what
the kept ones carry; so a channel whose noise dithers every harmonic has the plain term exactly.

The block sum loads the sine state at its start with −w/(πn) and the one at its end with
+w/(πn); with x' = F x + v that is c = a + Fᵀb on the start state, b·v in the sum (its variance
and its covariance with v: bᵀQb, Qb).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

KEPT_DAMPING = 0.01  # a harmonic kept as states where some block keeps more than this of its phase
MAX_HARMONICS = 16   # a noise-free pulse output keeps these (the rest, 3.7 % of w²/12, stays independent)


@dataclass
class RemainderForm:
    """The kept harmonics' states (2 per harmonic, cosine then sine) on B blocks: diagonal
    ``phi``, the turning ``spin`` at (i, ``partner[i]``), process variance ``q``, loading ``c``,
    ``cross`` (B, 2n); the block sums' own variance ``rest`` (B,) from them; ``p0`` (2n,); and the
    variance per boundary left to the independent term, ``independent``."""

    phi: np.ndarray
    spin: np.ndarray
    partner: np.ndarray
    q: np.ndarray
    c: np.ndarray
    cross: np.ndarray
    rest: np.ndarray
    p0: np.ndarray
    independent: float


def kept_harmonics(spread: np.ndarray) -> int:
    """How many harmonics some block with phase spread *spread* (counts², finite entries only)
    damps by less than :data:`KEPT_DAMPING` (at most :data:`MAX_HARMONICS`)."""
    s = spread[np.isfinite(spread)]
    if len(s) == 0:
        return 0
    least = float(np.min(s))
    if least <= 0:
        return MAX_HARMONICS
    return min(MAX_HARMONICS, int(math.floor(math.sqrt(math.log(1 / KEPT_DAMPING) / (2 * math.pi**2 * least)))))


def remainder_form(count: float, advance: np.ndarray, spread: np.ndarray, harmonics: int,
                   joined: np.ndarray | None = None, through: np.ndarray | None = None,
                   through_spread: np.ndarray | None = None) -> RemainderForm:
    """The form of a count *count* (w, in the channel's unit) with *harmonics* kept, on blocks of
    phase *advance* (counts; NaN where unknown) and phase spread *spread* (counts²). ``joined``
    (B,) bool: the block ends where the next one starts (None: all do); after one that does not,
    the phase turns through the gap by ``through`` (B,) counts with spread ``through_spread``
    (counts²) where its rest goes on (a lost packet: components.estimation.count_phase), and is
    anybody's where that is NaN (or None) — the next rest's rate is read anew and what the phase
    turned through the gap is not known to a count."""
    adv = np.asarray(advance, float)
    nb = len(adv)
    known = np.isfinite(adv) & np.isfinite(spread)
    joined = np.ones(nb, bool) if joined is None else np.asarray(joined, bool)
    gap = np.full(nb, np.nan) if through is None else np.where(joined, np.nan, np.asarray(through, float))
    bridged = np.isfinite(gap)
    gap_spread = np.zeros(nb) if through_spread is None else np.asarray(through_spread, float)
    cols = {k: [] for k in ("phi", "spin", "q", "c", "cross")}
    partner, rest, carried = [], np.zeros(nb), 0.0
    for n in range(1, harmonics + 1):
        beta = count / (math.pi * n)
        rho = np.where(known, np.exp(-2 * math.pi**2 * n**2 * np.where(known, spread, 0.0)), 0.0)
        turn = 2 * math.pi * n * np.where(known, adv, 0.0)
        cos, sin = np.cos(turn), np.sin(turn)
        fresh = (1 - rho**2) / 2
        i = len(partner)
        # cosine state, then sine state: F = ρ [[cos, −sin], [sin, cos]]; across a gap the block's
        # sum still loads its own end (turned from its start), and the next state is that end
        # turned on through the gap by G = ρ_g R(g) where the rest goes on, else new
        rho_g = np.where(bridged, np.exp(-2 * math.pi**2 * n**2 * gap_spread), 0.0)
        g = 2 * math.pi * n * np.where(bridged, gap, 0.0)
        hold = np.where(joined, rho, rho * rho_g)
        cols["phi"] += [hold * np.cos(turn + g)] * 2
        cols["spin"] += [-hold * np.sin(turn + g), hold * np.sin(turn + g)]
        partner += [i + 1, i]
        cols["q"] += [np.where(joined | bridged, (1 - hold**2) / 2, 0.5)] * 2
        cols["c"] += [rho * beta * sin, -beta + rho * beta * cos]
        # the sum's end noise (the sine state's, loaded +β) as the next state holds it: G Q b
        carried_on = np.where(joined, 1.0, rho_g)
        cols["cross"] += [-carried_on * fresh * beta * np.sin(g), carried_on * fresh * beta * np.cos(g)]
        rest += beta**2 * fresh
        carried += beta**2 / 2  # the harmonic's share of var(w r) at a boundary
    stack = {k: np.column_stack(v) if v else np.zeros((nb, 0)) for k, v in cols.items()}
    independent = max(count**2 / 12 - carried, 0.0)
    return RemainderForm(stack["phi"], stack["spin"], np.array(partner, dtype=np.int64), stack["q"], stack["c"],
                         stack["cross"], rest, np.full(2 * harmonics, 0.5), independent)


def remainder_carried(kept: int, through: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """(B,): the correlation of the remainder's harmonics beyond the *kept* ones across a gap the
    phase turns through by *through* counts with spread *spread* (counts²), each harmonic n turned
    by 2πn·through and damped by exp(−2π²n² spread), weighted by its share of the variance (1/n²):
    what the independent quantization term of the next block starts with (0 where *through* is
    NaN). A lost packet's gap in a slow rest carries nearly all of it; taken as new, the rest's
    rate had σ 1.17 times too wide (components.estimation.count_phase).

    The whole sum Σₙ cos(2πnx) e^(−2π²n²s²) / n² is the sawtooth's autocovariance π²(x² − |x| + 1/6)
    (x the turn's distance to the nearest whole count) smoothed by a Gaussian of variance s², in
    closed form while s is small beside a count; the kept harmonics are taken off it one by one.
    (Every whitening of a pulse log with lost packets builds it, and the noise terms' likelihood
    in diagnose and add thousands of times: summed directly over 2,000 harmonics a gap it cost
    ~5 ms a call and still missed ~1 % of the share at 16 kept.)"""
    through = np.asarray(through, float)
    out = np.zeros(len(through))
    on = np.flatnonzero(np.isfinite(through))
    if not len(on):
        return out
    from scipy.special import erf  # at use: only a pulse output with lost packets needs it

    x = through[on] - np.round(through[on])
    s2 = np.maximum(np.asarray(spread, float)[on], 0.0)
    s = np.sqrt(s2)
    wide = s > SMOOTH_CLOSED_FORM
    whole = np.empty(len(on))
    # |x| smoothed by the Gaussian: E|x + ε|
    n = ~wide
    with np.errstate(divide="ignore", invalid="ignore"):
        smooth_abs = np.where(s[n] > 0, s[n] * math.sqrt(2 / math.pi) * np.exp(-x[n] ** 2 / (2 * np.where(s[n] > 0, s2[n], 1.0)))
                              + x[n] * erf(x[n] / (math.sqrt(2) * np.where(s[n] > 0, s[n], 1.0))), np.abs(x[n]))
    whole[n] = math.pi**2 * (x[n] ** 2 + s2[n] - smooth_abs + 1 / 6)
    if wide.any():
        # damped within a few harmonics: summed directly
        m = np.arange(1, WIDE_HARMONICS + 1, dtype=float)
        whole[wide] = (np.exp(-2 * math.pi**2 * s2[wide, None] * m**2) * np.cos(2 * math.pi * x[wide, None] * m)) @ (1 / m**2)
    k = np.arange(1, kept + 1, dtype=float)
    if kept:
        whole -= (np.exp(-2 * math.pi**2 * s2[:, None] * k**2) * np.cos(2 * math.pi * x[:, None] * k)) @ (1 / k**2)
    out[on] = whole / (math.pi**2 / 6 - float(np.sum(1 / k**2)))
    return out


SMOOTH_CLOSED_FORM = 0.1  # counts: the phase spread below which the smoothed sawtooth's closed form holds
WIDE_HARMONICS = 40       # a spread above it damps the harmonics beyond these below 1e-30
