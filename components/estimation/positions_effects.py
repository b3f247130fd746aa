"""Calibration of a log without table angles for any sensor effects of the vocabulary.

The bias, scale factor and misalignment of both sensors are fitted by :mod:`.positions` (its own
model, with Newton's curvature for the headings a MEMS gyro barely sees). Further effects —
nonlinearity, g-sensitivity, drift, temperature, asymmetry, the ones ``diagnose`` names and
``add`` adds — are then fitted jointly with those and the attitudes by Gauss–Newton on the rows
of :mod:`.positions_design`, started from that solution. For the three effects alone the two
give the same estimate (tests/test_positions_effects.py checks it), so the result does not
depend on which one ran.
"""
from __future__ import annotations

import math

import numpy as np

from components.errors import EstimationError
from components.estimation.determinability import undetermined_columns
from components.estimation.log_data import LogData
from components.estimation.positions import SUPPORTED, angle_deg, calibrate_positions
from components.estimation.positions_design import PositionsDesign
from components.estimation.positions_observations import COLOURED_NOT_USED
from components.estimation.positions_result import PositionResult, PositionsFit, RotationResult
from components.model.effects import EFFECTS, parameters_of, parse_effects
from components.model.geometry import rodrigues, skew

STEP_TOL = 1e-4     # iterations stop when no unknown moves by this fraction of its σ
MAX_ITERATIONS = 20


def unsupported_on_positions(effects: list[str]) -> list[str]:
    """Effects a log without table angles cannot hold: the table's own."""
    return [e for e in effects if EFFECTS[e].target == "table"]


def fit_positions(data: LogData, effects, *, noise=None, chunk_s: float = 1.0,
                  temperature_ref: float | None = None) -> PositionsFit:
    """Calibrate *effects* (any sensor effects of the vocabulary) on a log without table angles."""
    effects = parse_effects(effects) if isinstance(effects, str) else list(effects)
    table = unsupported_on_positions(effects)
    if table:
        raise EstimationError(f"effects {', '.join(table)} are the turntable's: a log without table angles "
                              "cannot determine them")
    base_effects = [e for e in effects if e in SUPPORTED] or list(SUPPORTED)
    lat = data.geometry.latitude
    base = calibrate_positions(data.time, data.gyro, data.acc, data.segment, data.segments,
                               effects=base_effects, valid=data.usable, latitude=lat,
                               gravity=data.geometry.gravity, noise=noise, chunk_s=chunk_s)
    extra = [e for e in effects if e not in base_effects]
    if not extra and base_effects == effects and not (noise is not None and noise.coloured):
        return base
    # (the first fit weights its rows with white noise alone; the refinement whitens them with a
    # coloured noise model's every term)
    return refine_positions(data, base, effects, noise=noise, chunk_s=chunk_s, temperature_ref=temperature_ref)


def refine_positions(data: LogData, base: PositionsFit, effects: list[str], *, noise=None, chunk_s: float = 1.0,
                     temperature_ref: float | None = None) -> PositionsFit:
    """*effects* fitted with the attitudes by Gauss–Newton on the rows of
    :class:`~components.estimation.positions_design.PositionsDesign`, started from *base* (a fit of
    :func:`~components.estimation.positions.calibrate_positions` on the same log)."""
    design = PositionsDesign(data, chunk_s=chunk_s, noise=noise, temperature_ref=temperature_ref)
    if design.segs.names != [p.name for p in base.positions]:
        raise EstimationError("the positions of the refinement differ from the first fit's: "
                              f"{design.segs.names} against {[p.name for p in base.positions]}")
    notes = [n for n in base.notes if not (design.noise is not None and n == COLOURED_NOT_USED)]
    requested = [p for p in parameters_of(effects) if p not in base.held]
    # which parameters the rows determine: without the Earth rate's share, so that a gyro scale
    # factor counts as determined only where a turn excites it (as the first fit judges it)
    rd = design.rows(base.attitudes, requested, earth=False)
    na = rd.A.shape[1]
    J = np.hstack([rd.H, rd.A])
    undet = [requested[k] for k in undetermined_columns(J, list(range(len(requested))), list(range(len(requested),
                                                                                            len(requested) + na)))]
    new_undet = [p for p in undet if p not in base.undetermined]
    if new_undet:
        notes.append(f"not determined by these data, held at 0: {', '.join(new_undet)}")
    free = [p for p in requested if p not in undet]
    theta = np.array([base.values().get(p, 0.0) for p in free])
    C = base.attitudes.copy()
    it = 0
    for it in range(1, MAX_ITERATIONS + 1):
        r = design.rows(C, free, theta)
        X = np.hstack([r.H, r.A])
        sc = np.linalg.norm(X, axis=0)
        sc[sc == 0] = 1.0
        sol = np.linalg.lstsq(X / sc, r.y, rcond=None)[0] / sc
        cov = np.linalg.pinv((X / sc).T @ (X / sc)) / np.outer(sc, sc)
        sig = np.sqrt(np.clip(np.diag(cov), 0, None))
        delta = sol[len(free):]
        moved = np.max(np.abs(np.concatenate([sol[:len(free)] - theta, delta]) /
                              np.where(sig > 0, sig, 1.0))) if len(sol) else 0.0
        theta = sol[:len(free)]
        C = design.turn_rest(C, delta)
        if moved < STEP_TOL:
            break
    else:
        notes.append(f"Gauss-Newton stopped after {MAX_ITERATIONS} iterations without converging")
    r = design.rows(C, free, theta)
    X = np.hstack([r.H, r.A])
    sc = np.linalg.norm(X, axis=0)
    sc[sc == 0] = 1.0
    cov = np.linalg.pinv((X / sc).T @ (X / sc)) / np.outer(sc, sc)
    resid = r.y - r.H @ theta
    chi2 = float(resid @ resid)
    nf = len(free)
    return PositionsFit(
        effects=list(effects), parameters=free, value=theta, covariance=cov[:nf, :nf], held=dict(base.held),
        undetermined=list(dict.fromkeys(base.undetermined + undet)), chi2=chi2,
        dof=design.n_rows - nf - na, positions=_rests(design, C, cov[nf:, nf:], resid, r.info),
        rotations=_turns(design, C, resid, r.info, notes), sigma_gyro=design.sg, sigma_acc=design.sa,
        sample_interval=design.dt_med, noise_source=design.noise_source, latitude=base.latitude,
        gravity=design.g, iterations=base.iterations + it, excluded=dict(base.excluded), notes=notes,
        schedule=base.schedule, samples=base.samples, duration=base.duration, attitudes=C,
        temperature_ref=design.T0 if data.temperature is not None else None, noise=design.noise)


def _rests(design: PositionsDesign, C: np.ndarray, cov_att: np.ndarray, resid: np.ndarray,
           info: dict) -> list[PositionResult]:
    """Per rest: its attitude with covariance, its mean residual (unwhitened) and χ²."""
    na = design.na
    raw = resid * np.sqrt(info["variance"]) if design.noise is None else None
    ez_x = skew(np.array([0.0, 0.0, 1.0]))
    out = []
    cdt = np.concatenate([[0.0], np.cumsum(design.dt_samples)])
    for p, name in enumerate(design.segs.names):
        sel = (info["piece"] == p)
        T_p = float(sum(cdt[b] - cdt[a] for q, a, b in design.segs.chunks if q == p))
        s = slice(na * p, na * (p + 1))
        Ju = (C[p].T @ ez_x)[:, :na]
        mean = {}
        for sensor in ("gyro", "acc"):
            m = sel & (info["sensor"] == sensor)
            mean[sensor] = np.array([raw[m & (info["axis"] == k)].sum() / T_p if raw is not None else math.nan
                                     for k in range(3)])
        a, b = design.segs.ranges[p]
        hint = design.data.segment_kinds[design.segs.labels[p]].get("up")
        up = C[p, 2].copy()
        out.append(PositionResult(
            name=name, label=design.segs.labels[p], start=a, stop=b,
            samples=int(sum(e - st for q, st, e in design.segs.chunks if q == p)), duration=T_p, up=up,
            up_covariance=Ju @ cov_att[s, s] @ Ju.T, up_hint=hint,
            hint_angle_deg=None if hint is None else angle_deg(hint, up),
            north=C[p, 1].copy() if na == 3 else None,
            heading_sigma_deg=math.degrees(math.sqrt(max(cov_att[s, s][2, 2], 0.0))) if na == 3 else None,
            acc_residual=mean["acc"], gyro_residual=mean["gyro"], chi2=float(np.sum(resid[sel] ** 2)),
            rows=int(sel.sum())))
    return out


def _turns(design: PositionsDesign, C: np.ndarray, resid: np.ndarray, info: dict,
           notes: list[str]) -> list[RotationResult]:
    """Per turn its residual and how far the rest after it is from where the stated turn puts it."""
    out = []
    for k, r in enumerate(design.turns):
        sel = info["piece"] == design.P + k
        nrm = resid[sel]
        res = nrm * np.sqrt(info["variance"][sel]) if design.noise is None else np.full(3, math.nan)
        u_pred = rodrigues(r.axis, r.angle).T @ C[r.q, 2]
        earth = r.M @ (C[r.q].T @ design.Om)
        out.append(RotationResult(
            name=r.name, label=r.label, start=r.lo, stop=r.hi, axis=r.axis, angle=r.angle, duration=r.T,
            before=r.before, after=r.after, measured=r.sum, earth=earth, residual=res, normalized=nrm,
            end_mismatch_deg=angle_deg(u_pred, C[r.q_after, 2])))
        if out[-1].end_mismatch_deg > 2.0:
            notes.append(f"rotation {r.name!r}: the attitude after it is {out[-1].end_mismatch_deg:.1f}° from the "
                         "one the stated turn predicts: check its axis and angle, and that it is about a body axis")
    return out
