/* The turntable's kinematics: base, Earth, the gimbal chain, and the plate outputs with their
 * integrals over a communication step (see model.c for the other files).
 *
 * Conventions (see also the design notes, domain.md §1-§5)
 * ---------------------------------------------------------
 * Frames: n = ENU (x east, y north, z up); b0 = turntable base; stage k = frame carried by the
 *   k-th axis (1 outer, 2 middle, 3 inner); p = plate = frame of the innermost used stage.
 * C_x^y maps vectors given in frame x to frame y.
 * Rotations are active and right-handed. R(a, t) is the Rodrigues matrix
 *   R = I + sin t [a]x + (1 - cos t) [a]x^2;  Rot(w) = R(w/|w|, |w|) for a rotation vector w.
 * Base: C_b0^n = R(x, base.tilt.x) R(y, base.tilt.y) R(z, base.azimuth).
 * Axis k: a_k = Rot(delta_k) normalize(<a>.axis), delta_k = <a>.nonorth (rotation vector in
 *   the previous stage's frame; exact Rodrigues rotation of the axis vector, not linearised).
 * Wobble of axis k (amplitude A, phase phi): the stage transform is
 *   T_k = C_k^{k-1} = Rot(w_k) R(a_k, t_k),  w_k = A [cos(t_k + phi) u + sin(t_k + phi) v],
 *   u = normalize(e_j x a_k), e_j the basis vector (x, then y, then z on ties) with the smallest
 *   |a_k . e_j|, v = a_k x u.  Because w_k = R(a_k, t_k + phi) (A u), the same transform is
 *   T_k = R(a_k, t_k + phi) Rot(A u) R(a_k, -phi): a rigid rotation about a_k of a body mounted
 *   with a fixed tilt. Its relative angular rate in stage-k axes is therefore EXACTLY
 *   rho_k = t'_k b_k with the constant unit vector b_k = R(a_k, phi) Rot(-A u) a_k
 *   (= a_k when A = 0). This is the "rate contribution of the wobble", exact rather than only to
 *   first order, and it keeps plate.omega the true derivative of the attitude.
 * Chain: C_p^b0 = T_1 T_2 T_3 (only the n_axes used stages); C_p^n = C_b0^n C_p^b0.
 * Rates (plate axes, Earth rate included), recursion from the base outwards:
 *   omega_0 = C_n^b0 omega_ie^n,  omega_k = T_k^T omega_{k-1} + t'_k b_k
 *   alpha_0 = 0,  alpha_k = T_k^T alpha_{k-1} + t''_k b_k + (T_k^T omega_{k-1}) x (t'_k b_k)
 *   (the last term is d/dt T_k^T applied to omega_{k-1}).
 * Earth: omega_ie^n = [0, Omega cos L, Omega sin L]; gravity g = site.gravity if > 0, else WGS-84
 *   normal gravity (Somigliana) with the second-order height correction. Specific force at rest
 *   f^n = [0, 0, +g]; plate.f = C_n^p f^n at the axes' intersection (no lever arm).
 * plate.q: quaternion of C_p^n, scalar first, w >= 0.
 * Outputs are computed from the TRUE angles, rates and accelerations; the acceleration at the
 *   end of a step is the left limit (torque of the last controller tick).
 *
 * Integrals over the communication step (plate.omega_int, plate.f_int): the integrals of
 *   plate.omega and plate.f over the step just ended, for a consumer (the IMU) that must get the
 *   increments right although the motion inside a step is not a polynomial (the torque is
 *   piecewise constant at the controller rate, so the acceleration jumps at every tick). Per tick
 *   each axis moves in closed form, smooth between the instants where a rate reaches zero; the
 *   tick is split there (rare: ~2 ticks per index) and the kinematics (omega, f of the angles and
 *   rates of every used stage, the axes evaluated exactly) are integrated over each piece with
 *   2-point Gauss-Legendre (error piece^5/4320 times the 4th derivative of the integrand). Measured
 *   (tests/test_coupling.py): during a 90 deg index of all three axes the per-tick integral of
 *   omega agrees with an independent 64-substep RK4 + Simpson integral of the same ODE to 2e-17
 *   rad, 2e-13 in the two ticks with a friction switch; a navigation-grade gyro's per-sample
 *   noise at 5 ms is 4e-8 rad. Fast path: ticks in which every axis is stuck have constant omega
 *   and f; a run of them is integrated as value * (ticks * T), the kinematics evaluated once per
 *   run (normally once per step) instead of twice per tick.
 *   In Initialization Mode both are 0 (an empty interval).
 */
#include <math.h>
#include <string.h>
#include "turntable.h"

/* ------------------------------------------------------------------ Earth */

/* WGS-84 normal gravity (Somigliana) with the second-order free-air height correction. */
double normal_gravity(double lat, double h) {
    const double a = 6378137.0, f = 1.0 / 298.257223563, mm = 0.00344978650684;
    double s2 = sin(lat) * sin(lat);
    double g0 = 9.7803253359 * (1.0 + 0.00193185265241 * s2) / sqrt(1.0 - 0.00669437999013 * s2);
    return g0 * (1.0 - 2.0 / a * (1.0 + f + mm - 2.0 * f * s2) * h + 3.0 * h * h / (a * a));
}

/* ------------------------------------------------------------------ gimbal geometry */

/* Stage transform T = C_k^{k-1} = Rot(w) R(a, th) with the wobble tilt w of the convention. */
static void stage_matrix(const TTAxis *x, double th, double T[3][3]) {
    double Ra[3][3], W[3][3], w[3];
    int i;
    rodrigues(x->a, th, Ra);
    if (x->wob_amp == 0.0) {
        memcpy(T, Ra, sizeof Ra);
        return;
    }
    for (i = 0; i < 3; i++)
        w[i] = x->wob_amp * (cos(th + x->wob_phase) * x->u[i] + sin(th + x->wob_phase) * x->v[i]);
    rot_vec(w, W);
    mat_mul(W, Ra, T);
}

/* Set a (non-orthogonality applied), the wobble basis u, v and the rate axis b of one stage
 * from its parameters. Returns 0 when the axis vector is zero. */
int stage_geometry(ModelInstance *m, const AxisVR *vr, TTAxis *x) {
    double a0[3], d[3], D[3][3], W0[3][3], Rp[3][3], tilt[3], n, best;
    int k, j = 0;
    for (k = 0; k < 3; k++) {
        a0[k] = R(vr->axis[k]);
        d[k] = R(vr->nonorth[k]);
    }
    n = norm3(a0);
    if (!(n > 0.0)) return 0;
    scale3(a0, 1.0 / n);
    rot_vec(d, D);
    mat_vec(D, a0, x->a);
    scale3(x->a, 1.0 / norm3(x->a)); /* remove rounding: a stays a unit vector */
    /* u: basis vector least aligned with a (x, then y, then z on ties), crossed with a */
    best = fabs(x->a[0]);
    for (k = 1; k < 3; k++)
        if (fabs(x->a[k]) < best) {
            best = fabs(x->a[k]);
            j = k;
        }
    {
        double e[3] = {0.0, 0.0, 0.0};
        e[j] = 1.0;
        cross3(e, x->a, x->u);
    }
    scale3(x->u, 1.0 / norm3(x->u));
    cross3(x->a, x->u, x->v);
    x->wob_amp = R(vr->wob_amp);
    x->wob_phase = R(vr->wob_phase);
    /* b = R(a, phi) Rot(-A u) a: see the header comment */
    for (k = 0; k < 3; k++) tilt[k] = -x->wob_amp * x->u[k];
    rot_vec(tilt, W0);
    rodrigues(x->a, x->wob_phase, Rp);
    mat_vec(W0, x->a, x->b);
    mat_vec(Rp, x->b, x->b);
    return 1;
}

/* Plate outputs (attitude, inertial rate and acceleration, specific force) from the true
 * angles, rates and accelerations of the used stages. */
void plate_outputs(ModelInstance *m) {
    ModelPrivate *p = &m->s.p;
    double C[3][3], T[3][3], w[3], al[3], wc[3], rho[3], t[3], fn[3] = {0.0, 0.0, p->g}, f[3];
    double q[4];
    int k, i;
    memcpy(C, p->C_b0n, sizeof C);
    memcpy(w, p->w_ie_b0, sizeof w);
    memset(al, 0, sizeof al);
    for (k = 0; k < p->n_axes; k++) {
        const TTAxis *x = &p->ax[k];
        stage_matrix(x, x->th, T);
        mat_mul(C, T, C);
        mat_tvec(T, w, wc);   /* previous stage's rate in this stage's axes */
        mat_tvec(T, al, al);
        for (i = 0; i < 3; i++) rho[i] = x->thd * x->b[i];
        cross3(wc, rho, t);   /* transport term d/dt(T^T) omega_{k-1} */
        for (i = 0; i < 3; i++) {
            al[i] += x->thdd * x->b[i] + t[i];
            w[i] = wc[i] + rho[i];
        }
    }
    mat_tvec(C, fn, f);
    dcm_to_quat(C, q);
    R(VR_plate_omega_x) = w[0];
    R(VR_plate_omega_y) = w[1];
    R(VR_plate_omega_z) = w[2];
    R(VR_plate_alpha_x) = al[0];
    R(VR_plate_alpha_y) = al[1];
    R(VR_plate_alpha_z) = al[2];
    R(VR_plate_f_x) = f[0];
    R(VR_plate_f_y) = f[1];
    R(VR_plate_f_z) = f[2];
    R(VR_plate_q_w) = q[0];
    R(VR_plate_q_x) = q[1];
    R(VR_plate_q_y) = q[2];
    R(VR_plate_q_z) = q[3];
}

/* Inertial rate and specific force of the plate (plate axes) for the angles th[] and rates
 * thd[] of the used stages: the rate recursion of plate_outputs without the acceleration and the
 * attitude, and f carried through the same stage transforms (f_k = T_k^T f_{k-1}). */
static void plate_rate_force(const ModelPrivate *p, const double th[], const double thd[],
                             double w[3], double f[3]) {
    double T[3][3], fn[3] = {0.0, 0.0, p->g};
    int k, i;
    memcpy(w, p->w_ie_b0, 3 * sizeof(double));
    mat_tvec(p->C_b0n, fn, f);
    for (k = 0; k < p->n_axes; k++) {
        const TTAxis *x = &p->ax[k];
        if (x->wob_amp == 0.0) { /* T = R(a, th): rotate the two vectors without the matrix */
            double c = cos(th[k]), s = sin(th[k]);
            rodrigues_tvec(x->a, c, s, w);
            rodrigues_tvec(x->a, c, s, f);
        } else {
            stage_matrix(x, th[k], T);
            mat_tvec(T, w, w);
            mat_tvec(T, f, f);
        }
        for (i = 0; i < 3; i++) w[i] += thd[k] * x->b[i];
    }
}

/* ------------------------------------------------------------------ step integrals */

/* 2-point Gauss-Legendre on [0, 1]: nodes (3 -+ sqrt 3) / 6, weights 1/2 */
const double GL2_S[2] = {0.21132486540518711775, 0.78867513459481288225};

/* Add the integrals of plate.omega and plate.f over a tick in which some axis moves. The motion
 * of each axis is smooth between the instants where a rate reaches zero (friction switches
 * there), so the tick is split at them and each piece gets 2-point Gauss-Legendre with the axes
 * evaluated in closed form (error: piece^5 / 4320 times the integrand's 4th derivative). Ticks
 * without such an instant (nearly all) use the nodes' precomputed phi1, phi2. */
void tick_integrals(const ModelPrivate *p, const TickMotion mo[], double wi[3], double fi[3]) {
    double cut[TT_MAX_AXES + 2], th[TT_MAX_AXES], thd[TT_MAX_AXES], w[3], f[3];
    int nc = 0, k, i, q, c;
    cut[nc++] = 0.0;
    for (k = 0; k < p->n_axes; k++) /* insertion sort of the switching instants */
        if (mo[k].te > 0.0 && mo[k].te < p->T) {
            for (i = nc; i > 1 && cut[i - 1] > mo[k].te; i--) cut[i] = cut[i - 1];
            cut[i] = mo[k].te;
            nc++;
        }
    cut[nc++] = p->T;
    for (c = 0; c + 1 < nc; c++) {
        double len = cut[c + 1] - cut[c];
        if (!(len > 0.0)) continue;
        for (q = 0; q < 2; q++) {
            double t = cut[c] + GL2_S[q] * len;
            for (k = 0; k < p->n_axes; k++) {
                const TTAxis *x = &p->ax[k];
                if (nc == 2) { /* one smooth piece: the precomputed node values */
                    th[k] = mo[k].th0 + (mo[k].v0 * t + mo[k].a0 * x->phi2_g[q]);
                    thd[k] = mo[k].v0 + mo[k].a0 * x->phi1_g[q];
                } else {
                    motion_at(x, &mo[k], t, &th[k], &thd[k]);
                }
            }
            plate_rate_force(p, th, thd, w, f);
            for (i = 0; i < 3; i++) {
                wi[i] += 0.5 * len * w[i];
                fi[i] += 0.5 * len * f[i];
            }
        }
    }
}

/* Integrals over a run of n ticks in which every axis stuck at the angles th[]: omega and f are
 * constant, so the integral is value * n T, the kinematics evaluated once per run (normally once
 * per step) instead of twice per tick. */
void rest_integrals(const ModelPrivate *p, const double th[], long long n, double wi[3],
                    double fi[3]) {
    static const double zero[TT_MAX_AXES] = {0.0, 0.0, 0.0};
    double w[3], f[3], len = (double)n * p->T;
    int i;
    if (n == 0) return;
    plate_rate_force(p, th, zero, w, f);
    for (i = 0; i < 3; i++) {
        wi[i] += len * w[i];
        fi[i] += len * f[i];
    }
}
