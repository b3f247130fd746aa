/* 3-vectors and 3x3 matrices (rotations, direction cosine matrices) for the models: header
 * only and static inline, so each model compiles in what it uses. The arithmetic is the
 * models' own (-ffp-contract=off keeps it bit for bit): do not reorder it. */
#ifndef CALBENCH_VEC3_H
#define CALBENCH_VEC3_H

#include <math.h>
#include <string.h>

/* ISO C before C23 does not convert double (*)[3] to const double (*)[3] implicitly, so a
 * plain matrix passed to a const matrix parameter is a -Wpedantic error. The functions that
 * only read a matrix are therefore named with a trailing underscore and called through macros
 * that add the const here, in one place; _Generic lets nothing but a 3x3 double matrix
 * through. */
#define CONST_MAT3(M) _Generic((M), double(*)[3]: (const double(*)[3])(M), const double(*)[3]: (M))

static inline double dot3(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void cross3(const double a[3], const double b[3], double out[3]) {
    double t[3];
    t[0] = a[1] * b[2] - a[2] * b[1];
    t[1] = a[2] * b[0] - a[0] * b[2];
    t[2] = a[0] * b[1] - a[1] * b[0];
    memcpy(out, t, sizeof t);
}

static inline double norm3(const double a[3]) { return sqrt(dot3(a, a)); }

static inline void scale3(double a[3], double s) {
    a[0] *= s;
    a[1] *= s;
    a[2] *= s;
}

/* out = M x (out may alias x) */
static inline void mat_vec_(const double M[3][3], const double x[3], double out[3]) {
    double t[3];
    int i;
    for (i = 0; i < 3; i++) t[i] = M[i][0] * x[0] + M[i][1] * x[1] + M[i][2] * x[2];
    memcpy(out, t, sizeof t);
}

/* out = M^T x (out may alias x): the inverse transformation of a direction cosine matrix */
static inline void mat_tvec_(const double M[3][3], const double x[3], double out[3]) {
    double t[3];
    int i;
    for (i = 0; i < 3; i++) t[i] = M[0][i] * x[0] + M[1][i] * x[1] + M[2][i] * x[2];
    memcpy(out, t, sizeof t);
}

/* out = A B (out may alias A or B) */
static inline void mat_mul_(const double A[3][3], const double B[3][3], double out[3][3]) {
    double t[3][3];
    int i, j;
    for (i = 0; i < 3; i++)
        for (j = 0; j < 3; j++) t[i][j] = A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j];
    memcpy(out, t, sizeof t);
}

/* The functions above only read their matrices; call them through these. */
#define mat_vec(M, x, out) mat_vec_(CONST_MAT3(M), x, out)
#define mat_tvec(M, x, out) mat_tvec_(CONST_MAT3(M), x, out)
#define mat_mul(A, B, out) mat_mul_(CONST_MAT3(A), CONST_MAT3(B), out)

static inline void mat_identity(double M[3][3]) {
    memset(M, 0, 9 * sizeof(double));
    M[0][0] = M[1][1] = M[2][2] = 1.0;
}

/* Rodrigues: active right-hand rotation by angle t about the unit vector a. */
static inline void rodrigues(const double a[3], double t, double M[3][3]) {
    double s = sin(t), c1 = 1.0 - cos(t);
    double K[3][3] = {{0.0, -a[2], a[1]}, {a[2], 0.0, -a[0]}, {-a[1], a[0], 0.0}};
    double K2[3][3];
    int i, j;
    mat_mul(K, K, K2);
    for (i = 0; i < 3; i++)
        for (j = 0; j < 3; j++) M[i][j] = (i == j ? 1.0 : 0.0) + s * K[i][j] + c1 * K2[i][j];
}

/* v <- R(a, t)^T v = cos t v - sin t (a x v) + (1 - cos t)(a . v) a, given c = cos t, s = sin t
 * (the cost of one matrix-vector product, without forming the matrix). */
static inline void rodrigues_tvec(const double a[3], double c, double s, double v[3]) {
    double axv[3], ad = (1.0 - c) * dot3(a, v);
    int i;
    cross3(a, v, axv);
    for (i = 0; i < 3; i++) v[i] = c * v[i] - s * axv[i] + ad * a[i];
}

/* Rotation by a rotation vector (axis * angle); the identity for the zero vector. */
static inline void rot_vec(const double w[3], double M[3][3]) {
    double n = norm3(w), a[3];
    if (!(n > 0.0)) {
        mat_identity(M);
        return;
    }
    a[0] = w[0] / n;
    a[1] = w[1] / n;
    a[2] = w[2] / n;
    rodrigues(a, n, M);
}

/* Quaternion (w, x, y, z), w >= 0, of the rotation matrix C (Shepperd's method: divide by the
 * largest of the four candidate components, so no precision is lost near 180 deg). */
static inline void dcm_to_quat_(const double C[3][3], double q[4]) {
    double tr = C[0][0] + C[1][1] + C[2][2], s, n;
    int k;
    if (tr >= C[0][0] && tr >= C[1][1] && tr >= C[2][2]) {
        s = 2.0 * sqrt(1.0 + tr);
        q[0] = 0.25 * s;
        q[1] = (C[2][1] - C[1][2]) / s;
        q[2] = (C[0][2] - C[2][0]) / s;
        q[3] = (C[1][0] - C[0][1]) / s;
    } else if (C[0][0] >= C[1][1] && C[0][0] >= C[2][2]) {
        s = 2.0 * sqrt(1.0 + C[0][0] - C[1][1] - C[2][2]);
        q[0] = (C[2][1] - C[1][2]) / s;
        q[1] = 0.25 * s;
        q[2] = (C[0][1] + C[1][0]) / s;
        q[3] = (C[0][2] + C[2][0]) / s;
    } else if (C[1][1] >= C[2][2]) {
        s = 2.0 * sqrt(1.0 - C[0][0] + C[1][1] - C[2][2]);
        q[0] = (C[0][2] - C[2][0]) / s;
        q[1] = (C[0][1] + C[1][0]) / s;
        q[2] = 0.25 * s;
        q[3] = (C[1][2] + C[2][1]) / s;
    } else {
        s = 2.0 * sqrt(1.0 - C[0][0] - C[1][1] + C[2][2]);
        q[0] = (C[1][0] - C[0][1]) / s;
        q[1] = (C[0][2] + C[2][0]) / s;
        q[2] = (C[1][2] + C[2][1]) / s;
        q[3] = 0.25 * s;
    }
    n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (q[0] < 0.0) n = -n;
    for (k = 0; k < 4; k++) q[k] /= n;
}

#define dcm_to_quat(C, q) dcm_to_quat_(CONST_MAT3(C), q)

#endif
