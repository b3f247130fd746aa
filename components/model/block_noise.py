"""The exact discrete form of a channel's composite noise (components.model.noise) on the
estimators' observation blocks.

The estimators see block sums of increments over [t_k, t_k + Δ_k] (components.estimation.blocks).
Over a block each term has an exact discrete form with a state at the block boundary:

- Gauss–Markov x (the flicker floor as a sum of them, components.model.flicker): x' = φ x + w,
  ∫x = T (1 − φ) x + v, φ = e^(−Δ/T), var w = σ² (1 − φ²), var v = σ² T [2Δ − T (3 − 4φ + φ²)],
  cov(w, v) = σ² T (1 − φ)².
- random walk b: b' = b + w, ∫b = Δ b + v, var w = K² Δ, var v = K² Δ³ / 3, cov(w, v) = K² Δ² / 2.
- quantization: a pulse output carries the remainder r (|r| ≤ one count w / 2), so a block sum is
  the true sum + r_start − r_end; r at each boundary is a state with var Q² = w² / 12 (no memory).
  Where the blocks' advance is known (the rests of a pulse log), the harmonics of r that the
  noise does not dither away within a block turn from block to block instead
  (components.model.count_remainder): pairs of states, the one transition that is not diagonal.
- white: N² Δ, independent per block.

All other transitions are diagonal (the terms are independent), which keeps the whitening filter
(components.estimation.whitening) to a few vector operations per block.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from components.model.count_remainder import kept_harmonics, remainder_carried, remainder_form
from components.model.noise import ChannelNoise
from components.model.rest_wander import rest_spans, slow_wander_in_rest


@dataclass
class BlockNoise:
    """One channel's noise on a sequence of contiguous blocks: the boundary state's diagonal
    transition ``phi`` (B, m) and process variance ``q`` (B, m), the block sum's loading ``c``
    (B, m), its cross-covariance with the process noise ``cross`` (B, m), the rest of its variance
    ``r`` (B,), and the state's initial variance ``p0`` (m,)."""

    phi: np.ndarray
    q: np.ndarray
    c: np.ndarray
    cross: np.ndarray
    r: np.ndarray
    p0: np.ndarray
    # a transition that also turns pairs of states (a pulse count's remainder at rest,
    # components.model.count_remainder): ``spin`` (B, m) at (i, ``partner[i]``), -1 for none
    spin: np.ndarray | None = None
    partner: np.ndarray | None = None

    @property
    def states(self) -> int:
        return self.p0.shape[0]


# The bias-instability floor of a sensor runs on past the end of any one log: the slow part of it
# is an offset that stays over the log and is indistinguishable from the bias itself, and the
# bias estimated there carries it. A floor with no upper end would give that offset an unbounded
# variance, so an identified floor is taken to run to an hour (the averaging times datasheets
# state it over), or to the log's length if that is longer.
FLICKER_HORIZON = 3600.0


def flicker_upper(span: float, t_lo: float) -> float:
    """Where a floor without a range of its own is taken to end, on a log of *span* seconds."""
    return max(span, FLICKER_HORIZON, 2 * t_lo)


def block_noise(ch: ChannelNoise, durations: np.ndarray, white_var: np.ndarray, span: float,
                t_lo: float, advance: np.ndarray | None = None, gaps: np.ndarray | None = None) -> BlockNoise:
    """The discrete form of *ch* on blocks of *durations* [s] in time order, each *gaps* [s]
    after the one before it (None: contiguous; samples left out — a gap in the clock, the mask,
    an exclusion, a dropped move — lie between blocks, and the state runs on through them).
    ``white_var`` (B,): the block sums' variance from white noise and anything else independent
    per block (rest angles); ``span`` [s]: the log's duration (a floor without a range of its own
    is realised up to :func:`flicker_upper`, and the random walk's starting value has that much
    wander); ``t_lo`` [s]: the shortest time scale the flicker floor is realised from.
    ``advance`` (B,) or (B, 2): a pulse output's input over each block in the channel's unit (NaN
    where not known: a move), and through the gap before it where it goes on a rest
    (components.estimation.count_phase's second column; NaN: the phase is new after the gap);
    given, the quantization's remainder turns through the rests (components.model.count_remainder)."""
    d = np.asarray(durations, float)
    nb = len(d)
    # what lies between a block's end and the next one's start: a state's transition spans both
    after = np.zeros(nb) if gaps is None else np.append(np.asarray(gaps, float)[1:], 0.0)
    joined = after == 0  # the block's end is the next one's start
    rest = np.asarray(white_var, float).copy()
    terms = ch.gm_terms(t_lo, flicker_upper(span, t_lo))
    # the Gauss–Markov terms as (B, terms) at once: the noise likelihood builds this ~10^5 times
    # a `calbench noise`, and column by column it was a fifth of that command
    s2 = np.array([s * s for s, _ in terms]).reshape(1, -1)
    T = np.array([t for _, t in terms]).reshape(1, -1)
    phi = np.exp(-d[:, None] / T)
    on = np.exp(-after[:, None] / T)  # (the decay through the gap after the block)
    cols_phi, cols_q = [phi * on], [s2 * (1 - (phi * on) ** 2)]
    cols_c, cols_x = [T * (1 - phi)], [s2 * T * (1 - phi) ** 2 * on]
    rest += np.sum(s2 * T * (2 * d[:, None] - T * (3 - 4 * phi + phi**2)), axis=1)
    p0 = list(s2.ravel())
    K = ch.random_walk
    if K > 0:
        cols_phi.append(np.ones((nb, 1)))
        cols_q.append((K**2 * (d + after))[:, None])
        cols_c.append(d[:, None].copy())
        cols_x.append((K**2 * d**2 / 2)[:, None])
        rest += K**2 * d**3 / 3
        p0.append(K**2 * max(span, 1.0))
    Q = ch.quantization
    form = None
    carry = joined.astype(float)  # how much of the remainder at a block's end the next one starts with
    if Q > 0 and advance is not None:
        count = Q * math.sqrt(12.0)
        advance = np.asarray(advance, float)
        through = np.full(nb, np.nan)  # the input through the gap after each block, where the rest goes on
        if advance.ndim == 2:
            advance, through[:-1] = advance[:, 0], advance[1:, 1]
        through = np.where(joined, np.nan, through)
        # the white noise's spread through a gap: as over a block, for the gap's time
        through_spread = np.asarray(white_var, float) / count**2 * after / d
        # the phase spread over a block: its white noise, and the slow terms' wander within the
        # rest beyond the rest's mean rate (which the tick-read advance holds); the wander only
        # adds, so where the white noise alone dithers every harmonic (fine counts) it is not needed
        spread = np.where(np.isfinite(advance), np.asarray(white_var, float) / count**2, np.nan)
        n = kept_harmonics(spread)
        if n:
            on = joined | np.isfinite(through)  # the rest goes on after the block
            spread = spread + slow_wander_in_rest(terms, ch.random_walk, d, rest_spans(d, advance, on)) / count**2
            n = kept_harmonics(spread)
        if n:
            form = remainder_form(count, advance / count, spread, n, joined, through / count, through_spread)
            Q = math.sqrt(form.independent)
            rest += form.rest
        if np.isfinite(through).any():
            # the harmonics beyond those kept, through a short gap inside a rest: as much of the
            # remainder as the gap's advance and noise leave (after a lost packet, most of it)
            carry = np.where(np.isfinite(through), remainder_carried(n, through / count, through_spread), carry)
    if Q > 0:
        # the state is the remainder at the block's start; the new one (at its end) is the next
        # state's process noise, unless a gap lies between (or, through a short one inside a rest,
        # that much of it), and enters this block's sum with the opposite sign
        cols_phi.append(np.zeros((nb, 1)))
        cols_q.append(np.full((nb, 1), Q**2))
        cols_c.append(np.ones((nb, 1)))
        cols_x.append((-carry * Q**2)[:, None])
        rest += Q**2
        p0.append(Q**2)

    if form is not None:
        cols_phi.append(form.phi)
        cols_q.append(form.q)
        cols_c.append(form.c)
        cols_x.append(form.cross)
    states = (np.hstack(cols_phi), np.hstack(cols_q), np.hstack(cols_c), np.hstack(cols_x), rest)
    if form is None:
        return BlockNoise(*states, np.array(p0, float))
    m0 = len(p0)
    return BlockNoise(*states, np.concatenate([np.array(p0, float), form.p0]),
                      spin=np.hstack([np.zeros((nb, m0)), form.spin]),
                      partner=np.concatenate([np.full(m0, -1, np.int64), form.partner + m0]))
