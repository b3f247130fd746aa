"""Calibration without a turntable: a multi-position session (Ferraris et al. 1995; Tedaldi et
al. 2014), by hand or on any rig that logs no angles.

The IMU rests in N attitudes the calibration is not told (or told only roughly which body axis is
up), is moved by hand in between (those samples are excluded), and is turned from rest to rest
through a known total angle about a body axis (e.g. 360° about x). All inputs are explicit arrays
in SI, so any log reader can feed it: time, increments per sample, a segment label per sample,
what each label is (``kinds``, the ``segments`` block of docs/measurement-log.md, version 2) and
an optional mask of usable samples.

Sensor model (components.model.effects, the IMU FMU): y = (I + K) x + b per sensor, with K's
diagonal the scale factors (``*.sf.i``) and K_ij (i ≠ j) the misalignments (``*.mis.ij``, axis i's
sensitivity to x_j); A = K of the accelerometers, G = K of the gyros.

Rows (block sums of increments, white noise per sample):

- a static position p, over each chunk of about ``chunk_s`` [s] of duration T_c:
  accelerometer  Σ Δv = T_c [(I + A) g u_p + b_a],  u_p = C_pᵀ e_up the body-frame up vector;
  gyro           Σ Δθ = T_c [(I + G) C_pᵀ Ω_n + b_g],  Ω_n = Ω (0, cos L, sin L) in ENU.
  C_p (body → ENU) is a nuisance attitude per position: its tilt (2 angles) always, its heading
  (1 angle) only when the latitude is given; g is the site's gravity, known.
- a rotation r about the body axis a by the known angle θ, summed from the last rest sample
  before it to the first rest sample after it (duration T_r):
  Σ Δθ = (I + G) (θ a + M_r C_qᵀ Ω_n) + b_g T_r,  M_r = Σ_k R(a, θ_k)ᵀ Δt_k,
  q the static position before it, θ_k the angle turned at sample k (from the gyro itself: its
  errors change M_r by ~1e-9 rad). For a rotation about an axis fixed in the body this is exact
  and linear in G and b_g (∫ω dt = θ a for a single-axis turn, whatever its rate profile).

  What is approximated is the turn itself: the axis is the reference of the gyro misalignments.
  An axis off the stated one by δ [rad] moves the off-axis components θ G_ia one for one (δ =
  0.1° is 360″ of misalignment) and the scale factor by δ²/2 (1.5 ppm at 0.1°). A hand that does
  not turn about a fixed axis adds the coning term ½∫φ × ω dt, second order in the wobble. All
  three components of the summed increments are fitted, not their norm: the norm alone,
  2π √((1 + G_aa)² + G_ya² + G_za²), couples the two misalignments of a 360° turn into the scale
  factor by 2π (G_ya² + G_za²)/2, 24 ppm at 1000″ each.

Estimation: Gauss–Newton on the calibration parameters and the attitudes jointly, rows whitened
by the white noise: per-sample σ from the static data (consecutive differences,
components.estimation.blocks.white_noise_sigma) or the white part of a given noise model. With
white noise the chunk sums of a position enter the estimate only through their total, so the fit
runs on one sum per position and sensor (the same estimate and covariance) and χ² is taken over
the chunks (its within-position part does not depend on the parameters). Covariance (JᵀJ)⁻¹ of
the whitened Jacobian at the solution; χ²/dof with dof = chunk and rotation rows − parameters.

The gauge (what no data of this kind can tell): gravity's direction is free at every position,
so a common rotation of the accelerometer triad is invisible — only its non-orthogonality is
observable; a 360° turn returns to its start, so it does not tie the accelerometers to the turn's
axis either. The body frame B is therefore the frame the rotations' axes (and ``up`` hints) are
stated in, and the accelerometer triad is taken lower-triangular in it:

    acc x sensitive axis ∥ B x,  acc y sensitive axis in B's x–y plane:
    acc.mis.xy = acc.mis.xz = acc.mis.yz ≡ 0,   I + A lower triangular.

A true triad I + A_t is reported as the lower-triangular factor L of I + A_t = L Q (Q a rotation,
L with a positive diagonal); to first order acc.mis.yx → yx + xy, zx → zx + xz, zy → zy + yz
(the sums are the non-orthogonality), the biases and scale factors unchanged, the attitudes u_p
rotated by Q. The gyro parameters are relative to B (the turns' axes), so a gyro triad's
misalignment is observable from turns about several axes and only about the axes turned about.
The gauge's price is the Earth rate: it is placed along the accelerometer's up vector, which is
off by Q's angle ρ, an error ≤ Ω ρ in the gyro rows (0.07 deg/h at ρ = 1000″).

This module runs the method's steps in order and reports per rest and turn; the steps live in
:mod:`.positions_input` (the description checked, the samples sorted into rests and turns),
:mod:`.positions_observations` (the rows), :mod:`.positions_model` (their prediction and
Jacobian), :mod:`.positions_solve` (which parameters are determined, Gauss–Newton, covariance)
and :mod:`.positions_result` (what is returned).
"""
from __future__ import annotations

import math

import numpy as np

from components.errors import EstimationError
from components.estimation.positions_input import (
    SUPPORTED,
    Segments,
    checked_effects,
    checked_log,
    parse_kinds,
    split_segments,
)
from components.estimation.positions_model import CAL_NAMES, Model, starting_frames, unpack
from components.estimation.positions_observations import reduce_rests, reduce_turns, white_sigmas
from components.estimation.positions_result import GAUGE, PositionResult, PositionsFit, RotationResult
from components.estimation.positions_solve import covariance, determined, gauss_newton
from components.model.effects import DEFAULT_EFFECTS, effect_of
from components.model.geometry import EARTH_RATE, normal_gravity, rodrigues, skew
from components.model.result import schedule_of

# callers take the method's names from here, whichever module below defines them
__all__ = ["calibrate_positions", "parse_kinds", "PositionsFit", "PositionResult", "RotationResult", "CAL_NAMES",
           "GAUGE", "SUPPORTED"]

GAUGE_HELD = ("acc.mis.xy", "acc.mis.xz", "acc.mis.yz")
HELD_WHY = "held at 0 by the gauge (a common rotation of the accelerometer triad is not observable)"
HINT_LIMIT_DEG = 45.0     # a stated 'up' further than this from the measured one is a wrong label
SAME_ATTITUDE_DEG = 2.0   # positions closer than this count as one attitude


def calibrate_positions(time, gyro_inc, acc_inc, segment, kinds, *, effects=DEFAULT_EFFECTS, valid=None,
                        latitude: float | None = None, height: float = 0.0, gravity: float | None = None,
                        noise=None, chunk_s: float = 1.0, max_iterations: int = 50) -> PositionsFit:
    """Calibrate from static positions of unknown attitude and rotations of known angle.

    ``time`` (N,) [s] end of each sample's interval; ``gyro_inc`` (N, 3) [rad], ``acc_inc`` (N, 3)
    [m/s] increments per sample; ``segment`` (N,) a label per sample; ``kinds`` what each label
    is (:func:`parse_kinds`; a label it does not list is excluded, and said so); ``valid`` (N,)
    bool, False for samples to leave out (gaps, a mask); ``latitude`` [rad]: with it the Earth
    rate is modelled (its vertical part known, a heading per position estimated), without it
    ignored; ``gravity`` [m/s²], default WGS-84 normal gravity at ``latitude`` and ``height``
    [m]; ``noise`` a components.model.noise.NoiseModel whose white part weights the rows
    (default: white σ from the static data); ``chunk_s`` [s] the static blocks of χ².
    ``effects``: a subset of gyro/acc bias, sf, mis. Raises EstimationError for what the data
    cannot give (too few attitudes, a rotation not between rests, a label the data contradict)."""
    t, yg, ya, seg, ok = checked_log(time, gyro_inc, acc_inc, segment, valid)
    effects = checked_effects(effects)
    desc = parse_kinds(kinds)
    notes: list[str] = []

    dt_all = np.diff(t)
    dt_med = float(np.median(dt_all))
    dt = np.concatenate([[dt_med], dt_all])
    g, Om = _gravity_and_earth_rate(latitude, height, gravity, notes)
    use_heading = latitude is not None and abs(math.cos(latitude)) > 1e-6

    segs = split_segments(seg, ok, desc, t, dt_med, chunk_s, notes)
    rests = reduce_rests(segs, yg, ya, dt)
    sg, sa, source = white_sigmas(noise, yg, ya, segs.use, dt_med, notes)
    U0 = rests.S_a / np.linalg.norm(rests.S_a, axis=1)[:, None]
    hints = _checked_hints(U0, segs, desc)
    held, requested = _parameters(effects, U0)
    turns = reduce_turns(segs, yg, dt)

    model = Model(rests, turns, g, Om, 3 if use_heading else 2, sg / math.sqrt(dt_med), sa / math.sqrt(dt_med))
    theta = np.zeros(len(CAL_NAMES))
    C = starting_frames(U0, rests, Om, use_heading)
    free, undetermined = determined(model, theta, C, requested, notes)
    theta, C, it = gauss_newton(model, theta, C, free, max_iterations, notes)
    cov_all = covariance(model, theta, C, free)
    nf = len(free)

    pos_out, chi_pos = _rest_results(model, theta, C, cov_all, nf, segs, hints)
    rot_out = _turn_results(model, theta, C, notes)
    chi2 = float(chi_pos.sum() + sum(ro.chi2 for ro in rot_out))
    dof = 6 * len(rests.chunk_rest) + 3 * len(turns) - (nf + len(model.attitude_columns))
    if "acc.mis" in effects:
        notes.append("gauge: acc.mis.xy, acc.mis.xz, acc.mis.yz held at 0 (the accelerometer triad defines the "
                     "body frame's x axis and x-y plane; see docs/positions.md)")
    return PositionsFit(
        effects=list(effects), parameters=[CAL_NAMES[c] for c in free], value=theta[free].copy(),
        covariance=cov_all[:nf, :nf], held=held, undetermined=[CAL_NAMES[c] for c in undetermined], chi2=chi2,
        dof=dof, positions=pos_out, rotations=rot_out, sigma_gyro=sg, sigma_acc=sa, sample_interval=dt_med,
        noise_source=source, latitude=latitude, gravity=g, iterations=it, excluded=segs.excluded, notes=notes,
        schedule=schedule_of(t, seg), samples=len(t), duration=float(t[-1] - t[0] + dt_med), attitudes=C)


def _gravity_and_earth_rate(latitude: float | None, height: float, gravity: float | None,
                            notes: list[str]) -> tuple[float, np.ndarray]:
    """g [m/s²] and the Earth rate in ENU (zero without the latitude, which is said in ``notes``)."""
    if gravity is None:
        if latitude is None:
            raise EstimationError("the magnitude of gravity is needed (it sets the accelerometer scale): "
                                  "give gravity [m/s²] or the latitude (and height) for normal gravity")
        gravity = normal_gravity(latitude, height)
    if latitude is None:
        Om = np.zeros(3)
        notes.append("no latitude: the Earth rate (15.04 deg/h) is not modelled; the gyro bias takes its mean "
                     "over the positions, and each turn's share of it (up to Ω T) goes into the gyro "
                     "scale factors and misalignments")
    else:
        Om = EARTH_RATE * np.array([0.0, math.cos(latitude), math.sin(latitude)])
    return float(gravity), Om


def _checked_hints(U0: np.ndarray, segs: Segments, desc: dict) -> list[np.ndarray | None]:
    """Each rest's stated up (or None); one far from the accelerometers' mean is a wrong label."""
    P = len(U0)
    hints = [None] * P
    for p in range(P):
        h = desc[segs.labels[p]].get("up")
        if h is not None:
            hints[p] = h
            ang = angle_deg(h, U0[p])
            if ang > HINT_LIMIT_DEG:
                raise EstimationError(
                    f"static {segs.names[p]!r}: the accelerometers' mean points {ang:.0f}° from the stated up "
                    f"{np.round(h, 3).tolist()} (along {np.round(U0[p], 3).tolist()}): check the segment's 'up'")
    return hints


def _parameters(effects: list[str], U0: np.ndarray) -> tuple[dict[str, str], list[str]]:
    """The parameters held by the gauge and those requested; too few distinct attitudes for the
    requested accelerometer parameters is an EstimationError."""
    P = len(U0)
    reps: list[np.ndarray] = []
    for u in U0:
        if all(angle_deg(u, r) > SAME_ATTITUDE_DEG for r in reps):
            reps.append(u)
    held = {p: HELD_WHY for p in GAUGE_HELD if "acc.mis" in effects}
    requested = [p for p in CAL_NAMES if effect_of(p).name in effects and p not in held]
    n_acc = sum(1 for p in requested if p.startswith("acc."))
    if len(reps) < n_acc:
        raise EstimationError(
            f"{len(reps)} distinct attitude(s) ({P} static segment(s)) determine at most {len(reps)} accelerometer "
            f"parameters: each position's unknown direction of gravity takes 2 of its 3 equations. The "
            f"{n_acc} accelerometer parameters of {', '.join(e for e in effects if e.startswith('acc.'))} need "
            f"at least {n_acc} positions in different attitudes (more than {SAME_ATTITUDE_DEG:g}° apart; 12 or "
            f"more recommended), or fewer effects")
    return held, requested


def _rest_results(model: Model, th: np.ndarray, C: np.ndarray, cov_all: np.ndarray, nf: int, segs: Segments,
                  hints: list) -> tuple[list[PositionResult], np.ndarray]:
    """Per rest its attitude with covariance and its residuals, and each rest's χ² over its
    chunks (the fit needs only each rest's total; the module docstring says why χ² is over the
    chunks all the same)."""
    rests, P, na, use_heading = model.rests, model.P, model.na, model.na == 3
    ch_p, ch_T, T_p = rests.chunk_rest, rests.chunk_T, rests.T
    bg, G, ba, A = unpack(th)
    Kg, Ka = np.eye(3) + G, np.eye(3) + A
    U = C[:, 2, :]
    Ob = np.einsum("pij,i->pj", C, model.Om)
    mu_a = model.g * U @ Ka.T + ba        # per position, rate units
    mu_g = Ob @ Kg.T + bg
    res_a = rests.chunk_a - ch_T[:, None] * mu_a[ch_p]
    res_g = rests.chunk_g - ch_T[:, None] * mu_g[ch_p]
    wa = res_a / (model.dens_a[None, :] * np.sqrt(ch_T)[:, None])
    wg = res_g / (model.dens_g[None, :] * np.sqrt(ch_T)[:, None])
    chi_c = np.sum(wa**2, axis=1) + np.sum(wg**2, axis=1)
    chi_pos = np.bincount(ch_p, chi_c, P)
    ez_x = skew(np.array([0.0, 0.0, 1.0]))
    pos_out = []
    for p in range(P):
        s = slice(nf + na * p, nf + na * (p + 1))
        Cp = cov_all[s, s]
        Ju = (C[p].T @ ez_x)[:, :na]
        ucov = Ju @ Cp @ Ju.T
        a, b = segs.ranges[p]
        sel = ch_p == p
        pos_out.append(PositionResult(
            name=segs.names[p], label=segs.labels[p], start=a, stop=b, samples=int(rests.samples[p]),
            duration=float(T_p[p]), up=U[p].copy(), up_covariance=ucov, up_hint=hints[p],
            hint_angle_deg=None if hints[p] is None else angle_deg(hints[p], U[p]),
            north=C[p, 1].copy() if use_heading else None,
            heading_sigma_deg=math.degrees(math.sqrt(max(Cp[2, 2], 0.0))) if use_heading else None,
            acc_residual=res_a[sel].sum(axis=0) / T_p[p], gyro_residual=res_g[sel].sum(axis=0) / T_p[p],
            chi2=float(chi_pos[p]), rows=int(6 * sel.sum())))
    return pos_out, chi_pos


def _turn_results(model: Model, th: np.ndarray, C: np.ndarray, notes: list[str]) -> list[RotationResult]:
    """Per turn its residual and how far the rest after it is from where the stated turn puts
    it; far means a wrong axis or angle, or a turn not about a body axis, which is said in
    ``notes``."""
    P, pred, sig_row = model.P, model.predict(th, C), model.sig_row
    U = C[:, 2, :]
    Ob = np.einsum("pij,i->pj", C, model.Om)
    rot_out = []
    for k, r in enumerate(model.turns):
        res = r.sum - pred[6 * P + 3 * k:6 * P + 3 * k + 3]
        nrm = res / sig_row[6 * P + 3 * k:6 * P + 3 * k + 3]
        u_pred = rodrigues(r.axis, r.angle).T @ U[r.q]
        rot_out.append(RotationResult(
            name=r.name, label=r.label, start=r.lo, stop=r.hi, axis=r.axis, angle=r.angle,
            duration=r.T, before=r.before, after=r.after, measured=r.sum,
            earth=r.M @ Ob[r.q], residual=res, normalized=nrm, end_mismatch_deg=angle_deg(u_pred, U[r.q_after])))
    for ro in rot_out:
        if ro.end_mismatch_deg > 2.0:
            notes.append(f"rotation {ro.name!r}: the attitude after it is {ro.end_mismatch_deg:.1f}° from the one "
                         "the stated turn predicts: check its axis and angle, and that it is about a body axis")
    return rot_out


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """The angle between two vectors [deg]."""
    c = float(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))
    return math.degrees(math.acos(c))
