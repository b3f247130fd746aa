"""The system-level error-state Kalman filter (domain.md §7).

State: the 9 navigation errors ``[φE φN φU δVE δVN δVU δL δλ δh]`` followed by the residuals
of any chosen effect parameters (vocabulary names, each a random constant: x_θ = θ − θ̂).

Dynamics, per navigation step T (two samples), with C the attitude at the step's midpoint and
δω_ib^b = G x_θ, δf^b = A x_θ from the effects' regressors on the measured motion
(components.navigation.sensor)::

    φ̇  = φ × ω_ie^n − C δω          δv̇ = f^n × φ + C δf − 2 ω_ie^n × δv
    δL̇ = δV_N / R_M                 δλ̇ = δV_E / (R_N cos L)          δḣ = δV_U

discretised per step as ``x ← A_k x + B_k x_θ`` (A_k = I + F T + (F T)²/2, B_k the integrated
regressors mapped by C) and accumulated over the filter interval into the transition matrix
``Φ = [[ΠA, ΣΠA B], [0, I]]``; process noise from the white noise per sample (ARW on φ, VRW on
δv) accumulated the same way.

Prediction and update: filterpy's ``KalmanFilter`` (predict: P = Φ P Φᵀ + Q; update: Joseph form).
Observation: the navigation velocity (the truth is zero) in filter intervals whose samples are
all static (or in every interval, ``observe="always"``). After each update the navigation
errors are fed back (attitude, velocity and position corrected, their states reset to zero).
The effects, by default, are not fed back during a pass: the sensor data stay corrected with the pass's
linearisation point θ_lin and the effect states accumulate x_θ, so the pass ends with
θ̂ = θ_lin + x_θ, the posterior mode of the problem linearised at θ_lin with the prior kept where
it was (initial state x_θ = θ_prior − θ_lin). Repeated passes re-linearise at the previous
pass's θ̂: a Gauss–Newton iteration to the posterior mode that the covariance describes.
(``effect_feedback=True`` feeds θ̂ back at every update, as the smoother needs; its passes
re-centre the prior on the previous estimate, which walks them along weakly observable
directions while the covariance still counts the prior: NEES up to 132 for 30 states on a
12-minute seed-003 run.)

Coloured noise states (``noise_states``): a sensor's bias instability and random walk are not
white, and a filter that takes them for white noise is inconsistent (its innovations correlate
over minutes, its σ too small: seed 003 under a 0.005 deg/h / 10 ug flicker floor, estimates up
to 13σ off). Each channel's slow noise becomes states after the effects': each Gauss–Markov term
(σ, T) of it (a flicker floor as its sum of them, components.model.flicker) x' = φ x + w over a
filter interval Δ (φ = e^(−Δ/T), var w = σ² (1 − φ²), starting at its stationary σ²), a random walk
K as x' = x + w (var w = K² Δ, starting at 0: the bias parameter holds the start). Each enters the
navigation errors as a bias of its channel held over the interval (error ~Δ/T of its term); terms
much faster than the interval (T < 5 Δ) are white noise of power spectral density 2 σ² T instead.

Consider states (``consider``, a Schmidt–Kalman filter): parameters an earlier stage estimated
and this one keeps. They are states (their uncertainty drives the navigation errors through
their regressors, and their cross-covariance with the estimated states is kept) but the gain's
rows for them are zero, so they are never updated; the Joseph form keeps P exact for that
sub-optimal gain. Without them a reduced filter (seed 003's 12-state bias stage) believes
the other parameters perfect and reports too small a σ. The joint prior of estimated and
consider states is ``prior_cov`` (from the earlier stage).

RTS smoother (``smoother=True``): the filter's (Φ, P⁻, P⁺, x⁺) are kept and run backwards; the
feedback is a known input (x⁻_{k+1} = Φ (x⁺_k − u_k) = 0), so ``x^s_k = x⁺_k + C_k x^s_{k+1}``,
``C_k = P⁺_k Φᵀ (P⁻_{k+1})⁻¹``. For the random-constant effect states the smoothed value at
every step equals the final filtered one (a check); the smoother gives the navigation-error
history (attitude and velocity errors over the run). It keeps 3 (n×n) matrices per interval.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import KalmanFilter

from components.model.effects import effect_of
from components.model.geometry import skew
from components.navigation.earth import Site
from components.navigation.strapdown import Strapdown, rot

# Per-sample noise floors [rad], [m/s]: noise-free data still carry the filter's own numerical
# floor (linearisation, the discretised error model: ~1e-3 deg/h, 0.05 ug, 0.05 ppm seen), and a
# filter told the noise is 1e-12 rad reports σ a thousand times below it, which makes a later
# stage's consider states (their covariance) wrong by as much. 1e-10 rad and 1e-9 m/s per sample
# are 5e-5 deg/sqrt(h) and 0.02 ug/sqrt(Hz) at 200 Hz: 40x below navigation grade.
SIGMA_GYRO_FLOOR = 1e-10
SIGMA_ACC_FLOOR = 1e-9

NAV_STATES = ["phi.E", "phi.N", "phi.U", "dv.E", "dv.N", "dv.U", "dpos.L", "dpos.lon", "dpos.h"]
FAST_TERM = 5.0  # a Gauss–Markov term with T below this many filter intervals is white noise to it


@dataclass(frozen=True)
class NoiseState:
    """One state of a channel's slow noise (rate units: rad/s or m/s²)."""

    channel: int      # 0-2 gyro x y z, 3-5 accelerometer x y z
    sigma: float      # Gauss–Markov: stationary σ; random walk: K [unit/√s]
    T: float          # Gauss–Markov time constant [s]; math.inf: a random walk

    def transition(self, interval: float) -> tuple[float, float]:
        """(φ, var w) over *interval* seconds."""
        if math.isinf(self.T):
            return 1.0, self.sigma**2 * interval
        phi = math.exp(-interval / self.T)
        return phi, self.sigma**2 * (1.0 - phi * phi)


def noise_states(noise, kf_interval: float, span: float) -> tuple[list[NoiseState], np.ndarray]:
    """The slow-noise states of a composite noise model (components.model.noise.NoiseModel) for
    a filter of *kf_interval* over a run of *span* seconds, and (6,) the white power spectral
    density [unit²·s] of its terms too fast for the filter's states (to add to the white noise).
    A flicker floor without its own range is realised over [kf_interval, span]."""
    states, fast = [], np.zeros(6)
    for c, ch in enumerate(noise.channels):
        for sigma, T in ch.gm_terms(FAST_TERM * kf_interval, max(span, 2 * FAST_TERM * kf_interval)):
            if T < FAST_TERM * kf_interval:
                fast[c] += 2.0 * sigma**2 * T
            else:
                states.append(NoiseState(c, float(sigma), float(T)))
        if ch.random_walk > 0:
            states.append(NoiseState(c, float(ch.random_walk), math.inf))
    return states, fast


@dataclass
class FilterSettings:
    parameters: list[str]
    kf_interval: float = 0.1          # s between predictions / updates
    passes: int = 2
    phi0: tuple = (1e-3, 1e-3, 1e-2)  # initial attitude σ [rad] (level, level, heading)
    v0: float = 1e-3                  # m/s
    pos0: float = 1e-6                # rad / m
    prior_sigma: dict = field(default_factory=dict)  # parameter -> σ of the prior; default:
    prior_scale: float = 10.0         # prior_scale × the effect's typical magnitude
    initial: dict = field(default_factory=dict)      # starting estimates
    sigma_gyro: object = None         # per-sample white noise [rad] (None: from static data)
    sigma_acc: object = None          # [m/s]
    r_vel: float | None = None        # observation σ [m/s]; default: from the noise
    observe: str = "static"           # "static" or "always"
    # external table: the IMU sits off the rotation centre, which is what rests, so the position
    # (truth: the start) is observed too and the outer lever arm (the diagonal acc.lever.i.i of
    # a full 9-term lever model) becomes observable from the displacement (R − I) r
    observe_position: bool = False
    r_pos: float = 1e-4               # position observation σ [m]
    smoother: bool = False
    history_every: int = 1            # record θ̂ and σ every n updates
    consider: list = field(default_factory=list)   # kept, not updated (Schmidt–Kalman)
    effect_feedback: bool = False     # effects fed back at every update (the smoother needs it)
    prior_cov: object = None          # joint prior covariance of parameters + consider
    noise_states: tuple = ()          # NoiseState: the sensors' slow noise as states (module docstring)


@dataclass
class FilterOutput:
    parameters: list[str]
    values: np.ndarray
    covariance: np.ndarray            # of the effect states (m, m)
    P: np.ndarray                     # full final covariance
    C_final: np.ndarray
    sigma_nav: np.ndarray             # final σ of the 9 navigation errors
    updates: int
    predictions: int
    history_t: np.ndarray             # time of each recorded update [s]
    history_values: np.ndarray        # θ̂ after each recorded update (K, m)
    history_sigma: np.ndarray         # σ after each recorded update (K, m)
    innovations: np.ndarray           # (K, 3) velocity innovations
    innovation_var: np.ndarray        # (K, 3) their predicted variance
    smoothed_nav: np.ndarray | None = None   # (K, 9) smoothed navigation errors
    smoothed_values: np.ndarray | None = None  # θ at the first interval, smoothed
    pass_values: list = field(default_factory=list)

    @property
    def sigma(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))


def prior_sigmas(params: list[str], settings: FilterSettings) -> np.ndarray:
    return np.array([settings.prior_sigma.get(p, settings.prior_scale * effect_of(p).typical)
                     for p in params], float)


def _nav_F(site: Site) -> np.ndarray:
    F = np.zeros((9, 9))
    w = site.w_ie
    F[0:3, 0:3] = -skew(w)
    F[3:6, 3:6] = -2.0 * skew(w)
    F[6, 4] = 1.0 / site.rm
    F[7, 3] = 1.0 / (site.rn * math.cos(site.latitude))
    F[8, 5] = 1.0
    return F


def run_filter(gyro: np.ndarray, acc: np.ndarray, dt: float, site: Site, C0: np.ndarray,
               static: np.ndarray, settings: FilterSettings, regressors=None,
               theta0: np.ndarray | None = None, time0: float = 0.0,
               prior_mean: np.ndarray | None = None) -> FilterOutput:
    """One pass of the closed-loop filter over increments (N, 3) starting at attitude C0.
    ``regressors`` cover the parameters followed by the consider states; ``theta0`` the
    parameters only (the consider states' values are in the data already). ``prior_mean``: the
    centre of the parameters' prior when it differs from ``theta0`` (a later pass linearises at
    the previous pass's estimate but keeps the prior where it was: no data counted twice)."""
    params = list(settings.parameters) + list(settings.consider)
    m_est = len(settings.parameters)
    e = slice(9, 9 + m_est)  # the estimated parameters in the state
    m = len(params)
    slow = list(settings.noise_states)
    ns = slice(9 + m, 9 + m + len(slow))  # the slow-noise states
    n = 9 + m + len(slow)
    N = len(gyro)
    theta = np.zeros(m)
    if theta0 is not None:
        theta[:m_est] = theta0
    sg = np.broadcast_to(np.asarray(SIGMA_GYRO_FLOOR if settings.sigma_gyro is None else settings.sigma_gyro,
                                    float), (3,))
    sa = np.broadcast_to(np.asarray(SIGMA_ACC_FLOOR if settings.sigma_acc is None else settings.sigma_acc,
                                    float), (3,))
    sg = np.maximum(sg, SIGMA_GYRO_FLOOR)
    sa = np.maximum(sa, SIGMA_ACC_FLOOR)
    r = settings.r_vel if settings.r_vel is not None else max(3.0 * float(np.max(sa)), 1e-6)
    nz = 6 if settings.observe_position else 3   # velocity (+ position)
    kf = KalmanFilter(dim_x=n, dim_z=nz)
    kf.x = np.zeros((n, 1))
    if prior_mean is not None and m_est:
        kf.x[e, 0] = np.asarray(prior_mean, float) - theta[:m_est]
    P0 = np.zeros(n)
    P0[0:3] = np.asarray(settings.phi0, float) ** 2
    P0[3:6] = settings.v0 ** 2
    P0[6:8] = (settings.pos0 / site.rm) ** 2
    P0[8] = settings.pos0 ** 2
    if m:
        P0[9:9 + m] = prior_sigmas(params, settings) ** 2
    # a Gauss–Markov term starts stationary; a random walk at 0 (the bias parameter holds the start)
    P0[ns] = [0.0 if math.isinf(x.T) else x.sigma**2 for x in slow]
    kf.P = np.diag(P0)
    if settings.prior_cov is not None:
        kf.P[9:9 + m, 9:9 + m] = np.asarray(settings.prior_cov, float)
    effect_feedback = settings.effect_feedback or settings.smoother
    keep = np.ones((n, 1))
    keep[9 + m_est:9 + m] = 0.0  # Schmidt: no gain for the consider states
    schmidt = m > m_est
    # each slow state's column of the navigation errors' input: its channel's (a bias of it)
    slow_channel = np.array([x.channel for x in slow], int)
    slow_transitions: dict = {}   # samples in an interval -> the slow states' (φ, var w)
    H = np.zeros((nz, n))
    H[0:3, 3:6] = np.eye(3)
    R = np.eye(nz) * r * r
    pos0 = np.array([site.latitude, 0.0, site.height])
    if settings.observe_position:
        H[3:6, 6:9] = np.eye(3)
        R[3:6, 3:6] = np.diag([(settings.r_pos / site.rm) ** 2,
                               (settings.r_pos / (site.rn * math.cos(site.latitude))) ** 2,
                               settings.r_pos ** 2])
    nav = Strapdown(site, C0, dt)
    Fn = _nav_F(site)
    steps = max(1, int(round(settings.kf_interval / (2 * dt))))
    Qg, Qa = np.diag(sg ** 2), np.diag(sa ** 2)
    I9 = np.eye(9)
    hist_t, hist_v, hist_s, innov, innov_var = [], [], [], [], []
    store = [] if settings.smoother else None
    updates = predictions = 0
    k = 0
    while k < N:
        Aacc = I9.copy()
        Bacc = np.zeros((9, m))
        Bnoise = np.zeros((9, 6))   # per channel: a bias of 1 (rad/s, m/s²) held over the interval
        Qacc = np.zeros((9, 9))
        k_start = k
        all_static = True
        for _ in range(steps):
            if k >= N:
                break
            c = 2 if k + 1 < N else 1
            if m:
                Gk, Ak = regressors.block(k, k + c)
                dth = gyro[k:k + c] - Gk @ theta
                dv = acc[k:k + c] - Ak @ theta
            else:
                dth, dv = gyro[k:k + c], acc[k:k + c]
            T = c * dt
            phi_b = dth.sum(0)
            Cm = nav.C @ rot(0.5 * phi_b)
            fn = Cm @ dv.sum(0) / T
            nav.step(dth, dv)
            F = Fn.copy()
            F[3:6, 0:3] = skew(fn)
            FT = F * T
            Ak9 = I9 + FT + 0.5 * (FT @ FT)
            Aacc = Ak9 @ Aacc
            Qk = np.zeros((9, 9))
            Qk[0:3, 0:3] = c * (Cm @ Qg @ Cm.T)
            Qk[3:6, 3:6] = c * (Cm @ Qa @ Cm.T)
            Qacc = Ak9 @ Qacc @ Ak9.T + Qk
            if m:
                Bk = np.zeros((9, m))
                Bk[0:3] = -Cm @ Gk.sum(0)
                Bk[3:6] = Cm @ Ak.sum(0)
                Bacc = Ak9 @ Bacc + Bk
            if slow:
                Bn = np.zeros((9, 6))
                Bn[0:3, 0:3] = -Cm * T
                Bn[3:6, 3:6] = Cm * T
                Bnoise = Ak9 @ Bnoise + Bn
            all_static = all_static and bool(np.all(static[k:k + c]))
            k += c
        Phi = np.eye(n)
        Phi[:9, :9] = Aacc
        Phi[:9, 9:9 + m] = Bacc
        Q = np.zeros((n, n))
        Q[:9, :9] = Qacc
        if slow:
            Phi[:9, ns] = Bnoise[:, slow_channel]
            # every interval but a short last one has the same samples: its (φ, var w) once
            n_k = k - k_start
            if n_k not in slow_transitions:
                slow_transitions[n_k] = np.array([x.transition(n_k * dt) for x in slow]).T
            phi_s, q_s = slow_transitions[n_k]
            Phi[ns, ns] = np.diag(phi_s)
            Q[ns, ns] = np.diag(q_s)
        kf.predict(F=Phi, Q=Q)
        predictions += 1
        P_prior = kf.P.copy() if store is not None else None
        observed = settings.observe == "always" or all_static
        if observed:
            z = nav.v if nz == 3 else np.concatenate([nav.v, nav.pos - pos0])
            z = z.reshape(nz, 1)
            if schmidt:
                _schmidt_update(kf, z, R, H, keep)
            else:
                kf.update(z, R=R, H=H)
            updates += 1
            innov.append(kf.y.ravel()[:3].copy())   # the velocity's
            innov_var.append(np.diag(kf.S)[:3].copy())
        x = kf.x.ravel().copy()
        if store is not None:
            store.append((Phi, P_prior, kf.P.copy(), x))
        nav.correct(x[0:3], x[3:6], x[6:9])
        if effect_feedback:
            if m:
                theta = theta + x[9:9 + m]
            kf.x[:9 + m] = 0.0   # the slow noise is not fed back: its states carry it on
        else:  # the navigation errors only: the effects stay linearised at theta for the pass
            kf.x[0:9] = 0.0
        if observed and (updates % settings.history_every == 0):
            hist_t.append(time0 + k * dt)
            hist_v.append(theta[:m_est] + (0.0 if effect_feedback else kf.x[e, 0]))
            hist_s.append(np.sqrt(np.diag(kf.P)[e]))
    if not effect_feedback and m:
        theta = theta + kf.x[9:9 + m, 0]
    out = FilterOutput(params[:m_est], theta[:m_est], kf.P[e, e].copy(), kf.P.copy(), nav.C.copy(),
                       np.sqrt(np.diag(kf.P)[:9]), updates, predictions,
                       np.array(hist_t), np.array(hist_v, float).reshape(len(hist_t), m_est),
                       np.array(hist_s, float).reshape(len(hist_t), m_est), np.array(innov).reshape(-1, 3),
                       np.array(innov_var).reshape(-1, 3))
    if store:
        out.smoothed_nav, out.smoothed_values = _rts(store, theta, m, len(slow))
        out.smoothed_values = out.smoothed_values[:m_est]
    return out


def _schmidt_update(kf: KalmanFilter, z: np.ndarray, R: np.ndarray, H: np.ndarray,
                    keep: np.ndarray) -> None:
    """filterpy's update with the consider states' gain rows set to zero (Joseph form)."""
    P = kf.P
    PHt = P @ H.T
    S = H @ PHt + R
    K = np.linalg.solve(S, PHt.T).T * keep
    y = z - H @ kf.x
    kf.x = kf.x + K @ y
    IKH = np.eye(len(P)) - K @ H
    kf.P = IKH @ P @ IKH.T + K @ R @ K.T
    kf.y, kf.S, kf.K = y, S, K


def _rts(store, theta_final, m, slow: int = 0):
    """Backward pass with the feedback as a known input (see the module docstring). Returns the
    smoothed navigation errors per interval (K, 9) (relative to each interval's navigation
    solution before its feedback) and the smoothed effect values at the first interval."""
    K = len(store)
    xs = store[-1][3].copy()
    nav = np.zeros((K, 9))
    nav[-1] = xs[:9]
    for i in range(K - 2, -1, -1):
        _, _, P_post, x_post = store[i]
        Phi_next, P_prior_next = store[i + 1][0], store[i + 1][1]
        # the effect states are random constants (rows [0 | I] of Φ, no process noise), so their
        # rows of the gain C = P⁺ Φᵀ (P⁻)⁻¹ are exactly [0 | I]; solving for them against P⁻
        # (condition number up to 1e23) only adds rounding noise that depends on the BLAS kernel
        # (0.5 σ of acc.bias.y on AVX2 OpenBLAS, 7e-6 σ on AVX-512)
        Cg = np.zeros_like(Phi_next)
        Cg[9:9 + m, 9:9 + m] = np.eye(m)
        solved = np.r_[0:9, 9 + m:9 + m + slow]   # the navigation errors and the slow noise
        Cg[solved] = np.linalg.solve(P_prior_next.T, (P_post[solved] @ Phi_next.T).T).T
        # x⁻_{i+1} = Φ (x⁺_i − u_i): the feedback u_i is all of x⁺_i but the slow noise, which
        # is not fed back (without it x⁻ is 0)
        kept = np.zeros_like(x_post)
        kept[9 + m:] = x_post[9 + m:]
        xs = x_post + Cg @ (xs - Phi_next @ kept)
        nav[i] = xs[:9]
    # θ at the first interval: θ̂ after the first feedback minus the first x⁺ plus the smoothed x
    theta_first = theta_final - sum(s[3][9:9 + m] for s in store[1:]) if m else np.zeros(0)
    smoothed = theta_first - store[0][3][9:9 + m] + xs[9:9 + m] if m else np.zeros(0)
    return nav, smoothed
