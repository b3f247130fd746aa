"""Does a log mean what its metadata say? Checks of the declared output kinds and angle units
against physics, before anything is fitted (a fit on a mis-declared log converges all the same,
to a scale factor of −99.5 % or a χ²/dof of 10⁹, and says nothing of why).

- the accelerometers at rest measure gravity: their mean magnitude over the static samples,
  read as the metadata say, is g; dt·g says increments were declared as specific force (rates),
  g/dt the reverse, 1/g or g² (in m/s²) that g and m/s² were confused;
- during the table's moves the gyros turn as the table angles do: the ratio of the gyros'
  rotation to the rotation the angles give is 1; dt or 1/dt says rates and increments were
  confused, 57.3 or 1/57.3 degrees and radians (in the gyro or in the table angles);
- a log without table angles: at rest the gyros' rate along the specific force is the Earth's
  rate along the vertical plus the gyro bias along it, in every attitude; one axis of a triad
  reversed (a left-handed pair) breaks that, and the axis that mends it is named.

Each finding is one line naming the evidence; the caller prints it as a warning (the estimate's
own plausibility check, components.model.plausibility, flags the result too).
"""
from __future__ import annotations

import math

import numpy as np

from components.logs.spill import piece_rows, pieces

# a measured ratio within this factor of a mistake's ratio is taken as that mistake; the right
# declaration gives 1 within a few per cent (a scale factor error, the table's own servo error)
MATCH = 1.3


# samples each unit check looks at, at most: a mis-declaration scales every sample alike, and the
# median of this many reads the ratio to far better than MATCH (the checks ran over a whole
# 8-hour log: ~3 s of every command)
ENOUGH_MOVING = 50_000  # moving samples of the gyro's check
ENOUGH_STATIC = 1 << 16  # samples of the accelerometers' check (the static among them), spread over the log


def _near(ratio: float, target: float) -> bool:
    return ratio > 0 and target > 0 and abs(math.log(ratio / target)) < math.log(MATCH)


def check_semantics(data, log) -> list[str]:
    """Findings (one line each) where the log's numbers contradict its declared kinds or units."""
    out: list[str] = []
    dt = float(log.dt)
    use = data.usable
    g = float(log.gravity) if getattr(log, "gravity", None) else 9.80665
    stride = max(1, len(data.time) // ENOUGH_STATIC)
    static = data.static[::stride] & use[::stride]
    if static.sum() >= 10:
        # per sample (the rests differ in attitude: their mean vector would cancel)
        f = float(np.median(_norms(data.acc[::stride], static), overwrite_input=True)) / dt
        r = f / g
        for target, what in ((dt, "increments declared as specific force (rates): the values are g·dt"),
                             (1 / dt, "specific force (rates) declared as increments: the values are g/dt"),
                             (1 / g, "values in g declared as m/s²"), (g, "values in m/s² declared as g")):
            if _near(r, target):
                out.append(f"{log.source or 'log'}: the accelerometers at rest measure {f:.4g} m/s² as declared "
                           f"({log.acc_output}), {r:.4g} × gravity {g:.5g} m/s²: {what}?")
                break
    if data.has_table:
        ideal, moving = _ideal_gyro_moving(data, use)
        if len(ideal) >= 10:
            expected = np.linalg.norm(ideal, axis=1)
            measured = _norms(data.gyro[:len(moving)], moving)
            # per sample and the median: a mis-declaration scales every sample alike, while one
            # corrupt angle cell (a jump of hundreds of radians) must not pass for a unit mistake
            turning = expected > 0.1 * np.median(expected) if expected.size else expected
            if turning.sum() >= 10:
                r = float(np.median(measured[turning] / expected[turning]))
                for target, what in ((dt, "increments declared as rates"), (1 / dt, "rates declared as increments"),
                                     (180 / math.pi, "gyro values in degrees declared as radians, or table angles "
                                                     "in radians declared as degrees"),
                                     (math.pi / 180, "table angles in degrees declared as radians, or gyro values "
                                                     "in radians declared as degrees")):
                    if _near(r, target):
                        span = float(np.ptp(data.angles[use], axis=0).max()) if data.angles.size else 0.0
                        out.append(f"{log.source or 'log'}: during the table's moves the gyros turn {r:.4g} × what "
                                   f"the table angles give (the angles span {span:.4g} rad = {math.degrees(span):.4g}° "
                                   f"as declared): {what}?")
                        break
        out += _clipped(data, log, use, ideal, moving)
    elif static.any():
        out += _handedness(data, log)
    return out


# a clipped output: a gyro channel whose extreme reading recurs to the last digit in this many
# moving samples (noise never repeats a maximum; a constant rate without noise, as a simulator
# writes, does: the table tells the two apart) ...
PLATEAU = 10
# ... and reads less than CLIP_SHORT of the table's rotation about its axis there than in the
# channel's other moves (its own scale factor, whatever it is, cancels out of the comparison)
CLIP_SHORT = 0.01
ENOUGH_PLATEAU = 2000  # plateau samples the ratio is read from, at most (spread over them)


def _clipped(data, log, use: np.ndarray, ideal: np.ndarray, moving: np.ndarray) -> list[str]:
    """A finding per gyro channel whose output stops at a value while the table turns faster
    about it: a sensor driven beyond its range reads its full scale (its increments repeat to the
    bit), and every estimate takes that for a scale factor or a misalignment. *ideal*, *moving*:
    the unit check's moving samples (:func:`_ideal_gyro_moving`), the channel's other moves."""
    out = []
    measured_else = np.asarray(data.gyro[:len(moving)], float)[moving] if len(ideal) else np.zeros((0, 3))
    extremes = _extreme_readings(log.gyro, ~data.static & use)
    for c, axis in enumerate("xyz"):
        sides = []
        for at in extremes[c]:
            at = at[at > 0]  # nothing before the first sample to take a chord from
            if len(at) < PLATEAU:
                continue
            k = at[np.linspace(0, len(at) - 1, min(len(at), ENOUGH_PLATEAU)).astype(int)]
            chord = _chords(data, k)[:, c]
            got = np.asarray(data.gyro[k, c], float)
            if not np.all(chord * got > 0):
                continue
            plateau = float(np.median(got / chord))
            # the channel's reading of the table elsewhere: moves turning it at least a fifth as fast
            far = np.abs(ideal[:, c]) > 0.2 * float(np.median(np.abs(chord)))
            far &= ~np.isin(np.flatnonzero(moving), at)
            elsewhere = float(np.median(measured_else[far, c] / ideal[far, c])) if far.sum() >= PLATEAU else 1.0
            if not plateau < elsewhere * (1 - CLIP_SHORT):
                continue
            rate = float(np.median(got / (data.times_at(k) - data.times_at(k - 1))))
            t = data.times_at(at[[0, -1]])
            sides.append(f"{rate:+.6g} rad/s ({math.degrees(rate):+.5g}°/s) in {len(at)} moving samples "
                         f"(t = {t[0]:.6g}-{t[1]:.6g} s), {100 * (1 - plateau / elsewhere):.3g} % short of the "
                         "table's rotation about it there against its other moves")
        if sides:
            out.append(f"{log.source or 'log'}: gyro_{axis} reads to the last digit {' and '.join(sides)}: its "
                       "output is clipped at its range? Give the range (imu.gyro_range_radps in a calbench-log/2 "
                       "file's metadata, range in an import mapping's [imu.gyro]) and the samples at it are left "
                       "out, or --exclude those times; as it is, the estimates take the clipped samples for the "
                       "gyro's own error")
    return out


def _extreme_readings(raw, turning: np.ndarray) -> list[list[np.ndarray]]:
    """Per channel of *raw* (N, 3), as in the file (a rate output's clipped value repeats to the
    bit even where the intervals jitter), the samples of *turning* that read its largest value and
    those that read its smallest: two passes a piece of the log at a time."""
    hi, lo = np.full(3, -np.inf), np.full(3, np.inf)
    for s in pieces(len(raw), raw, step=piece_rows(raw)):
        x = np.asarray(raw[s], float)[turning[s]]
        if len(x):
            hi, lo = np.maximum(hi, x.max(axis=0)), np.minimum(lo, x.min(axis=0))
    found = [[[], []] for _ in range(3)]
    for s in pieces(len(raw), raw, step=piece_rows(raw)):
        x = np.asarray(raw[s], float)
        for c in range(3):
            for side, e in enumerate((hi[c], lo[c])):
                if np.isfinite(e) and e != 0:
                    found[c][side].append(np.flatnonzero((x[:, c] == e) & turning[s]) + s.start)
    return [[np.concatenate(f) if f else np.zeros(0, np.intp) for f in sides] for sides in found]


# the handedness check (a log without table angles): a reversed axis is named when the rests'
# f·ω misfit a constant plus the gyro bias along f beyond chance (p below HANDED_P), one axis
# reversed fits them (χ²/dof below HANDED_FIT) and better by HANDED_GAIN in χ² (a likelihood
# ratio of e^25): a gyro that cannot see the Earth's rate against its noise (MEMS) fits every
# hypothesis alike and is never named
HANDED_P = 1e-6
HANDED_FIT = 3.0
HANDED_GAIN = 50.0
MIN_RESTS = 8


def _handedness(data, log) -> list[str]:
    """At rest the unit specific force u (up) and the Earth rate ω have u·ω = Ω sin(latitude) in
    any frame and attitude; the gyros read ω + b, so u·(ω + b) is a constant plus u·b, linear in
    the bias. With one axis of one triad reversed (a left-handed pair: a sign in the logger or the
    import mapping) it is not, and the positions method converges all the same (each rest's
    attitude is free) to a χ²/dof of thousands and a 'missing' g-sensitivity."""
    from components.estimation.allan import static_runs

    use = data.static_usable
    rests = static_runs(use, 10)
    if len(rests) < MIN_RESTS:
        return []
    f = np.array([np.sum(data.acc[a:b], axis=0) for a, b in rests])
    w = np.array([np.sum(data.gyro[a:b], axis=0) for a, b in rests])
    n = np.array([b - a for a, b in rests], float)
    u = f / np.linalg.norm(f, axis=1)[:, None]
    sg = float(np.median(np.maximum(data.white_sigma_at_rest("gyro"), data.quantization_floor()[:3])))
    if not np.isfinite(sg) or sg <= 0:
        return []
    sigma = sg * np.sqrt(n)  # of u·(gyro sum): white per sample along a unit vector

    def misfit(v: np.ndarray) -> float:
        """χ² of u·(gyro sum) against (c + u·b) n (the rests' lengths differ)."""
        X = np.column_stack([n, v * n[:, None]]) / sigma[:, None]
        y = np.einsum("ij,ij->i", v, w) / sigma
        r = y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
        return float(r @ r)

    from components.estimation.distributions import chi2_sf

    dof = len(rests) - 4
    plain = misfit(u)
    reversed_ = [misfit(u * np.where(np.arange(3) == i, -1.0, 1.0)) for i in range(3)]
    i = int(np.argmin(reversed_))
    if chi2_sf(plain, dof) >= HANDED_P or reversed_[i] > HANDED_FIT * dof or plain - reversed_[i] < HANDED_GAIN:
        return []
    axis = "xyz"[i]
    return [f"{log.source or 'log'}: at its {len(rests)} rests the gyros' rate along the accelerometers' specific "
            f"force is not the Earth's rate along the vertical plus a bias (χ²/dof {plain / dof:.3g}); with axis "
            f"{axis} of one sensor reversed it is (χ²/dof {reversed_[i] / dof:.3g}): the accelerometer's or the "
            f"gyro's {axis} axis is reversed against the other triad (a left-handed pair: check the logger's or the "
            f"import mapping's sign of acc_{axis} and gyro_{axis})?"]


def _norms(x: np.ndarray, which: np.ndarray) -> np.ndarray:
    """|x| of the rows *which*, a piece of the log at a time (the selected rows of a long log at
    once would be 24 bytes a sample beside the norms)."""
    out = np.empty(int(np.count_nonzero(which)))
    i = 0
    for s in pieces(len(x), x, step=piece_rows(x)):
        v = np.linalg.norm(x[s][which[s]], axis=1)
        out[i:i + len(v)] = v
        i += len(v)
    return out


def _ideal_gyro_moving(data, use: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ideal gyro increments of the moving samples the mask *use* keeps, from the table
    angles, and which samples those are (a mask of the log up to the last of them). Each is its
    interval's chord: the rate (θ_k − θ_{k−1})/Δt at the mid angles, times Δt, the interval's
    rotation to second order in the angle step, where the check reads a ratio to within
    :data:`MATCH` (the spline profile of the moves the estimators use cost a sixth of a diagnose on
    a 40-minute log, for this ratio alone). Only the first :data:`ENOUGH_MOVING` moving samples,
    found a piece of the log at a time (the whole log's mask was two bytes a sample)."""
    n = len(data.time)
    picked, got = [], 0
    for s in pieces(n, data.angles):
        mask = ~data.static[s] & use[s]
        if s.start == 0:
            mask[0] = False  # nothing before the first sample to take a chord from
        k = np.flatnonzero(mask)[:ENOUGH_MOVING - got] + s.start
        picked.append(k)
        got += len(k)
        if got >= ENOUGH_MOVING:
            break
    k = np.concatenate(picked) if picked else np.zeros(0, np.intp)
    upto = int(k[-1]) + 1 if len(k) else 0
    moving = ~data.static[:upto] & use[:upto]
    if upto:
        moving[0] = False
    if not len(k):
        return np.zeros((0, 3)), moving
    return _chords(data, k), moving


def _chords(data, k: np.ndarray) -> np.ndarray:
    """(len(k), 3) the ideal gyro increments of samples *k* (each ≥ 1) as their intervals' chords
    (:func:`_ideal_gyro_moving`)."""
    before, after = data.angles[k - 1], data.angles[k]
    step = (data.times_at(k) - data.times_at(k - 1))[:, None]
    omega, _, _ = data.geometry.motion((before + after) / 2, (after - before) / step)
    return omega * step
