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
"""
from __future__ import annotations

import math

import numpy as np

from components.errors import EstimationError
from components.estimation.blocks import white_noise_sigma
from components.estimation.design import noise_floor
from components.estimation.positions_input import checked_effects, checked_log, parse_kinds, split_segments
from components.estimation.positions_result import PositionResult, PositionsFit, RotationResult
from components.model.effects import AX, DEFAULT_EFFECTS, effect_of
from components.model.geometry import EARTH_RATE, normal_gravity, rodrigues, rotvec, skew
from components.model.result import schedule_of

GAUGE_HELD = ("acc.mis.xy", "acc.mis.xz", "acc.mis.yz")
HELD_WHY = "held at 0 by the gauge (a common rotation of the accelerometer triad is not observable)"
HINT_LIMIT_DEG = 45.0     # a stated 'up' further than this from the measured one is a wrong label
SAME_ATTITUDE_DEG = 2.0   # positions closer than this count as one attitude
ANGLE_TOL = (0.1, 5.0)    # a turn's gyro angle within 10 % + 5° of the stated one
STEP_TOL = 1e-4           # iterations stop when no parameter moves by this fraction of its σ
INDEPENDENT = 1e-6        # fraction of a column not explained by the others, below: undetermined

# internal parameter layout: gyro bias (3), G (9, row-major), acc bias (3), A (9), then attitudes
_GB, _G, _AB, _A, _NCAL = 0, 3, 12, 15, 24


def _cal_names() -> list[str]:
    names = [f"gyro.bias.{c}" for c in AX]
    names += [f"gyro.sf.{AX[i]}" if i == j else f"gyro.mis.{AX[i]}{AX[j]}" for i in range(3) for j in range(3)]
    names += [f"acc.bias.{c}" for c in AX]
    names += [f"acc.sf.{AX[i]}" if i == j else f"acc.mis.{AX[i]}{AX[j]}" for i in range(3) for j in range(3)]
    return names


CAL_NAMES = _cal_names()


def _frame(up: np.ndarray, north: np.ndarray | None) -> np.ndarray:
    """C (body -> ENU) whose rows are east, north and up in the body frame."""
    u = up / np.linalg.norm(up)
    if north is None or np.linalg.norm(north - (north @ u) * u) < 1e-9:
        e = np.zeros(3)
        e[int(np.argmin(np.abs(u)))] = 1.0
        north = e
    n = north - (north @ u) * u
    n /= np.linalg.norm(n)
    return np.vstack([np.cross(n, u), n, u])


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = float(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))
    return math.degrees(math.acos(c))


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
    n = len(t)
    effects = checked_effects(effects)
    desc = parse_kinds(kinds)
    notes: list[str] = []

    dt_all = np.diff(t)
    dt_med = float(np.median(dt_all))
    dt = np.concatenate([[dt_med], dt_all])
    if gravity is None:
        if latitude is None:
            raise EstimationError("the magnitude of gravity is needed (it sets the accelerometer scale): "
                                  "give gravity [m/s²] or the latitude (and height) for normal gravity")
        gravity = normal_gravity(latitude, height)
    g = float(gravity)
    if latitude is None:
        Om = np.zeros(3)
        notes.append("no latitude: the Earth rate (15.04 deg/h) is not modelled; the gyro bias takes its mean "
                     "over the positions, and each turn's share of it (up to Ω T) goes into the gyro "
                     "scale factors and misalignments")
    else:
        Om = EARTH_RATE * np.array([0.0, math.cos(latitude), math.sin(latitude)])
    use_heading = latitude is not None and abs(math.cos(latitude)) > 1e-6
    na = 3 if use_heading else 2

    # ---- segments: positions (in chunks), rotations, excluded
    segs = split_segments(seg, ok, desc, t, dt_med, chunk_s, notes)
    pos_names, pos_label, pos_range, chunk_list = segs.names, segs.labels, segs.ranges, segs.chunks
    use, excluded = segs.use, segs.excluded
    P = len(pos_names)
    ch_p = np.array([c[0] for c in chunk_list])
    ch_a = np.array([c[1] for c in chunk_list])
    ch_b = np.array([c[2] for c in chunk_list])
    cdt = np.concatenate([[0.0], np.cumsum(dt)])
    cg = np.vstack([np.zeros(3), np.cumsum(yg, axis=0)])
    ca = np.vstack([np.zeros(3), np.cumsum(ya, axis=0)])
    ch_T = cdt[ch_b] - cdt[ch_a]
    ch_g = cg[ch_b] - cg[ch_a]
    ch_acc = ca[ch_b] - ca[ch_a]
    T_p = np.bincount(ch_p, ch_T, P)
    S_g = np.column_stack([np.bincount(ch_p, ch_g[:, i], P) for i in range(3)])
    S_a = np.column_stack([np.bincount(ch_p, ch_acc[:, i], P) for i in range(3)])
    n_used = np.bincount(ch_p, ch_b - ch_a, P)

    # ---- noise
    if noise is not None:
        white = np.asarray(noise.white_sigma(dt_med), float)
        est = white_noise_sigma(np.hstack([yg, ya]), use)
        missing = ~(white > 0)
        if np.any(missing):
            white = np.where(missing, est, white)
            notes.append("the noise model has no white term on some channels: their σ is estimated from "
                         "the static data")
        source = f"white part of the given noise model ({noise.source or 'given'})"
        if noise.coloured:
            notes.append("the noise model's coloured terms are not used by the positions method (white part only)")
    else:
        white = white_noise_sigma(np.hstack([yg, ya]), use)
        source = "estimated from the static data"
    sg = noise_floor(white[:3], 7.3e-5 * dt_med)
    sa = noise_floor(white[3:], 9.8 * dt_med)
    dens_g, dens_a = sg / math.sqrt(dt_med), sa / math.sqrt(dt_med)   # per √s

    # ---- initial attitudes, hints, distinct attitudes
    U0 = S_a / np.linalg.norm(S_a, axis=1)[:, None]
    hints = [None] * P
    for p in range(P):
        h = desc[pos_label[p]].get("up")
        if h is not None:
            hints[p] = h
            ang = _angle_deg(h, U0[p])
            if ang > HINT_LIMIT_DEG:
                raise EstimationError(
                    f"static {pos_names[p]!r}: the accelerometers' mean points {ang:.0f}° from the stated up "
                    f"{np.round(h, 3).tolist()} (along {np.round(U0[p], 3).tolist()}): check the segment's 'up'")
    reps: list[np.ndarray] = []
    for u in U0:
        if all(_angle_deg(u, r) > SAME_ATTITUDE_DEG for r in reps):
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

    # ---- rotations: sums, angle profiles, M_r
    pidx = {nm: i for i, nm in enumerate(pos_names)}
    rots = []
    for sp in segs.turns:
        name, lab, lo, hi, axis, angle, before, after = (sp.name, sp.label, sp.lo, sp.hi, sp.axis, sp.angle,
                                                         sp.before, sp.after)
        if before not in pidx or after not in pidx:
            raise EstimationError(f"rotation {name!r}: the static segment on each side needs usable samples")
        s = yg[lo:hi] @ axis
        total = float(s.sum())
        if abs(total - angle) > ANGLE_TOL[0] * abs(angle) + math.radians(ANGLE_TOL[1]):
            raise EstimationError(f"rotation {name!r}: the gyros turn {math.degrees(total):+.1f}° about "
                                  f"{np.round(axis, 3).tolist()}, the segment says {math.degrees(angle):+.1f}°: "
                                  "check its axis and angle")
        theta = (np.cumsum(s) - s / 2) * (angle / total)
        R = rodrigues(axis, theta)
        M = np.einsum("k,kji->ij", dt[lo:hi], R)   # Σ R(a, θ_k)ᵀ Δt_k
        rots.append({"name": name, "label": lab, "lo": lo, "hi": hi, "axis": axis, "angle": angle,
                     "T": float(dt[lo:hi].sum()), "sum": yg[lo:hi].sum(axis=0), "M": M,
                     "q": pidx[before], "before": before, "after": after})
    NR = len(rots)

    # ---- initial headings (latitude given): alternate bias and per-position north
    north0 = [None] * P
    if use_heading:
        rate = S_g / T_p[:, None]
        vert = Om[2] * U0
        bg = np.average(rate - vert, axis=0, weights=T_p)
        for _ in range(30):
            hor = rate - bg - vert
            hor -= np.sum(hor * U0, axis=1)[:, None] * U0
            nb = np.linalg.norm(hor, axis=1)
            nvec = np.where(nb[:, None] > 0, hor / np.where(nb > 0, nb, 1.0)[:, None], 0.0)
            bg = np.average(rate - vert - Om[1] * nvec, axis=0, weights=T_p)
        north0 = [v if np.linalg.norm(v) > 0 else None for v in nvec]
    C = np.array([_frame(U0[p], north0[p]) for p in range(P)])
    theta_cal = np.zeros(_NCAL)

    # ---- the model
    ez_x = skew(np.array([0.0, 0.0, 1.0]))
    om_x = skew(Om)
    nrow = 6 * P + 3 * NR
    sig_row = np.concatenate([(dens_a[None, :] * np.sqrt(T_p)[:, None]).ravel(),
                              (dens_g[None, :] * np.sqrt(T_p)[:, None]).ravel(),
                              np.concatenate([dens_g * math.sqrt(r["T"]) for r in rots]) if NR else []])
    y_obs = np.concatenate([S_a.ravel(), S_g.ravel()] + [r["sum"] for r in rots])
    ncol = _NCAL + na * P

    def unpack(th):
        return th[_GB:_GB + 3], th[_G:_G + 9].reshape(3, 3), th[_AB:_AB + 3], th[_A:_A + 9].reshape(3, 3)

    def model(th, C, jac=True, determinability=False):
        bg, G, ba, A = unpack(th)
        Kg, Ka = np.eye(3) + G, np.eye(3) + A
        U = C[:, 2, :]
        Ob = np.einsum("pij,i->pj", C, Om)
        f = g * U
        pa = T_p[:, None] * (f @ Ka.T + ba)
        pg = T_p[:, None] * (Ob @ Kg.T + bg)
        v = [r["angle"] * r["axis"] + r["M"] @ Ob[r["q"]] for r in rots]
        pr = [Kg @ vr + bg * r["T"] for vr, r in zip(v, rots)]
        pred = np.concatenate([pa.ravel(), pg.ravel()] + pr)
        if not jac:
            return pred, None
        J = np.zeros((nrow, ncol))
        for p in range(P):
            att = slice(_NCAL + na * p, _NCAL + na * (p + 1))
            Da = Ka @ (g * C[p].T @ ez_x)
            Dg = Kg @ (C[p].T @ om_x)
            for i in range(3):
                ra, rg = 3 * p + i, 3 * P + 3 * p + i
                J[ra, _AB + i] = T_p[p]
                J[ra, _A + 3 * i:_A + 3 * i + 3] = T_p[p] * f[p]
                J[ra, att] = T_p[p] * Da[i, :na]
                J[rg, _GB + i] = T_p[p]
                if not determinability:
                    J[rg, _G + 3 * i:_G + 3 * i + 3] = T_p[p] * Ob[p]
                J[rg, att] = T_p[p] * Dg[i, :na]
        for k, r in enumerate(rots):
            q = r["q"]
            att = slice(_NCAL + na * q, _NCAL + na * (q + 1))
            Dr = Kg @ (r["M"] @ C[q].T @ om_x)
            vr = r["angle"] * r["axis"] if determinability else v[k]
            for i in range(3):
                row = 6 * P + 3 * k + i
                J[row, _GB + i] = r["T"]
                J[row, _G + 3 * i:_G + 3 * i + 3] = vr
                J[row, att] = Dr[i, :na]
        return pred, J / sig_row[:, None]

    # ---- which requested parameters the data determine (pivoted QR after the attitudes)
    req_cols = [CAL_NAMES.index(p) for p in requested]
    att_cols = list(range(_NCAL, ncol))
    _, Jd = model(theta_cal, C, determinability=True)
    undetermined = _undetermined(Jd, req_cols, att_cols)
    if undetermined:
        names = [CAL_NAMES[c] for c in undetermined]
        notes.append(f"not determined by these data, held at 0: {', '.join(names)}")
    free = [c for c in req_cols if c not in undetermined]
    cols = free + att_cols

    # ---- Gauss-Newton
    def chi2_of(th, C):
        pred, _ = model(th, C, jac=False)
        r = (y_obs - pred) / sig_row
        return float(r @ r)

    def step_to(th, C, d):
        th2 = th.copy()
        th2[free] += d[:len(free)]
        phi = d[len(free):].reshape(P, na)
        if na == 2:
            phi = np.hstack([phi, np.zeros((P, 1))])
        C2 = np.einsum("pij,pjk->pik", rotvec(phi), C)
        return th2, C2

    Om_h = np.array([Om[0], Om[1], 0.0])
    head = [len(free) + na * p + 2 for p in range(P)] if use_heading else []

    def heading_curvature(th, C, r):
        """Σ_i r_i ∂²(pred_i/σ_i)/∂ψ_p² per position's heading ψ_p with the sign of the cost's
        Hessian: a heading turns the horizontal Earth rate, ∂²(C_pᵀ Ω_n)/∂ψ² = −C_pᵀ Ω_h."""
        _, G, _, _ = unpack(th)
        Kg = np.eye(3) + G
        out = np.zeros(P)
        for p in range(P):
            rows = slice(3 * P + 3 * p, 3 * P + 3 * p + 3)
            out[p] += r[rows] @ (T_p[p] * Kg @ C[p].T @ Om_h / sig_row[rows])
        for k, rt in enumerate(rots):
            rows = slice(6 * P + 3 * k, 6 * P + 3 * k + 3)
            out[rt["q"]] += r[rows] @ (Kg @ rt["M"] @ C[rt["q"]].T @ Om_h / sig_row[rows])
        return out

    # Gauss-Newton, with Newton's curvature for the headings: a heading known to ~15° (MEMS gyros)
    # has a residual curvature comparable to its information, and Gauss-Newton alone then
    # crawls (steps shrinking by 0.9 per iteration were seen) or overshoots
    it = 0
    for it in range(1, max_iterations + 1):
        pred, J = model(theta_cal, C)
        r = (y_obs - pred) / sig_row
        Js = J[:, cols]
        sc = np.linalg.norm(Js, axis=0)
        sc[sc == 0] = 1.0
        Jn = Js / sc
        H = Jn.T @ Jn
        grad = Jn.T @ r
        if head:
            curv = heading_curvature(theta_cal, C, r) / sc[head] ** 2
            H[head, head] += np.maximum(curv, -0.5 * H[head, head])
        try:
            d = np.linalg.solve(H, grad)
        except np.linalg.LinAlgError:
            d, *_ = np.linalg.lstsq(Jn, r, rcond=None)
        size = float(np.max(np.abs(d))) if len(d) else 0.0
        d = d / sc
        old = float(r @ r)
        lam = 1.0
        for _ in range(30):
            th2, C2 = step_to(theta_cal, C, lam * d)
            if chi2_of(th2, C2) <= old * (1 + 1e-12) + 1e-12:
                break
            lam /= 2
        theta_cal, C = th2, C2
        if size * lam < STEP_TOL:
            break
    else:
        notes.append(f"Gauss-Newton stopped after {max_iterations} iterations without converging")

    pred, J = model(theta_cal, C)
    Js = J[:, cols]
    sc = np.linalg.norm(Js, axis=0)
    sc[sc == 0] = 1.0
    cov_all = np.linalg.pinv((Js / sc).T @ (Js / sc)) / np.outer(sc, sc)
    nf = len(free)
    cov = cov_all[:nf, :nf]

    # ---- χ² on the chunks, residuals per position and rotation
    bg, G, ba, A = unpack(theta_cal)
    Kg, Ka = np.eye(3) + G, np.eye(3) + A
    U = C[:, 2, :]
    Ob = np.einsum("pij,i->pj", C, Om)
    mu_a = g * U @ Ka.T + ba        # per position, rate units
    mu_g = Ob @ Kg.T + bg
    res_a = ch_acc - ch_T[:, None] * mu_a[ch_p]
    res_g = ch_g - ch_T[:, None] * mu_g[ch_p]
    wa = res_a / (dens_a[None, :] * np.sqrt(ch_T)[:, None])
    wg = res_g / (dens_g[None, :] * np.sqrt(ch_T)[:, None])
    chi_c = np.sum(wa**2, axis=1) + np.sum(wg**2, axis=1)
    chi_pos = np.bincount(ch_p, chi_c, P)
    rot_out = []
    for k, r in enumerate(rots):
        res = r["sum"] - pred[6 * P + 3 * k:6 * P + 3 * k + 3]
        nrm = res / sig_row[6 * P + 3 * k:6 * P + 3 * k + 3]
        after = pidx[r["after"]]
        u_pred = rodrigues(r["axis"], r["angle"]).T @ U[r["q"]]
        rot_out.append(RotationResult(
            name=r["name"], label=r["label"], start=r["lo"], stop=r["hi"], axis=r["axis"], angle=r["angle"],
            duration=r["T"], before=r["before"], after=r["after"], measured=r["sum"],
            earth=r["M"] @ Ob[r["q"]], residual=res, normalized=nrm, end_mismatch_deg=_angle_deg(u_pred, U[after])))
    chi2 = float(chi_pos.sum() + sum(ro.chi2 for ro in rot_out))
    dof = 6 * len(ch_p) + 3 * NR - len(cols)
    for ro in rot_out:
        if ro.end_mismatch_deg > 2.0:
            notes.append(f"rotation {ro.name!r}: the attitude after it is {ro.end_mismatch_deg:.1f}° from the one "
                         "the stated turn predicts: check its axis and angle, and that it is about a body axis")

    pos_out = []
    for p in range(P):
        s = slice(nf + na * p, nf + na * (p + 1))
        Cp = cov_all[s, s]
        Ju = (C[p].T @ ez_x)[:, :na]
        ucov = Ju @ Cp @ Ju.T
        a, b = pos_range[p]
        sel = ch_p == p
        pos_out.append(PositionResult(
            name=pos_names[p], label=pos_label[p], start=a, stop=b, samples=int(n_used[p]), duration=float(T_p[p]),
            up=U[p].copy(), up_covariance=ucov, up_hint=hints[p],
            hint_angle_deg=None if hints[p] is None else _angle_deg(hints[p], U[p]),
            north=C[p, 1].copy() if use_heading else None,
            heading_sigma_deg=math.degrees(math.sqrt(max(Cp[2, 2], 0.0))) if use_heading else None,
            acc_residual=res_a[sel].sum(axis=0) / T_p[p], gyro_residual=res_g[sel].sum(axis=0) / T_p[p],
            chi2=float(chi_pos[p]), rows=int(6 * sel.sum())))

    if "acc.mis" in effects:
        notes.append("gauge: acc.mis.xy, acc.mis.xz, acc.mis.yz held at 0 (the accelerometer triad defines the "
                     "body frame's x axis and x-y plane; see docs/positions.md)")
    return PositionsFit(
        effects=list(effects), parameters=[CAL_NAMES[c] for c in free], value=theta_cal[free].copy(),
        covariance=cov, held=held, undetermined=[CAL_NAMES[c] for c in undetermined], chi2=chi2, dof=dof,
        positions=pos_out, rotations=rot_out, sigma_gyro=sg, sigma_acc=sa, sample_interval=dt_med,
        noise_source=source, latitude=latitude, gravity=g, iterations=it, excluded=excluded, notes=notes,
        schedule=schedule_of(t, seg), samples=n, duration=float(t[-1] - t[0] + dt_med))


def _undetermined(J: np.ndarray, req: list[int], nuisance: list[int]) -> list[int]:
    """Requested columns the rows cannot determine: with every column scaled to unit length,
    the attitude columns projected out, a column-pivoted QR; a column with less than
    INDEPENDENT of its length outside the span of the ones before it is undetermined."""
    from scipy.linalg import qr

    def unit(M):
        s = np.linalg.norm(M, axis=0)
        return M / np.where(s > 0, s, 1.0), s > 0

    N, _ = unit(J[:, nuisance])
    Q, R, _ = qr(N, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    Q = Q[:, d > INDEPENDENT * (d.max() if len(d) else 1.0)]
    X, nonzero = unit(J[:, req])
    X = X - Q @ (Q.T @ X)
    out = [req[k] for k in np.nonzero(~nonzero)[0]]
    keep = [k for k in range(len(req)) if nonzero[k]]
    if keep:
        _, R2, piv = qr(X[:, keep], mode="economic", pivoting=True)
        d2 = np.abs(np.diag(R2))
        out += [req[keep[piv[k]]] for k in range(len(d2)) if d2[k] < INDEPENDENT]
        out += [req[keep[piv[k]]] for k in range(len(d2), len(keep))]
    return sorted(out)
