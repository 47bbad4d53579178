/* Small dense linear algebra of the resonator's exact discretization (row-major n x n):
 * the matrix exponential, the covariance of integrated white noise, a symmetric
 * eigen-decomposition. No allocation; the sizes are bounded in gyro_linalg.h. */
#include "gyro_linalg.h"

#include <float.h>
#include <math.h>
#include <string.h>

/* C = A B for n x n row-major matrices (C distinct from A and B). */
static void matmul(int n, const double *A, const double *B, double *C) {
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double acc = 0.0;
            for (int q = 0; q < n; q++) acc += A[i * n + q] * B[q * n + j];
            C[i * n + j] = acc;
        }
}

/* Solve A X = B in place (X to B) by LU with partial pivoting; A is overwritten. */
static void solve(int n, double *A, double *B) {
    for (int k = 0; k < n; k++) {
        int piv = k;
        for (int i = k + 1; i < n; i++)
            if (fabs(A[i * n + k]) > fabs(A[piv * n + k])) piv = i;
        if (piv != k)
            for (int j = 0; j < n; j++) {
                double t = A[k * n + j];
                A[k * n + j] = A[piv * n + j], A[piv * n + j] = t;
                t = B[k * n + j];
                B[k * n + j] = B[piv * n + j], B[piv * n + j] = t;
            }
        for (int i = k + 1; i < n; i++) {
            const double f = A[i * n + k] / A[k * n + k];
            if (f == 0.0) continue;
            for (int j = k; j < n; j++) A[i * n + j] -= f * A[k * n + j];
            for (int j = 0; j < n; j++) B[i * n + j] -= f * B[k * n + j];
        }
    }
    for (int k = n - 1; k >= 0; k--)
        for (int j = 0; j < n; j++) {
            double acc = B[k * n + j];
            for (int q = k + 1; q < n; q++) acc -= A[k * n + q] * B[q * n + j];
            B[k * n + j] = acc / A[k * n + k];
        }
}

void gyro_expm(int n, const double *M, double *E) {
    /* Higham (2005), "The scaling and squaring method for the matrix exponential
     * revisited": the [13/13] Pade approximant of e^(M / 2^s), ||M / 2^s||_1 <= theta_13,
     * then s squarings. */
    static const double b[14] = {64764752532480000.0, 32382376266240000.0, 7771770303897600.0,
                                 1187353796428800.0, 129060195264000.0, 10559470521600.0,
                                 670442572800.0, 33522128640.0, 1323241920.0, 40840800.0,
                                 960960.0, 16380.0, 182.0, 1.0};
    const double theta13 = 5.371920351148152;
    double A[144] = {0}, A2[144] = {0}, A4[144] = {0}, A6[144] = {0}, U[144] = {0};
    double V[144] = {0}, T[144] = {0}, W[144] = {0};
    const int nn = n * n;
    double norm = 0.0;
    for (int j = 0; j < n; j++) {
        double c = 0.0;
        for (int i = 0; i < n; i++) c += fabs(M[i * n + j]);
        norm = norm > c ? norm : c;
    }
    if (!(norm <= DBL_MAX)) { /* inf or NaN: no exponential (bounded work: s below) */
        for (int i = 0; i < nn; i++) E[i] = NAN;
        return;
    }
    int s = 0; /* at most 1024 + 3: a finite norm is below 2^1024 */
    while (ldexp(norm, -s) > theta13) s++;
    for (int i = 0; i < nn; i++) A[i] = ldexp(M[i], -s);
    matmul(n, A, A, A2);
    matmul(n, A2, A2, A4);
    matmul(n, A4, A2, A6);
    for (int i = 0; i < nn; i++) {
        T[i] = b[13] * A6[i] + b[11] * A4[i] + b[9] * A2[i];
        W[i] = b[12] * A6[i] + b[10] * A4[i] + b[8] * A2[i];
    }
    matmul(n, A6, T, U); /* U = A (A6 T + b7 A6 + b5 A4 + b3 A2 + b1 I) */
    for (int i = 0; i < nn; i++) U[i] += b[7] * A6[i] + b[5] * A4[i] + b[3] * A2[i];
    for (int i = 0; i < n; i++) U[i * n + i] += b[1];
    matmul(n, A, U, T);
    matmul(n, A6, W, V); /* V = A6 W + b6 A6 + b4 A4 + b2 A2 + b0 I */
    for (int i = 0; i < nn; i++) V[i] += b[6] * A6[i] + b[4] * A4[i] + b[2] * A2[i];
    for (int i = 0; i < n; i++) V[i * n + i] += b[0];
    for (int i = 0; i < nn; i++) { /* (V - U) E = V + U */
        W[i] = V[i] - T[i];
        E[i] = V[i] + T[i];
    }
    solve(n, W, E);
    for (int r = 0; r < s; r++) {
        matmul(n, E, E, T);
        memcpy(E, T, sizeof(double) * nn);
    }
}

void gyro_white_noise_covariance(int n, const double *A, const double *Qc, double h,
                                 double *Q) {
    /* Van Loan over t = h / 2^k with ||A||_1 t < 1/2, then k doublings
     * Q(2t) = Q(t) + Phi(t) Q(t) Phi(t)': sums of positive semi-definite terms */
    double norm = 0.0;
    for (int j = 0; j < n; j++) {
        double c = 0.0;
        for (int i = 0; i < n; i++) c += fabs(A[i * n + j]);
        norm = norm > c ? norm : c;
    }
    const double nh = norm * h > 1.0 ? norm * h : 1.0;
    const int k = (int)ceil(log2(nh)) + 1;
    const double t = ldexp(h, -k);
    const int m = 2 * n;
    double M[144] = {0}, E[144], Phi[36], T1[36], T2[36];
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            M[i * m + j] = -A[i * n + j] * t;
            M[i * m + n + j] = Qc[i * n + j] * t;
            M[(n + i) * m + n + j] = A[j * n + i] * t;
        }
    gyro_expm(m, M, E);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) Phi[i * n + j] = E[(n + j) * m + n + i];
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double acc = 0.0;
            for (int q = 0; q < n; q++) acc += Phi[i * n + q] * E[q * m + n + j];
            Q[i * n + j] = acc;
        }
    for (int r = 0; r < k; r++) {
        for (int i = 0; i < n; i++) /* T1 = Phi Q */
            for (int j = 0; j < n; j++) {
                double acc = 0.0;
                for (int q = 0; q < n; q++) acc += Phi[i * n + q] * Q[q * n + j];
                T1[i * n + j] = acc;
            }
        for (int i = 0; i < n; i++) /* Q += T1 Phi' */
            for (int j = 0; j < n; j++) {
                double acc = 0.0;
                for (int q = 0; q < n; q++) acc += T1[i * n + q] * Phi[j * n + q];
                T2[i * n + j] = acc;
            }
        for (int i = 0; i < n * n; i++) Q[i] += T2[i];
        for (int i = 0; i < n; i++) /* Phi = Phi Phi */
            for (int j = 0; j < n; j++) {
                double acc = 0.0;
                for (int q = 0; q < n; q++) acc += Phi[i * n + q] * Phi[q * n + j];
                T1[i * n + j] = acc;
            }
        memcpy(Phi, T1, sizeof(double) * n * n);
    }
    for (int i = 0; i < n; i++)
        for (int j = 0; j < i; j++) Q[i * n + j] = Q[j * n + i] = 0.5 * (Q[i * n + j] + Q[j * n + i]);
}

/* Symmetric eigen-decomposition by cyclic Jacobi rotations: A (n x n) = U diag(w) U'. */
void gyro_jacobi_eigen(int n, double *A, double *w, double *U) {
    for (int i = 0; i < n * n; i++) U[i] = 0.0;
    for (int i = 0; i < n; i++) U[i * n + i] = 1.0;
    for (int sweep = 0; sweep < 60; sweep++) {
        double off = 0.0, diag = 0.0;
        for (int i = 0; i < n; i++) {
            diag += A[i * n + i] * A[i * n + i];
            for (int j = i + 1; j < n; j++) off += A[i * n + j] * A[i * n + j];
        }
        if (off <= 1e-34 * diag || off == 0.0) break;
        for (int p = 0; p < n; p++)
            for (int q = p + 1; q < n; q++) {
                const double apq = A[p * n + q];
                if (apq == 0.0) continue;
                const double theta = (A[q * n + q] - A[p * n + p]) / (2.0 * apq);
                const double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                const double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < n; k++) { /* A = J' A J */
                    const double akp = A[k * n + p], akq = A[k * n + q];
                    A[k * n + p] = c * akp - s * akq;
                    A[k * n + q] = s * akp + c * akq;
                }
                for (int k = 0; k < n; k++) {
                    const double apk = A[p * n + k], aqk = A[q * n + k];
                    A[p * n + k] = c * apk - s * aqk;
                    A[q * n + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < n; k++) {
                    const double ukp = U[k * n + p], ukq = U[k * n + q];
                    U[k * n + p] = c * ukp - s * ukq;
                    U[k * n + q] = s * ukp + c * ukq;
                }
            }
    }
    for (int i = 0; i < n; i++) w[i] = A[i * n + i];
}
