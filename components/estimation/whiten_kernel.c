/* The whitening Kalman filter of components/estimation/whitening.py, one channel: the same
 * recursion, compiled, because diagnose and the noise likelihood run it hundreds of times per
 * call over every block of the log.
 *
 * Blocks k = 0..nb-1, m noise states, ncol columns (y and the design's columns):
 *   Pc = P c_k;  S_k = c_k' Pc + r_k;  nu = v_k - c_k' x;  g = (phi_k .* Pc + cross_k) / S_k
 *   out_k = nu / sqrt(S_k);  x = phi_k .* x + g nu';  P = phi_k phi_k' .* P + diag(q_k) - S_k g g'
 * Row-major arrays: phi, q, c, cross (nb x m), values and out (nb x ncol); work holds
 * m*m + m*ncol + 2*m + ncol doubles, the filter's state P then x first: with resume = 0 the filter starts
 * afresh (P = diag(p0), x = 0), otherwise from the state work holds, which a call leaves there after its
 * last block, so a channel can be whitened a piece of blocks at a time (the same operations in the
 * same order as in one call). Returns 0, or k + 1 when S_k is not positive (also nan; S_all[k]
 * then holds it). */
#include <math.h>
#include <string.h>

/* P = diag(p0), x = 0: the filter's start (P m x m, x m x ncol) */
static void start_state(long m, long ncol, const double *p0, double *P, double *x) {
    memset(P, 0, sizeof(double) * (size_t)(m * m));
    memset(x, 0, sizeof(double) * (size_t)(m * ncol));
    for (long i = 0; i < m; i++) P[i * m + i] = p0[i];
}

/* Block k's innovation: Pc = P c_k, S = c_k' Pc + r_k, nu = v_k - c_k' x, out_k = nu / sqrt(S).
 * Returns S (not positive: the filter has failed, out_k untouched). */
static double innovate(long m, long ncol, const double *P, const double *ck, double rk, const double *x,
                       const double *vk, double *Pc, double *nu, double *outk) {
    double S = rk;
    for (long i = 0; i < m; i++) {
        double s = 0.0;
        for (long l = 0; l < m; l++) s += P[i * m + l] * ck[l];
        Pc[i] = s;
    }
    for (long i = 0; i < m; i++) S += ck[i] * Pc[i];
    if (!(S > 0.0)) return S;
    const double rs = 1.0 / sqrt(S);
    for (long j = 0; j < ncol; j++) {
        double v = vk[j];
        for (long i = 0; i < m; i++) v -= ck[i] * x[i * ncol + j];
        nu[j] = v;
        outk[j] = v * rs;
    }
    return S;
}

/* P = (P + P') / 2 */
static void symmetrise(long m, double *P) {
    for (long i = 0; i < m; i++)
        for (long l = i + 1; l < m; l++) {
            double a = 0.5 * (P[i * m + l] + P[l * m + i]);
            P[i * m + l] = P[l * m + i] = a;
        }
}

__attribute__((visibility("default"))) long calbench_whiten(
    long nb, long m, long ncol, long resume, const double *phi, const double *q, const double *c,
    const double *cross, const double *r, const double *p0, const double *values, double *out, double *S_all,
    double *work) {
    double *P = work, *x = P + m * m, *Pc = x + m * ncol, *g = Pc + m, *nu = g + m;
    if (!resume) start_state(m, ncol, p0, P, x);
    for (long k = 0; k < nb; k++) {
        const double *ck = c + k * m, *fk = phi + k * m, *qk = q + k * m, *xk = cross + k * m;
        const double S = innovate(m, ncol, P, ck, r[k], x, values + k * ncol, Pc, nu, out + k * ncol);
        S_all[k] = S;
        if (!(S > 0.0)) return k + 1;
        for (long i = 0; i < m; i++) g[i] = (fk[i] * Pc[i] + xk[i]) / S;
        for (long i = 0; i < m; i++)
            for (long j = 0; j < ncol; j++) x[i * ncol + j] = fk[i] * x[i * ncol + j] + g[i] * nu[j];
        for (long i = 0; i < m; i++)
            for (long l = 0; l < m; l++) P[i * m + l] = fk[i] * P[i * m + l] * fk[l] - S * g[i] * g[l];
        for (long i = 0; i < m; i++) P[i * m + i] += qk[i];
        symmetrise(m, P);
    }
    return 0;
}

/* The same filter with a transition that turns pairs of states (an entry of its own, not this one
 * with every partner -1: the diagonal filter is the hot path, with no product matrix to hold and
 * no state to copy): F_k = diag(phi_k) plus, for each
 * state i with partner[i] >= 0, spin_k[i] at (i, partner[i]) (a damped rotation of the pair: the
 * harmonics of a pulse output's count remainder, components.model.noise.block_noise).
 *   g = (F Pc + cross_k) / S_k;  x = F x + g nu';  P = F P F' + diag(q_k) - S_k g g'
 * work holds 2*m*m + 2*m*ncol + 2*m + ncol doubles (P then x first, resumed as above). */
__attribute__((visibility("default"))) long calbench_whiten_turning(
    long nb, long m, long ncol, long resume, const double *phi, const double *spin, const long *partner,
    const double *q, const double *c, const double *cross, const double *r, const double *p0, const double *values,
    double *out, double *S_all, double *work) {
    double *P = work, *x = P + m * m, *Pc = x + m * ncol, *g = Pc + m, *nu = g + m, *A = nu + ncol, *xt = A + m * m;
    if (!resume) start_state(m, ncol, p0, P, x);
    for (long k = 0; k < nb; k++) {
        const double *ck = c + k * m, *fk = phi + k * m, *sk = spin + k * m, *qk = q + k * m, *xk = cross + k * m;
        const double S = innovate(m, ncol, P, ck, r[k], x, values + k * ncol, Pc, nu, out + k * ncol);
        S_all[k] = S;
        if (!(S > 0.0)) return k + 1;
        for (long i = 0; i < m; i++) {
            const long p = partner[i];
            g[i] = (fk[i] * Pc[i] + (p >= 0 ? sk[i] * Pc[p] : 0.0) + xk[i]) / S;
        }
        for (long i = 0; i < m; i++) {
            const long p = partner[i];
            for (long j = 0; j < ncol; j++)
                xt[i * ncol + j] = fk[i] * x[i * ncol + j] + (p >= 0 ? sk[i] * x[p * ncol + j] : 0.0) + g[i] * nu[j];
        }
        memcpy(x, xt, sizeof(double) * (size_t)(m * ncol));
        for (long i = 0; i < m; i++) {
            const long p = partner[i];
            for (long l = 0; l < m; l++) A[i * m + l] = fk[i] * P[i * m + l] + (p >= 0 ? sk[i] * P[p * m + l] : 0.0);
        }
        for (long i = 0; i < m; i++)
            for (long l = 0; l < m; l++) {
                const long p = partner[l];
                P[i * m + l] = A[i * m + l] * fk[l] + (p >= 0 ? A[i * m + p] * sk[l] : 0.0) - S * g[i] * g[l];
            }
        for (long i = 0; i < m; i++) P[i * m + i] += qk[i];
        symmetrise(m, P);
    }
    return 0;
}
