/* The observer of US 2011/0314910 A1 (eqs. 5-9): see gyro_observer.h for the contract.
 *
 * The operation order is that of gyro_fmu 0.3.0's compiled kernels (tests/oracle_observer/),
 * so IEEE arithmetic gives the same bits; compiled with -ffp-contract=off. The IMM
 * equations are Bar-Shalom, Li & Kirubarajan, "Estimation with Applications to Tracking
 * and Navigation" (2001), sec. 11.6.6, eqs. 11.6.6-1 to -22. */
#include "gyro_observer.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gyro_text.h"

#define NMAX GYRO_OBS_NMAX
#define KMAX GYRO_OBS_KMAX
#define IPAR GYRO_OBS_IPAR
#define IOM GYRO_OBS_IOM

/* Longer held steps (||A h||_inf > STEP_NORM) are split into equal sub-steps. */
static const double STEP_NORM = 0.5;
/* Most sub-steps of one held step (bounded work; held_step_split). A state the monitor
 * accepts needs a few at the largest step accepted (omega h <= OMEGA_H_MAX). */
static const double SPLIT_MAX = 4096.0;
/* Process noise of the plant state per step relative to each signal's running peak: a
 * floor far below any pick-off noise. Without it the correlations between the plant state
 * and the parameters of a constant-rate filter reach 1 - 1e-16 within seconds and
 * rounding breaks positive definiteness (lost at 3.09 s at noise 1e-4). */
static const double STATE_NOISE = 1e-9;
/* The adaptive set's rough and slow models follow rate_bandwidth / SLOW_FRACTION. */
static const double SLOW_FRACTION = 10.0;
/* More rough models (random walks of Omega_z) at these multiples of the rough model's
 * intensity, after the four named ones: a wandering rate's intensity is chosen by the IMM
 * likelihood among graded ones (one fixed intensity left 30-50 Hz wandering rates at
 * error/sigma 1.9-2.7; docs/observer-rate-model.md). */
static const double ROUGH_GRADES[GYRO_OBS_MMAX - 4] = {3.0, 10.0, 100.0};
/* Auto prior of [x, vx, y, vy] started by the drive (plant at rest): this fraction of the
 * static deflection; 10 % or more let the velocity-pair filter converge to Omega -5.
 * Started by a measurement above its noise (a plant not known at rest): its size; 1 %
 * there made relative-noise runs overconfident (dyy error/sigma 3.4, 300 ms) since the
 * innovation floor of R never saw a large early innovation. */
static const double PRIOR_FRACTION = 0.01;
static const double PRIOR_FRACTION_MEASURED = 1.0;
/* Largest omega h accepted: the sampling must be 25 % faster than the Nyquist rate of the
 * guessed resonance (omega h = pi). Beyond, the resonance aliases: measured at 200 us
 * (omega h 4.6) runs from 10 % off ended wrong with status 0; at 100 us (2.3) they
 * converged or were refused. */
static const double OMEGA_H_MAX = 2.5;
/* Warning above this omega h (US 2011/0314910's held step stays exact, but the samples
 * resolve the resonance less and less: dampings and the tracking degrade long before the
 * refusal, and the sigmas do not say so; issue "observer honest when the rate moves"). */
static const double OMEGA_H_WARN = GYRO_OBS_OMEGA_H_WARN;
/* Monitor. Corrections per block of the innovation tests (1 ms at the default 5 us). */
static const int BLOCK = 200;
/* Warning above the chi-square quantile of this normal quantile (p = 1e-4 per block). */
static const double NIS_WARN_Z = 3.719;
/* Lost when the block mean NIS exceeds this (innovations ~70 sigma RMS; expected 2): a
 * noise 10x larger than told gives ~200 (a warning), a diverged filter 1e6 and more. */
static const double NIS_LOST = 1.0e4;
/* Relative mode (noise estimated from the innovations): warning above REL_WARN, lost above
 * REL_LOST, block RMS innovations relative to each signal's peak. The noise is estimated,
 * so innovations above noise_rel are no warning; a slow misfit is caught by whiteness. */
static const double REL_WARN = 0.02, REL_LOST = 0.2;
/* Warning when an innovation sequence's lag-1 autocorrelation over a block exceeds
 * CORR_WARN (white: 0 +- 0.07) while the mean NIS exceeds NIS_MIN: the innovations are a
 * slowly varying misfit, not noise, so the sigmas (which assume white noise) are too
 * small. A converged noise-free filter has NIS ~1e-8 and is not flagged. */
static const double CORR_WARN = 0.5, NIS_MIN = 0.1;
/* Time constant (s) of the innovations' running mean square at the start (innov_tau's
 * default); a longer innov_tau is reached as the run goes (rel_R). */
static const double INNOV_TAU_START = 1e-3;
/* Re-fit test: window time constant (s) and warning threshold on T (chi-square, 8 dof;
 * measured on good runs in docs/observer-soundness.md). */
static const double REFIT_TAU = 0.02;
static const double REFIT_WARN = 40.0;
/* kxx, kyy and 1/m must stay within this factor of their initial guesses. */
static const double RATIO = 100.0;

static const double FACTORIAL[48] = {
    1.0, 1.0, 2.0, 6.0,
    24.0, 120.0, 720.0, 5040.0,
    40320.0, 362880.0, 3628800.0, 39916800.0,
    479001600.0, 6227020800.0, 87178291200.0, 1307674368000.0,
    20922789888000.0, 355687428096000.0, 6402373705728000.0, 1.21645100408832e+17,
    2.43290200817664e+18, 5.109094217170944e+19, 1.1240007277776077e+21, 2.585201673888498e+22,
    6.204484017332394e+23, 1.5511210043330986e+25, 4.0329146112660565e+26, 1.0888869450418352e+28,
    3.0488834461171387e+29, 8.841761993739702e+30, 2.6525285981219107e+32, 8.222838654177922e+33,
    2.631308369336935e+35, 8.683317618811886e+36, 2.9523279903960416e+38, 1.0333147966386145e+40,
    3.7199332678990125e+41, 1.3763753091226346e+43, 5.230226174666011e+44, 2.0397882081197444e+46,
    8.159152832478977e+47, 3.345252661316381e+49, 1.40500611775288e+51, 6.041526306337383e+52,
    2.658271574788449e+54, 1.1962222086548019e+56, 5.502622159812089e+57, 2.5862324151116818e+59,
};

const double gyro_observer_prior_fraction = PRIOR_FRACTION;

double gyro_observer_factorial(int k) { return k >= 0 && k < 48 ? FACTORIAL[k] : -1.0; }

size_t gyro_observer_size(void) { return sizeof(GyroObserver); }

int gyro_observer_rough_grades(double *grades, int n) {
    const int m = GYRO_OBS_MMAX - 4;
    for (int i = 0; i < m && i < n; i++) grades[i] = ROUGH_GRADES[i];
    return m;
}

static double dmax(double a, double b) { return a >= b ? a : b; }
static double dmin(double a, double b) { return a <= b ? a : b; }

/* ------------------------------------------------------------ held step (eq. 5) */

/* Taylor terms K with norm^K / K! < 1e-15 (norm = ||A h||_inf <= 0.5). */
static int n_terms(double norm) {
    double term = 1.0;
    for (int k = 1; k < KMAX; k++) {
        term *= norm / k;
        if (term < 1e-15) return k + 1;
    }
    return KMAX;
}

static double inf_norm_4x5(const double M[5][5]) {
    double norm = 0.0;
    for (int i = 0; i < 4; i++) {
        double r = 0.0;
        for (int j = 0; j < 5; j++) r += fabs(M[i][j]);
        norm = dmax(norm, r);
    }
    return norm;
}

/* Taylor powers st[j] = (A h)^j / j!, their sum Phi_aug = expm(A_aug h) (top 4 rows), and
 * the Frechet series S = h sum_{j,m} j! m! / (j+m+1)! T_j G(T_m xi0) of the sensitivities. */
static void held_step_single(const double xi0[5], const double Ah[5][5], double h,
                             const double MgT[5][16], double s1[4], double Phi[4][4],
                             double S[4][8]) {
    double st[KMAX][5][5], G[KMAX][16], Gb[KMAX][16], beta[KMAX][KMAX];
    memset(st[0], 0, sizeof st[0]);
    for (int a = 0; a < 5; a++) st[0][a][a] = 1.0;
    const int K = n_terms(inf_norm_4x5(Ah));
    for (int j = 0; j < K - 1; j++) {
        const double inv = 1.0 / (j + 1);
        for (int a = 0; a < 5; a++)
            for (int c = 0; c < 5; c++) {
                double acc = 0.0;
                for (int b = 0; b < 5; b++) acc += st[j][a][b] * (Ah[b][c] * inv);
                st[j + 1][a][c] = acc;
            }
    }
    for (int i = 0; i < 4; i++) {
        for (int c = 0; c < 4; c++) {
            double acc = 0.0;
            for (int j = 0; j < K; j++) acc += st[j][i][c];
            Phi[i][c] = acc;
        }
        double acc = 0.0;
        for (int c = 0; c < 5; c++) {
            double e = 0.0;
            for (int j = 0; j < K; j++) e += st[j][i][c];
            acc += e * xi0[c];
        }
        s1[i] = acc;
    }
    for (int m = 0; m < K; m++) { /* G[m] = (T_m xi0) MgT */
        for (int q = 0; q < 16; q++) G[m][q] = 0.0;
        for (int a = 0; a < 5; a++) {
            double txi = 0.0;
            for (int b = 0; b < 5; b++) txi += st[m][a][b] * xi0[b];
            for (int q = 0; q < 16; q++) G[m][q] += txi * MgT[a][q];
        }
    }
    for (int j = 0; j < K; j++) /* beta[j][m] = j! m! / (j + m + 1)! */
        for (int m = 0; m < K; m++) beta[j][m] = FACTORIAL[j] * FACTORIAL[m] / FACTORIAL[j + m + 1];
    for (int j = 0; j < K; j++)
        for (int q = 0; q < 16; q++) {
            double acc = 0.0;
            for (int m = 0; m < K; m++) acc += beta[j][m] * G[m][q];
            Gb[j][q] = acc;
        }
    for (int i = 0; i < 4; i++)
        for (int q = 0; q < 8; q++) {
            double acc = 0.0;
            for (int j = 0; j < K; j++) acc += st[j][i][1] * Gb[j][q] + st[j][i][3] * Gb[j][8 + q];
            S[i][q] = acc * h;
        }
}

/* held_step_single, with ||A h|| > STEP_NORM in equal sub-steps (Jacobians chained).
 *
 * Bounded work: the input column A_aug[:, 4] (b u / w) grows with the force and 1/m
 * without bound (ux = 1e13 N or m = 1e-22 kg made the sub-step count overflow int, and
 * ux = 1e9 N took 7-40 s a step). The held step is linear in that column, so when it
 * alone would need more than SPLIT_MAX sub-steps it is scaled by 2^-k and the constant
 * state xi0[4] (and MgT's row 4) by 2^k: a power of two, so every product is the same
 * number and the result is exact; the cost then follows the plant's own matrix. A step
 * whose plant matrix itself needs more than SPLIT_MAX sub-steps (or is not finite) has no
 * result: s1, Phi and S are NaN, and the filter is lost with that cause. */
static void held_step_split(const double xi0_in[5], const double Ah_in[5][5], double h,
                            const double MgT_in[5][16], double s1[4], double Phi[4][4],
                            double S[4][8]) {
    double norm = inf_norm_4x5(Ah_in);
    if (norm <= STEP_NORM) {
        held_step_single(xi0_in, Ah_in, h, MgT_in, s1, Phi, S);
        return;
    }
    double Ah[5][5], xi0[5], MgT[5][16];
    memcpy(Ah, Ah_in, sizeof Ah);
    memcpy(xi0, xi0_in, sizeof xi0);
    memcpy(MgT, MgT_in, sizeof MgT);
    if (!(norm <= SPLIT_MAX * STEP_NORM)) {
        double plant = 0.0, column = 0.0; /* ||A h|| of the 4x4 plant part; the input column */
        for (int i = 0; i < 4; i++) {
            double r = 0.0;
            for (int j = 0; j < 4; j++) r += fabs(Ah[i][j]);
            plant = dmax(plant, r);
            column = dmax(column, fabs(Ah[i][4]));
        }
        if (plant <= SPLIT_MAX * STEP_NORM * 0.5 && isfinite(column)) {
            int k;
            frexp(column / dmax(plant, STEP_NORM), &k); /* column 2^-k <= max(plant, 0.5) */
            for (int i = 0; i < 5; i++) Ah[i][4] = ldexp(Ah[i][4], -k);
            xi0[4] = ldexp(xi0[4], k);
            for (int q = 0; q < 16; q++) MgT[4][q] = ldexp(MgT[4][q], -k);
            norm = inf_norm_4x5((const double(*)[5])Ah);
        }
    }
    if (!(norm <= SPLIT_MAX * STEP_NORM)) {
        for (int i = 0; i < 4; i++) {
            s1[i] = NAN;
            for (int c = 0; c < 4; c++) Phi[i][c] = NAN;
            for (int q = 0; q < 8; q++) S[i][q] = NAN;
        }
        return;
    }
    if (norm <= STEP_NORM) {
        held_step_single(xi0, (const double(*)[5])Ah, h, (const double(*)[16])MgT, s1, Phi, S);
        return;
    }
    const int nsub = (int)ceil(norm / STEP_NORM);
    double Ahs[5][5], xi[5], Phi_t[4][4] = {{0}}, S_t[4][8] = {{0}}, Phi1[4][4], S1[4][8];
    double s_1[4], tmpP[4][4], tmpS[4][8];
    for (int a = 0; a < 5; a++)
        for (int b = 0; b < 5; b++) Ahs[a][b] = Ah[a][b] / nsub;
    memcpy(xi, xi0, sizeof xi);
    for (int i = 0; i < 4; i++) Phi_t[i][i] = 1.0;
    for (int k = 0; k < nsub; k++) {
        held_step_single(xi, (const double(*)[5])Ahs, h / nsub, (const double(*)[16])MgT, s_1,
                         Phi1, S1);
        for (int i = 0; i < 4; i++) {
            for (int q = 0; q < 8; q++) {
                double acc = 0.0;
                for (int c = 0; c < 4; c++) acc += Phi1[i][c] * S_t[c][q];
                tmpS[i][q] = acc + S1[i][q];
            }
            for (int q = 0; q < 4; q++) {
                double acc = 0.0;
                for (int c = 0; c < 4; c++) acc += Phi1[i][c] * Phi_t[c][q];
                tmpP[i][q] = acc;
            }
        }
        memcpy(S_t, tmpS, sizeof S_t);
        memcpy(Phi_t, tmpP, sizeof Phi_t);
        memcpy(xi, s_1, sizeof s_1);
    }
    memcpy(s1, xi, 4 * sizeof(double));
    memcpy(Phi, Phi_t, sizeof Phi_t);
    memcpy(S, S_t, sizeof S_t);
}

void gyro_observer_held_step(const GyroObserver *o, const double theta[GYRO_OBS_NPAR],
                             double Omega_z, const double s[4], double ux, double uy, double h,
                             double s1[4], double Phi[4][4], double S[4][8]) {
    const double wx = o->wx, wy = o->wy, b = theta[6];
    const GyroParams p = {theta[0], theta[1], theta[2], theta[3], theta[4], theta[5], 1.0};
    double Ap[4][4], A[5][5] = {{0}}, Ah[5][5], MgT[5][16], xi0[5];
    gyro_system_matrix(&p, Omega_z, Ap);
    A[0][1] = wx; /* A_aug of [s, 1] in the filter's scaling */
    A[2][3] = wy;
    A[1][0] = Ap[1][0] / wx;
    A[1][1] = Ap[1][1];
    A[1][2] = Ap[1][2] / wx;
    A[1][3] = Ap[1][3] * wy / wx;
    A[1][4] = b * ux / wx;
    A[3][0] = Ap[3][0] / wy;
    A[3][1] = Ap[3][1] * wx / wy;
    A[3][2] = Ap[3][2] / wy;
    A[3][3] = Ap[3][3];
    A[3][4] = b * uy / wy;
    memcpy(MgT, o->MgT, sizeof MgT);
    MgT[4][6] = o->scale[6] * ux / wx;
    MgT[4][14] = o->scale[6] * uy / wy;
    for (int i = 0; i < 5; i++)
        for (int j = 0; j < 5; j++) Ah[i][j] = A[i][j] * h;
    memcpy(xi0, s, 4 * sizeof(double));
    xi0[4] = 1.0;
    held_step_split(xi0, Ah, h, MgT, s1, Phi, S);
}

/* The held step of x's plant state at x's parameters and Omega_z (the linearization). */
static void linearize(const GyroObserver *o, const double *x, double ux, double uy, double h,
                      double s1[4], double Phi[4][4], double S[4][8]) {
    double theta[GYRO_OBS_NPAR];
    for (int i = 0; i < GYRO_OBS_NPAR; i++) theta[i] = o->theta0[i] + o->scale[i] * x[IPAR + i];
    gyro_observer_held_step(o, theta, x[IOM], x, ux, uy, h, s1, Phi, S);
}

/* ------------------------------------------------------------ correction (eq. 8) */

/* Relative-mode noise variance: (noise_rel peak)^2, floored by the innovations' running
 * mean square: an EWMA of time constant INNOV_TAU_START at first, whose memory then
 * grows as a plain mean's (t) until innov_tau. (An EWMA of a slow innov_tau started at
 * the first square stayed near that one sample: at 50 ms it lost a good gyro at 85 us.
 * A plain mean from the start slowed far noise-free starts: 30 % off, 20 ms, -3 rad/s.) */
static double rel_R(GyroObserver *o, int j, double nu, double h) {
    const GyroObserverTuning *tun = &o->tuning;
    const double v2 = nu * nu;
    double e = o->nu2[j];
    const double w = dmax(dmin(h / tun->innov_tau, 1.0),
                          dmin(h / (o->t + h), h / INNOV_TAU_START));
    e = e < 0.0 ? v2 : e + w * (v2 - e);
    o->nu2[j] = e;
    const double floor_ = tun->noise_rel * o->peak[j];
    return dmax(floor_ * floor_, tun->innov_floor * e);
}

/* Noise variances R of the measured pair at t and the innovations nu of the combined
 * prediction; updates the running peaks and the innovation EWMA (time base: h). */
static void noise_variances(GyroObserver *o, double z1, double z2, double h, double R[2],
                            double nu[2]) {
    const int i0 = o->i0;
    nu[0] = z1 - o->hgain[0] * o->x[i0];
    nu[1] = z2 - o->hgain[1] * o->x[i0 + 2];
    if (fabs(z1) > o->peak[0]) o->peak[0] = fabs(z1);
    if (fabs(z2) > o->peak[1]) o->peak[1] = fabs(z2);
    R[0] = o->tuning.sigma_z1 > 0.0 ? o->tuning.sigma_z1 * o->tuning.sigma_z1
                                     : rel_R(o, 0, nu[0], h);
    R[1] = o->tuning.sigma_z2 > 0.0 ? o->tuning.sigma_z2 * o->tuning.sigma_z2
                                     : rel_R(o, 1, nu[1], h);
}

/* Measurement update (eq. 8) of one filter's x, P in place: x += K (z - H x), P by Joseph
 * (symmetrized) or P - K H P. Returns the NIS of its innovation (2 dof; < 0: S singular,
 * no update) and *logdet = log det S. */
static double correct_with(const GyroObserver *o, double *x, double P[NMAX][NMAX], double z1,
                           double z2, const double R[2], double *logdet) {
    const int n = o->n, i0 = o->i0, i1 = i0 + 2;
    const double g0 = o->hgain[0], g1 = o->hgain[1];
    const double nu0 = z1 - g0 * x[i0], nu1 = z2 - g1 * x[i1];
    const double a = P[i0][i0] * g0 * g0 + R[0];
    const double b_ = P[i0][i1] * g0 * g1;
    const double c = P[i1][i0] * g0 * g1;
    const double d = P[i1][i1] * g1 * g1 + R[1];
    const double det = a * d - b_ * c;
    *logdet = 0.0;
    if (!(det > 0.0 && a > 0.0)) return -1.0;
    const double s00 = d / det, s01 = -b_ / det, s10 = -c / det, s11 = a / det;
    double PHt[NMAX][2], K[NMAX][2];
    for (int i = 0; i < n; i++) {
        PHt[i][0] = P[i][i0] * g0;
        PHt[i][1] = P[i][i1] * g1;
    }
    for (int i = 0; i < n; i++) {
        K[i][0] = PHt[i][0] * s00 + PHt[i][1] * s10;
        K[i][1] = PHt[i][0] * s01 + PHt[i][1] * s11;
        x[i] = x[i] + (K[i][0] * nu0 + K[i][1] * nu1);
    }
    if (o->tuning.joseph) { /* (I - K H) P (I - K H)' + K R K', O(n^2): H picks i0, i1 */
        double M[NMAX][NMAX];
        for (int i = 0; i < n; i++) {
            const double k0 = K[i][0] * g0, k1 = K[i][1] * g1;
            for (int j = 0; j < n; j++) M[i][j] = P[i][j] - (k0 * P[i0][j] + k1 * P[i1][j]);
        }
        for (int i = 0; i < n; i++) {
            const double m0 = M[i][i0] * g0, m1 = M[i][i1] * g1;
            const double kr0 = K[i][0] * R[0], kr1 = K[i][1] * R[1];
            for (int j = 0; j < n; j++)
                P[i][j] = (M[i][j] - (m0 * K[j][0] + m1 * K[j][1])) +
                          (kr0 * K[j][0] + kr1 * K[j][1]);
        }
        for (int i = 0; i < n; i++) /* symmetric to the last bit */
            for (int j = 0; j < i; j++) {
                const double v = 0.5 * (P[i][j] + P[j][i]);
                P[i][j] = v;
                P[j][i] = v;
            }
    } else {
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) P[i][j] -= K[i][0] * PHt[j][0] + K[i][1] * PHt[j][1];
    }
    *logdet = log(det);
    return nu0 * (s00 * nu0 + s01 * nu1) + nu1 * (s10 * nu0 + s11 * nu1);
}

/* S = H P H' + R of the combined prediction as [a, b, d, det] (S = [[a, b], [b, d]]);
 * 0 when it is not positive definite. */
static int innovation_covariance(const GyroObserver *o, const double R[2], double S[4]) {
    const int i0 = o->i0, i1 = i0 + 2;
    const double g0 = o->hgain[0], g1 = o->hgain[1];
    S[0] = o->P[i0][i0] * g0 * g0 + R[0];
    S[1] = o->P[i0][i1] * g0 * g1;
    S[2] = o->P[i1][i1] * g1 * g1 + R[1];
    S[3] = S[0] * S[2] - S[1] * S[1];
    return S[3] > 0.0 && S[0] > 0.0;
}

/* Add one correction's innovations (of the combined prediction) to the monitor's block. */
static void monitor_innovations(GyroObserver *o, const double nu[2], const double R[2]) {
    double S[4];
    if (!innovation_covariance(o, R, S)) return;
    const double a = S[0], b_ = S[1], d = S[2], det = S[3];
    GyroMonitor *m = &o->mon;
    m->nis += (d * nu[0] * nu[0] - 2.0 * b_ * nu[0] * nu[1] + a * nu[1] * nu[1]) / det;
    for (int j = 0; j < 2; j++) { /* lag-1 autocorrelation and power of each sequence */
        m->ac[j] += nu[j] * m->prev[j];
    }
    m->sq[0] += nu[0] * nu[0];
    m->sq[1] += nu[1] * nu[1];
    m->prev[0] = nu[0];
    m->prev[1] = nu[1];
    m->count += 1.0;
}

/* Re-fit test, at a correction: the score and its covariance take this correction (nu of
 * the combined prediction, S = H P H' + R), then W <- (I - K H) W. */
static void refit_correct(GyroObserver *o, const double nu[2], const double R[2], double h) {
    const int i0 = o->i0, i1 = i0 + 2;
    const double g0 = o->hgain[0], g1 = o->hgain[1];
    double S[4];
    if (!innovation_covariance(o, R, S)) return;
    const double s00 = S[2] / S[3], s01 = -S[1] / S[3], s11 = S[0] / S[3]; /* S^-1 */
    GyroRefit *r = &o->refit;
    const double lam = exp(-h / REFIT_TAU), lam2 = lam * lam;
    double psi[2][8], sp[2][8]; /* psi = H W; sp = S^-1 psi */
    for (int c = 0; c < 8; c++) {
        psi[0][c] = g0 * r->W[i0][c];
        psi[1][c] = g1 * r->W[i1][c];
    }
    for (int c = 0; c < 8; c++) {
        sp[0][c] = s00 * psi[0][c] + s01 * psi[1][c];
        sp[1][c] = s01 * psi[0][c] + s11 * psi[1][c];
        r->g[c] = lam * r->g[c] + sp[0][c] * nu[0] + sp[1][c] * nu[1];
    }
    for (int c = 0; c < 8; c++)
        for (int e = 0; e <= c; e++) {
            const double v = lam2 * r->F[c][e] + psi[0][c] * sp[0][e] + psi[1][c] * sp[1][e];
            r->F[c][e] = v;
            r->F[e][c] = v;
        }
    r->weight = lam2 * r->weight + 1.0;
    double K[4][2]; /* state rows of the combined gain P H' S^-1 */
    for (int i = 0; i < 4; i++) {
        const double p0 = o->P[i][i0] * g0, p1 = o->P[i][i1] * g1;
        K[i][0] = p0 * s00 + p1 * s01;
        K[i][1] = p0 * s01 + p1 * s11;
    }
    double W[4][8];
    for (int i = 0; i < 4; i++)
        for (int c = 0; c < 8; c++) W[i][c] = r->W[i][c] - K[i][0] * psi[0][c] - K[i][1] * psi[1][c];
    memcpy(r->W, W, sizeof W);
}

/* Re-fit test, at a prediction over the held step (Phi, S): W <- Phi W + S. */
static void refit_predict(GyroObserver *o, const double Phi[4][4], const double S[4][8]) {
    double W[4][8];
    for (int i = 0; i < 4; i++)
        for (int c = 0; c < 8; c++) {
            double acc = S[i][c];
            for (int k = 0; k < 4; k++) acc += Phi[i][k] * o->refit.W[k][c];
            W[i][c] = acc;
        }
    memcpy(o->refit.W, W, sizeof W);
}

/* A rejected estimate restarted along the re-fit's move: every rate model's covariance of
 * (p, Omega_z) gains move move' (rank one: stays positive definite), so the filter's gain
 * re-opens where the recent data disagree and its sigmas cover the move; the window starts
 * afresh. */
static void refit_restart(GyroObserver *o) {
    GyroRefit *r = &o->refit;
    for (int j = 0; j < o->n_models; j++)
        for (int a = 0; a < 8; a++)
            for (int b = 0; b < 8; b++) o->Ps[j][IPAR + a][IPAR + b] += r->move[a] * r->move[b];
    for (int a = 0; a < 8; a++)
        for (int b = 0; b < 8; b++) o->P[IPAR + a][IPAR + b] += r->move[a] * r->move[b];
    memset(r->g, 0, sizeof r->g);
    memset(r->F, 0, sizeof r->F);
    r->weight = 0.0;
    r->restarts += 1.0;
}

/* Re-fit test, judged: T = g' F^-1 g (a Cholesky factor of F with a relative ridge of
 * 1e-10 on its diagonal; a direction the window cannot see adds nothing) once the window
 * is full (weight >= 0.8 of its limit). shift = the Gauss-Newton move of the window's
 * weighted fit, F1^-1 g with F1 = sum lambda^(N-k) psi' S^-1 psi ~ (1 + lambda) F, in the
 * filter's sigmas. Returns T, or -1 when not judged. */
static double refit_judge(GyroObserver *o, double h) {
    GyroRefit *r = &o->refit;
    const double lam2 = exp(-2.0 * h / REFIT_TAU);
    if (!(r->weight >= 0.8 / (1.0 - lam2))) return -1.0;
    double L[8][8] = {{0}}, y[8], v[8];
    for (int j = 0; j < 8; j++) {
        double acc = r->F[j][j] * (1.0 + 1e-10);
        for (int k = 0; k < j; k++) acc -= L[j][k] * L[j][k];
        if (!(acc > 0.0)) { /* a direction with no information: skip it */
            L[j][j] = 0.0;
            continue;
        }
        L[j][j] = sqrt(acc);
        for (int i = j + 1; i < 8; i++) {
            double a = r->F[i][j];
            for (int k = 0; k < j; k++) a -= L[i][k] * L[j][k];
            L[i][j] = a / L[j][j];
        }
    }
    double T = 0.0;
    for (int i = 0; i < 8; i++) { /* L y = g */
        double acc = r->g[i];
        for (int k = 0; k < i; k++) acc -= L[i][k] * y[k];
        y[i] = L[i][i] > 0.0 ? acc / L[i][i] : 0.0;
        T += y[i] * y[i];
    }
    for (int i = 7; i >= 0; i--) { /* L' v = y: v = F^-1 g */
        double acc = y[i];
        for (int k = i + 1; k < 8; k++) acc -= L[k][i] * v[k];
        v[i] = L[i][i] > 0.0 ? acc / L[i][i] : 0.0;
    }
    const double lam = exp(-h / REFIT_TAU); /* F1 = sum lambda^(N-k) a ~ F (1 + lambda) */
    for (int i = 0; i < 8; i++) {
        const double sd = sqrt(dmax(o->P[IPAR + i][IPAR + i], 0.0));
        r->move[i] = v[i] / (1.0 + lam);
        r->shift[i] = sd > 0.0 ? r->move[i] / sd : 0.0;
    }
    r->last_T = T;
    return T;
}

/* ------------------------------------------------------------ IMM over the rate models */

/* x, P = the mixture of the filters (xs, Ps) with weights w (eqs. 11.6.6-21, -22). */
static void combine(const GyroObserver *o, const double xs[][NMAX],
                    const double Ps[][NMAX][NMAX], const double *w, double *x,
                    double P[NMAX][NMAX]) {
    const int M = o->n_models, n = o->n;
    for (int i = 0; i < n; i++) {
        double acc = 0.0;
        for (int j = 0; j < M; j++) acc += w[j] * xs[j][i];
        x[i] = acc;
    }
    if (M == 1) {
        memcpy(P, Ps[0], sizeof(double) * NMAX * NMAX);
        return;
    }
    for (int a = 0; a < n; a++)
        for (int b = 0; b <= a; b++) {
            double acc = 0.0;
            for (int j = 0; j < M; j++)
                acc += w[j] * (Ps[j][a][b] + (xs[j][a] - x[a]) * (xs[j][b] - x[b]));
            P[a][b] = acc;
            P[b][a] = acc;
        }
}

void gyro_observer_mix(GyroObserver *o) {
    const int M = o->n_models;
    if (M == 1) {
        o->c[0] = 1.0;
        return;
    }
    double x0[GYRO_OBS_MMAX][NMAX], P0[GYRO_OBS_MMAX][NMAX][NMAX], wj[GYRO_OBS_MMAX];
    for (int j = 0; j < M; j++) {
        double acc = 0.0;
        for (int i = 0; i < M; i++) acc += o->Pi[i][j] * o->mu[i];
        o->c[j] = acc;
        for (int i = 0; i < M; i++) wj[i] = o->Pi[i][j] * o->mu[i] / acc;
        combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, wj, x0[j],
                P0[j]);
    }
    const int n = o->n;
    for (int j = 0; j < M; j++) {
        memcpy(o->xs[j], x0[j], n * sizeof(double));
        for (int a = 0; a < n; a++) memcpy(o->Ps[j][a], P0[j][a], n * sizeof(double));
    }
}

void gyro_observer_combine(const GyroObserver *o, const double *w, double *x,
                           double P[GYRO_OBS_NMAX][GYRO_OBS_NMAX]) {
    combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, w, x, P);
}

/* IMM correction at t: every filter corrected with the noise variances of the combined
 * prediction; mu = c x likelihood, normalized (eqs. 11.6.6-15 to -19); x, P combined. */
static void imm_update(GyroObserver *o, double z1, double z2, double h) {
    double R[2], nu[2], ll[GYRO_OBS_MMAX];
    noise_variances(o, z1, z2, h, R, nu);
    monitor_innovations(o, nu, R);
    refit_correct(o, nu, R, h);
    const int M = o->n_models;
    for (int j = 0; j < M; j++) {
        double logdet;
        const double nis = correct_with(o, o->xs[j], o->Ps[j], z1, z2, R, &logdet);
        ll[j] = nis >= 0.0 ? -0.5 * (nis + logdet) : 0.0;
    }
    if (M > 1) {
        double top = ll[0], total = 0.0;
        for (int j = 1; j < M; j++) top = ll[j] > top ? ll[j] : top;
        for (int j = 0; j < M; j++) {
            o->mu[j] = o->c[j] * exp(ll[j] - top);
            total += o->mu[j];
        }
        for (int j = 0; j < M; j++) o->mu[j] /= total;
    } else {
        o->mu[0] = 1.0;
    }
    combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, o->mu, o->x,
            o->P);
}

/* Propagate one filter's x, P to t + h linearized about xbar ((s1, Phi, S) its held step):
 * x[:4] -> s1 + Phi (x[:4] - xbar[:4]) + S (x[4:12] - xbar[4:12]), process noise q0 on x,
 * vx and q1 on y, vy; parameters a random walk of qpar per step; the rate block
 * x[IOM:] -> Fr x[IOM:] with noise Qr. P -> F P F' + Q (F's structure used), symmetrized. */
static void predict_about(const GyroObserver *o, const double *xbar, const double s1[4],
                          const double Phi[4][4], const double S[4][8], double *x,
                          double P[NMAX][NMAX], const double Fr[][GYRO_OBS_RMAX],
                          const double Qr[][GYRO_OBS_RMAX], double q0, double q1) {
    const int n = o->n, r = n - IOM;
    double d[12], om[GYRO_OBS_RMAX], A[NMAX][NMAX], B[NMAX][NMAX];
    for (int c = 0; c < 12; c++) d[c] = x[c] - xbar[c];
    for (int i = 0; i < 4; i++) {
        double acc = s1[i];
        for (int c = 0; c < 4; c++) acc += Phi[i][c] * d[c];
        for (int c = 0; c < 8; c++) acc += S[i][c] * d[4 + c];
        x[i] = acc;
    }
    for (int a = 0; a < r; a++) {
        double acc = 0.0;
        for (int c = 0; c < r; c++) acc += Fr[a][c] * x[IOM + c];
        om[a] = acc;
    }
    for (int a = 0; a < r; a++) x[IOM + a] = om[a];
    for (int k = 0; k < n; k++) { /* A = F P */
        for (int i = 0; i < 4; i++) {
            double acc = 0.0;
            for (int c = 0; c < 4; c++) acc += Phi[i][c] * P[c][k];
            for (int c = 0; c < 8; c++) acc += S[i][c] * P[4 + c][k];
            A[i][k] = acc;
        }
        for (int i = 4; i < IOM; i++) A[i][k] = P[i][k];
        for (int a = 0; a < r; a++) {
            double acc = 0.0;
            for (int c = 0; c < r; c++) acc += Fr[a][c] * P[IOM + c][k];
            A[IOM + a][k] = acc;
        }
    }
    for (int i = 0; i < n; i++) { /* B = (F P) F' */
        for (int j = 0; j < 4; j++) {
            double acc = 0.0;
            for (int c = 0; c < 4; c++) acc += A[i][c] * Phi[j][c];
            for (int c = 0; c < 8; c++) acc += A[i][4 + c] * S[j][c];
            B[i][j] = acc;
        }
        for (int j = 4; j < IOM; j++) B[i][j] = A[i][j];
        for (int a = 0; a < r; a++) {
            double acc = 0.0;
            for (int c = 0; c < r; c++) acc += A[i][IOM + c] * Fr[a][c];
            B[i][IOM + a] = acc;
        }
    }
    B[0][0] += q0;
    B[1][1] += q0;
    B[2][2] += q1;
    B[3][3] += q1;
    for (int i = IPAR; i < IOM; i++) B[i][i] += o->qpar;
    for (int a = 0; a < r; a++)
        for (int c = 0; c < r; c++) B[IOM + a][IOM + c] += Qr[a][c];
    for (int i = 0; i < n; i++) {
        P[i][i] = B[i][i];
        for (int j = 0; j < i; j++) {
            const double v = 0.5 * (B[i][j] + B[j][i]);
            P[i][j] = v;
            P[j][i] = v;
        }
    }
}

/* IMM prediction to t + h: mix, propagate every filter about the combined estimate (one
 * held step, eq. 5), then x, P = their mixture with the predicted probabilities c. */
static void imm_predict(GyroObserver *o, double ux, double uy, double h) {
    double s1[4], Phi[4][4], S[4][8], xbar[NMAX];
    linearize(o, o->x, ux, uy, h, s1, Phi, S);
    refit_predict(o, (const double(*)[4])Phi, (const double(*)[8])S);
    gyro_observer_mix(o);
    const double a0 = STATE_NOISE * o->peak[0] / o->hgain[0];
    const double a1 = STATE_NOISE * o->peak[1] / o->hgain[1];
    memcpy(xbar, o->x, sizeof xbar); /* the linearization point is replaced only below */
    for (int j = 0; j < o->n_models; j++)
        predict_about(o, xbar, s1, Phi, S, o->xs[j], o->Ps[j],
                      (const double(*)[GYRO_OBS_RMAX])o->Fr[j],
                      (const double(*)[GYRO_OBS_RMAX])o->Qr[j], a0 * a0, a1 * a1);
    combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, o->c, o->x,
            o->P);
}

/* ------------------------------------------------------------ rate models */

/* q (rad^2/s^(2 order + 1)) of white noise on the order-th derivative of Omega_z that
 * follows a sine of amplitude span (rad/s) at bandwidth (Hz): span^2 w^(2 order - 1) / 2 pi. */
static double intensity(int order, double span, double bandwidth) {
    const double w = 2.0 * GYRO_PI * bandwidth;
    return span * span * pow(w, 2 * order - 1) / (2.0 * GYRO_PI);
}

/* Transition and process noise over h of an order-th random walk of intensity q, embedded
 * in the rate block (unused derivatives 0). */
static void rate_process(int order, double q, double h, double F[GYRO_OBS_RMAX][GYRO_OBS_RMAX],
                         double Q[GYRO_OBS_RMAX][GYRO_OBS_RMAX]) {
    memset(F, 0, sizeof(double) * GYRO_OBS_RMAX * GYRO_OBS_RMAX);
    memset(Q, 0, sizeof(double) * GYRO_OBS_RMAX * GYRO_OBS_RMAX);
    for (int a = 0; a < order; a++)
        for (int c = a; c < order; c++) F[a][c] = pow(h, c - a) / FACTORIAL[c - a];
    for (int a = 0; a < order; a++)
        for (int c = 0; c < order; c++) {
            const int pa = order - 1 - a, pc = order - 1 - c;
            Q[a][c] = q * pow(h, pa + pc + 1) / (FACTORIAL[pa] * FACTORIAL[pc] * (pa + pc + 1));
        }
}

void gyro_observer_set_step(GyroObserver *o, double h) {
    const GyroObserverTuning *tun = &o->tuning;
    const double span = tun->rate_span, f = tun->rate_bandwidth;
    int orders[GYRO_OBS_MMAX];
    double qs[GYRO_OBS_MMAX];
    int M = 1;
    switch (tun->rate_model) {
    case 0: { /* adaptive: constant, rough, slow, agile */
        const double slow = f / SLOW_FRACTION;
        orders[0] = 1, qs[0] = 0.0;
        orders[1] = 1, qs[1] = intensity(1, span, slow);
        orders[2] = 2, qs[2] = intensity(2, span, slow);
        orders[3] = 3, qs[3] = intensity(3, span, f);
        M = GYRO_OBS_MMAX;
        for (int j = 4; j < M; j++) orders[j] = 1, qs[j] = ROUGH_GRADES[j - 4] * qs[1];
        break;
    }
    case 1: orders[0] = 1, qs[0] = 0.0; break;
    case 2: orders[0] = 3, qs[0] = intensity(3, span, f); break;
    default: orders[0] = tun->omega_order, qs[0] = tun->q_Omega; break;
    }
    for (int j = 0; j < M; j++) rate_process(orders[j], qs[j], h, o->Fr[j], o->Qr[j]);
    memset(o->Pi, 0, sizeof o->Pi);
    if (M > 1) {
        const double sw = -expm1(-h / tun->rate_dwell); /* P(leave a model within h) */
        for (int i = 0; i < M; i++)
            for (int j = 0; j < M; j++) o->Pi[i][j] = i == j ? 1.0 - sw : sw / (M - 1);
    } else {
        o->Pi[0][0] = 1.0;
    }
    o->qpar = tun->q_param_rel * h;
    o->h_cached = h;
}

/* ------------------------------------------------------------ monitor */

int gyro_observer_cholesky_ok(const double *P, int n) {
    double L[NMAX][NMAX] = {{0}};
#define PIJ(i, j) P[(i) * NMAX + (j)]
    for (int j = 0; j < n; j++) {
        double acc = PIJ(j, j);
        for (int k = 0; k < j; k++) acc -= L[j][k] * L[j][k];
        if (acc == 0.0) { /* a state known exactly: semidefinite only in that way */
            for (int i = j + 1; i < n; i++) {
                double r = PIJ(i, j);
                for (int k = 0; k < j; k++) r -= L[i][k] * L[j][k];
                if (r != 0.0) return 0;
                L[i][j] = 0.0;
            }
            L[j][j] = 0.0;
            continue;
        }
        if (!(acc > 0.0)) return 0;
        const double d = sqrt(acc);
        L[j][j] = d;
        for (int i = j + 1; i < n; i++) {
            double a = PIJ(i, j);
            for (int k = 0; k < j; k++) a -= L[i][k] * L[j][k];
            L[i][j] = a / d;
        }
    }
#undef PIJ
    return 1;
}

static int lost_verdict(GyroMonitor *m, int cause, int which, double value) {
    m->status = cause;
    m->cause = cause;
    m->which = which;
    m->value = value;
    return cause;
}

/* Divergence monitor after a step: 0 ok, 1 warning, >= 2 lost (GYRO_MON_*), in o->mon. */
static int monitor_check(GyroObserver *o) {
    const GyroMonitorLimits *lim = &o->lim;
    GyroMonitor *m = &o->mon;
    const double *x = o->x;
    const int n = o->n;
    for (int i = 0; i < n; i++)
        if (!(isfinite(x[i]) && isfinite(o->P[i][i])))
            return lost_verdict(m, GYRO_MON_NONFINITE, i, x[i]);
    if (!gyro_observer_cholesky_ok(&o->P[0][0], n))
        return lost_verdict(m, GYRO_MON_NOT_SPD, -1, 0.0);
    double th[GYRO_OBS_NPAR];
    for (int i = 0; i < GYRO_OBS_NPAR; i++) th[i] = o->theta0[i] + o->scale[i] * x[IPAR + i];
    static const int positive[3] = {0, 1, 6}; /* kxx, kyy, 1/m: within a factor of the guess */
    for (int k = 0; k < 3; k++) {
        const int i = positive[k];
        if (!(th[i] > 0.0 && o->theta0[i] / lim->ratio <= th[i] &&
              th[i] <= o->theta0[i] * lim->ratio))
            return lost_verdict(m, GYRO_MON_BOUNDS, i, th[i]);
    }
    if (!(th[0] * th[1] > th[2] * th[2])) return lost_verdict(m, GYRO_MON_BOUNDS, 2, th[2]);
    for (int i = 3; i < 6; i++)
        if (!(fabs(th[i]) <= lim->d_max)) return lost_verdict(m, GYRO_MON_BOUNDS, i, th[i]);
    if (!(fabs(x[IOM]) <= lim->omega_max)) return lost_verdict(m, GYRO_MON_BOUNDS, 7, x[IOM]);
    const double count = m->count;
    if (count >= lim->block) {
        const double nis = m->nis / count;
        double rel = 0.0, corr = 0.0; /* worse signal's RMS innovation / peak; lag-1 corr */
        for (int j = 0; j < 2; j++) {
            if (o->peak[j] > 0.0) rel = dmax(rel, sqrt(m->sq[j] / count) / o->peak[j]);
            if (m->sq[j] > 0.0) corr = dmax(corr, m->ac[j] / m->sq[j]);
            m->ac[j] = 0.0;
            m->sq[j] = 0.0;
        }
        m->last_corr = corr;
        m->nis = 0.0;
        m->count = 0.0;
        m->block += 1.0;
        m->last_nis = nis;
        m->last_rel = rel;
        int status = GYRO_MON_OK;
        if (lim->absolute) {
            if (nis > lim->nis_lost) return lost_verdict(m, GYRO_MON_INNOVATIONS, 0, nis);
            if (nis > lim->nis_warn) status = GYRO_MON_WARN;
        } else {
            if (rel > lim->rel_lost) return lost_verdict(m, GYRO_MON_INNOVATIONS, 1, rel);
            if (rel > lim->rel_warn) status = GYRO_MON_WARN;
        }
        if (status == GYRO_MON_WARN) {
            m->which = lim->absolute ? 0 : 1;
            m->value = lim->absolute ? nis : rel;
        } else if (corr > lim->corr_warn && nis > lim->nis_min) {
            status = GYRO_MON_WARN;
            m->which = GYRO_WARN_CORR;
            m->value = corr;
        }
        const double T = refit_judge(o, o->h_cached);
        if (T >= 0.0) o->refit.pending = T > REFIT_WARN;
        if (T > REFIT_WARN) refit_restart(o);
        if (status == GYRO_MON_OK && o->refit.pending) { /* until a window judges it good */
            status = GYRO_MON_WARN;
            m->which = GYRO_WARN_REFIT;
            m->value = o->refit.last_T;
        }
        m->status = status;
    }
    return (int)m->status;
}

static const char *const PAR_NAMES[8] = {"kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "1/m",
                                         "Omega_z"};
static const char *const PAR_UNITS[8] = {"1/s^2", "1/s^2", "1/s^2", "1/s", "1/s", "1/s",
                                         "1/kg", "rad/s"};

static void cause_text(const GyroObserver *o, char *buf, size_t n) {
    const GyroMonitor *m = &o->mon;
    const GyroMonitorLimits *lim = &o->lim;
    const int cause = (int)m->cause, which = (int)m->which;
    if (cause == GYRO_MON_NONFINITE) {
        snprintf(buf, n, "its estimate or covariance became non-finite (filter state row %d): "
                 "numbers beyond the double range, or a held step beyond its bounded work "
                 "(||A h|| > %g of the plant matrix at the estimated parameters)", which,
                 SPLIT_MAX * STEP_NORM);
    } else if (cause == GYRO_MON_NOT_SPD) {
        snprintf(buf, n, "its covariance lost positive definiteness (no Cholesky factor): the "
                 "linearization no longer holds");
    } else if (cause == GYRO_MON_BOUNDS) {
        char why[200];
        if (which == 0 || which == 1 || which == 6)
            snprintf(why, sizeof why, "must be > 0 and within x%g of its initial guess",
                     lim->ratio);
        else if (which == 2)
            snprintf(why, sizeof why, "K = [[kxx, kxy], [kxy, kyy]] must stay positive "
                     "definite");
        else if (which == 7)
            snprintf(why, sizeof why, "a rate beyond the gyro's natural frequency (%.4g rad/s)",
                     lim->omega_max);
        else
            snprintf(why, sizeof why, "|d| must stay <= %.4g 1/s", lim->d_max);
        snprintf(buf, n, "its estimate %s=%.4g %s left the physical range (%s)",
                 PAR_NAMES[which], m->value, PAR_UNITS[which], why);
    } else if (which == 0) {
        snprintf(buf, n, "its innovations are inconsistent: mean normalized innovation squared "
                 "%.3g over %d corrections (expected 2, lost above %g)", m->value, lim->block,
                 lim->nis_lost);
    } else {
        snprintf(buf, n, "its one-step predictions miss the measurements by %.3g %% RMS of "
                 "the signal over %d corrections (lost above %g %%)", 100 * m->value,
                 lim->block, 100 * lim->rel_lost);
    }
}

/* Why the filter is lost and what to do, in one line (kept in o->lost_message). */
static void lose(GyroObserver *o, double h) {
    char cause[600], hints[400] = "";
    cause_text(o, cause, sizeof cause);
    const double coarse = dmax(o->wx, o->wy) * h;
    if (coarse > 0.5)
        snprintf(hints, sizeof hints, "the communication step %.3g s is too coarse for the "
                 "observer (omega h = %.2g; use omega h < 0.5); ", h, coarse);
    snprintf(o->lost_message, sizeof o->lost_message,
             "observer lost at t=%.6g s (the step from %.6g s): %s. Likely causes and "
             "remedies: %sthe initial rate guess Omega_z_0 too far from the true rate or the "
             "parameter guesses too far (start within ~10 %%); a smaller communication step; "
             "measurement noise larger than the observer was told (sigma_z1, sigma_z2, "
             "noise_rel). Its estimates are meaningless from here: restore an earlier state "
             "or start anew", o->t, o->t - h, cause, hints);
    o->status = 2;
    o->lost = 1;
}

/* The re-fit test's last rejection in words: T, the two largest moves, the restart. */
static void refit_text(const GyroObserver *o, char *what, size_t n) {
    int a = 0, b = 1; /* the two largest moves */
    for (int i = 0; i < 8; i++)
        if (fabs(o->refit.shift[i]) > fabs(o->refit.shift[a])) a = i;
    if (b == a) b = 0;
    for (int i = 0; i < 8; i++)
        if (i != a && fabs(o->refit.shift[i]) > fabs(o->refit.shift[b])) b = i;
    snprintf(what, n, "a re-fit of the last %g ms of data rejects its estimate (chi-square "
             "%.4g over 8 dof, warning above %g) and would move %s by %+.3g sigma and %s by "
             "%+.3g sigma: the estimate and its sigmas did not fit the recent data; restarted "
             "along that move (restart %d), judged again in %.3g ms", 1e3 * REFIT_TAU,
             o->refit.last_T, REFIT_WARN, PAR_NAMES[a], o->refit.shift[a], PAR_NAMES[b],
             o->refit.shift[b], (int)o->refit.restarts, 1e3 * REFIT_TAU * 0.5 * log(5.0));
}

int gyro_observer_restart_message(const GyroObserver *o, char *msg, size_t n) {
    if (n) msg[0] = '\0';
    if (!(o->refit.restarts > 0.0)) return 0;
    char what[600];
    refit_text(o, what, sizeof what);
    snprintf(msg, n, "observer at t=%.6g s: %s", o->t, what);
    return 1;
}

int gyro_observer_warning(const GyroObserver *o, char *msg, size_t n) {
    if (o->status != 1) return 0;
    const GyroMonitor *m = &o->mon;
    const GyroMonitorLimits *lim = &o->lim;
    char what[400];
    if ((int)m->which == GYRO_WARN_REFIT) {
        refit_text(o, what, sizeof what);
    } else if ((int)m->which == GYRO_WARN_CORR)
        snprintf(what, sizeof what, "its innovations are not white (lag-1 autocorrelation "
                 "%.2g over %d corrections): a misfit the sigmas do not count", m->value,
                 lim->block);
    else if (lim->absolute)
        snprintf(what, sizeof what, "mean normalized innovation squared %.3g over %d "
                 "corrections, above its chi-square 0.9999 band (%.3g)", m->value, lim->block,
                 lim->nis_warn);
    else
        snprintf(what, sizeof what, "one-step predictions miss by %.3g RMS of the signal, "
                 "above %.3g", m->value, lim->rel_warn);
    snprintf(msg, n, "observer at t=%.6g s: %s: the estimates may be off (initial guesses "
             "far, or noise larger than told)", o->t, what);
    return 1;
}

/* ------------------------------------------------------------ construction and steps */

/* Wilson-Hilferty approximation of the chi-square quantile at normal quantile z. */
static double chi2_quantile(int dof, double z) {
    const double a = 2.0 / (9.0 * dof);
    return dof * pow(1.0 - a + z * sqrt(a), 3);
}

int gyro_observer_tuning_problems(const GyroObserverTuning *tun, char *msg, size_t n) {
    char num[GYRO_REAL_TEXT];
    const struct { const char *name; double v; } reals[] = {
        {"noise_rel", tun->noise_rel}, {"sigma_z1", tun->sigma_z1},
        {"sigma_z2", tun->sigma_z2}, {"innov_floor", tun->innov_floor},
        {"innov_tau", tun->innov_tau}, {"rate_bandwidth", tun->rate_bandwidth},
        {"rate_span", tun->rate_span}, {"rate_dwell", tun->rate_dwell},
        {"q_Omega", tun->q_Omega}, {"q_param_rel", tun->q_param_rel},
        {"sigma0_k_rel", tun->sigma0_k_rel}, {"sigma0_d_rel", tun->sigma0_d_rel},
        {"sigma0_m_rel", tun->sigma0_m_rel}, {"sigma0_Omega", tun->sigma0_Omega},
        {"sigma0_Omega_rate", tun->sigma0_Omega_rate},
        {"sigma0_Omega_acc", tun->sigma0_Omega_acc},
        {"sigma0_position", tun->sigma0_position}, {"sigma0_velocity", tun->sigma0_velocity}};
    for (size_t i = 0; i < sizeof reals / sizeof reals[0]; i++)
        if (!(isfinite(reals[i].v) && reals[i].v >= 0.0)) {
            snprintf(msg, n, "%s=%s must be a finite number >= 0", reals[i].name,
                     gyro_real_text(reals[i].v, num));
            return 1;
        }
    if (tun->joseph != 0 && tun->joseph != 1) {
        snprintf(msg, n, "joseph=%d: use 1 (Joseph form) or 0", (int)tun->joseph);
        return 1;
    }
    if (tun->omega_order < 1 || tun->omega_order > 3) {
        snprintf(msg, n, "omega_order=%d: use 1 (random walk), 2 (integrated random walk) or 3",
                 (int)tun->omega_order);
        return 1;
    }
    if (tun->rate_model < 0 || tun->rate_model > 3) {
        snprintf(msg, n, "rate_model=%d: use 0 (adaptive), 1 (constant), 2 (tracking at "
                 "rate_bandwidth) or 3 (expert: q_Omega, omega_order)", (int)tun->rate_model);
        return 1;
    }
    const struct { const char *name, *unit; double v; } positive[] = {
        {"rate_bandwidth", "Hz", tun->rate_bandwidth}, {"rate_span", "rad/s", tun->rate_span},
        {"rate_dwell", "s", tun->rate_dwell}};
    for (int i = 0; i < 3; i++)
        if (positive[i].v <= 0.0) {
            snprintf(msg, n, "%s=%s must be > 0 (its unit: %s)", positive[i].name,
                     gyro_real_text(positive[i].v, num), positive[i].unit);
            return 1;
        }
    if (tun->noise_rel <= 0.0 && (tun->sigma_z1 <= 0.0 || tun->sigma_z2 <= 0.0)) {
        snprintf(msg, n, "noise_rel=%s: give noise_rel > 0 (e.g. 1e-6 for noise-free data) or "
                 "both sigma_z1 and sigma_z2 > 0", gyro_real_text(tun->noise_rel, num));
        return 1;
    }
    if (tun->innov_tau <= 0.0) {
        snprintf(msg, n, "innov_tau=%s s must be > 0", gyro_real_text(tun->innov_tau, num));
        return 1;
    }
    const struct { const char *name; double v; } sigma0[] = {
        {"sigma0_k_rel", tun->sigma0_k_rel}, {"sigma0_d_rel", tun->sigma0_d_rel},
        {"sigma0_m_rel", tun->sigma0_m_rel}, {"sigma0_Omega", tun->sigma0_Omega}};
    for (int i = 0; i < 4; i++)
        if (sigma0[i].v <= 0.0) {
            snprintf(msg, n, "%s=%s must be > 0: a zero initial uncertainty freezes that "
                     "estimate", sigma0[i].name, gyro_real_text(sigma0[i].v, num));
            return 1;
        }
    return 0;
}

void gyro_observer_set_scaling(GyroObserver *o, double wx, double wy,
                               const double theta0[GYRO_OBS_NPAR],
                               const double scale[GYRO_OBS_NPAR]) {
    o->wx = wx, o->wy = wy;
    memcpy(o->theta0, theta0, sizeof o->theta0);
    memcpy(o->scale, scale, sizeof o->scale);
    o->hgain[0] = o->pair == 1 ? 1.0 : wx;
    o->hgain[1] = o->pair == 1 ? 1.0 : wy;
    /* d(A_aug xi)/d(p, Omega_z): MgT[a][8 k + p] = Mg[k][p][a], rows 1 (k = 0), 3 (k = 1) */
    const double r = wy / wx;
    memset(o->MgT, 0, sizeof o->MgT);
    o->MgT[0][0] = -scale[0] / wx;
    o->MgT[2][8 + 1] = -scale[1] / wy;
    o->MgT[2][2] = -scale[2] / wx;
    o->MgT[0][8 + 2] = -scale[2] / wy;
    o->MgT[1][3] = -scale[3];
    o->MgT[3][8 + 4] = -scale[4];
    o->MgT[3][5] = -scale[5] * r;
    o->MgT[1][8 + 5] = -scale[5] / r;
    o->MgT[3][7] = 2.0 * r;
    o->MgT[1][8 + 7] = -2.0 / r;
    GyroMonitorLimits *lim = &o->lim;
    const GyroObserverTuning *tun = &o->tuning;
    lim->block = BLOCK;
    lim->absolute = tun->sigma_z1 > 0.0 && tun->sigma_z2 > 0.0;
    lim->nis_warn = chi2_quantile(2 * BLOCK, NIS_WARN_Z) / BLOCK; /* 0.9999 quantile */
    lim->nis_lost = NIS_LOST;
    lim->rel_warn = REL_WARN;
    lim->rel_lost = REL_LOST;
    lim->ratio = RATIO;
    lim->d_max = dmax(2.0 * sqrt(dmax(theta0[0], theta0[1])), RATIO * scale[3]);
    lim->omega_max = sqrt(dmin(theta0[0], theta0[1]));
    lim->corr_warn = CORR_WARN;
    lim->nis_min = NIS_MIN;
    o->h_cached = -1.0; /* the rate models are rebuilt at the next step */
}

int gyro_observer_init(GyroObserver *o, const GyroParams *guess, double Omega_z_0, int pair,
                       const GyroObserverTuning *tun, char *msg, size_t n) {
    char problems[GYRO_OBS_MESSAGE] = "", num[GYRO_REAL_TEXT];
    if (pair != 1 && pair != 2) {
        snprintf(msg, n, "measured_pair=%d is invalid: use 1 for positions (x, y) or 2 for "
                 "velocities (vx, vy)", pair);
        return 1;
    }
    if (gyro_params_problems(guess, problems, sizeof problems) == 0 && !(guess->kyy > 0.0))
        snprintf(problems, sizeof problems, "kyy=%s must be > 0",
                 gyro_real_text(guess->kyy, num));
    if (problems[0]) {
        snprintf(msg, n, "initial parameter guess is unusable: %s. Give a physical guess "
                 "(positive m, positive definite K)", problems);
        return 1;
    }
    if (!isfinite(Omega_z_0)) {
        snprintf(msg, n, "Omega_z_0=%s rad/s must be a finite number",
                 gyro_real_text(Omega_z_0, num));
        return 1;
    }
    if (gyro_rate_problem(guess, "Omega_z_0", Omega_z_0, problems, sizeof problems)) {
        snprintf(msg, n, "%s (the guessed kxx and kyy)", problems);
        return 1;
    }
    if (gyro_observer_tuning_problems(tun, msg, n)) return 1;
    memset(o, 0, sizeof *o);
    o->tuning = *tun;
    o->pair = pair;
    o->order = tun->rate_model == 1 ? 1 : tun->rate_model == 3 ? tun->omega_order : 3;
    o->n = 4 + GYRO_OBS_NPAR + o->order;
    o->n_models = tun->rate_model == 0 ? GYRO_OBS_MMAX : 1;
    o->i0 = pair == 1 ? 0 : 1;
    const double wx = sqrt(guess->kxx), wy = sqrt(guess->kyy);
    const double theta0[GYRO_OBS_NPAR] = {guess->kxx, guess->kyy, guess->kxy, guess->dxx,
                                          guess->dyy, guess->dxy, 1.0 / guess->m};
    const double d_scale = dmax(dmax(dmax(fabs(guess->dxx), fabs(guess->dyy)),
                                     fabs(guess->dxy)), 1e-3);
    const double kxy_scale = dmax(fabs(guess->kxy), 1e-2 * sqrt(guess->kxx * guess->kyy));
    const double scale[GYRO_OBS_NPAR] = {guess->kxx, guess->kyy, kxy_scale, d_scale, d_scale,
                                         d_scale, 1.0 / guess->m};
    gyro_observer_set_scaling(o, wx, wy, theta0, scale);
    /* prior */
    double sig[NMAX] = {0};
    o->auto_prior = tun->sigma0_position <= 0.0 || tun->sigma0_velocity <= 0.0;
    if (!o->auto_prior) {
        sig[0] = sig[2] = tun->sigma0_position;
        sig[1] = tun->sigma0_velocity / wx;
        sig[3] = tun->sigma0_velocity / wy;
    }
    for (int i = 0; i < 3; i++) sig[4 + i] = tun->sigma0_k_rel * fabs(theta0[i]) / scale[i];
    sig[7] = sig[8] = sig[9] = tun->sigma0_d_rel;
    sig[10] = tun->sigma0_m_rel;
    sig[IOM] = tun->sigma0_Omega;
    if (o->order >= 2) sig[IOM + 1] = tun->sigma0_Omega_rate;
    if (o->order >= 3) sig[IOM + 2] = tun->sigma0_Omega_acc;
    o->x[IOM] = Omega_z_0;
    for (int i = 0; i < o->n; i++) o->P[i][i] = sig[i] * sig[i];
    for (int j = 0; j < o->n_models; j++) {
        memcpy(o->xs[j], o->x, sizeof o->x);
        memcpy(o->Ps[j], o->P, sizeof o->P);
        o->mu[j] = 1.0 / o->n_models;
        o->c[j] = o->mu[j];
    }
    o->peak[0] = sig[o->i0] * o->hgain[0];
    o->peak[1] = sig[o->i0 + 2] * o->hgain[1];
    o->nu2[0] = o->nu2[1] = -1.0;
    o->refit.last_T = -1.0;
    return 0;
}

/* The signal size (m) that starts the auto prior; 0: at rest. */
static double prior_size(const GyroObserver *o, double ux, double uy, double z1, double z2) {
    const double *th = o->theta0, *g = o->hgain;
    const double a = fabs(z1) > 3.0 * o->tuning.sigma_z1 ? fabs(z1) / g[0] : 0.0;
    const double b = fabs(z2) > 3.0 * o->tuning.sigma_z2 ? fabs(z2) / g[1] : 0.0;
    const double c = th[6] * fabs(ux) / th[0], d = th[6] * fabs(uy) / th[1];
    double size = a;
    if (b > size) size = b;
    if (c > size) size = c;
    if (d > size) size = d;
    return size;
}

/* Scale-invariant prior of [x, vx, y, vy]: at rest until the first drive or measurement
 * above its noise, then 1-sigma = PRIOR_FRACTION of the static deflection b |u| / k
 * (drive) or PRIOR_FRACTION_MEASURED of the measured displacement. */
static void start_prior(GyroObserver *o, double ux, double uy, double z1, double z2) {
    double size = prior_size(o, ux, uy, z1, z2);
    if (!(size > 0.0)) return;
    for (int j = 0; j < 2; j++) o->peak[j] = dmax(o->peak[j], size * o->hgain[j]);
    size *= (ux != 0.0 || uy != 0.0) ? PRIOR_FRACTION : PRIOR_FRACTION_MEASURED;
    for (int i = 0; i < 4; i++) {
        o->P[i][i] += size * size;
        for (int j = 0; j < o->n_models; j++) o->Ps[j][i][i] += size * size;
    }
    o->auto_prior = 0;
}

/* The common refusals of step, update and predict (nothing changes); with_step: the step
 * h is propagated over (a new h is checked against the resonance). */
static int refusal(GyroObserver *o, double h, const char *const names[], const double *values,
                   int count, int with_step, char *msg, size_t n) {
    char num[GYRO_REAL_TEXT];
    if (!(h > 0.0 && isfinite(h))) {
        snprintf(msg, n, "step h=%s s must be finite and > 0", gyro_real_text(h, num));
        return GYRO_OBS_BAD_INPUT;
    }
    int finite = 1;
    for (int i = 0; i < count; i++) finite &= isfinite(values[i]) != 0;
    if (!finite) {
        size_t used = (size_t)snprintf(msg, n, "non-finite input ");
        for (int i = 0; i < count && used < n; i++)
            used += (size_t)snprintf(msg + used, n - used, "%s%s=%s", i ? ", " : "", names[i],
                                     gyro_real_text(values[i], num));
        if (used < n) snprintf(msg + used, n - used, ": pass finite forces (N) and measurements");
        return GYRO_OBS_BAD_INPUT;
    }
    if (o->lost) {
        snprintf(msg, n, "%s", o->lost_message);
        return GYRO_OBS_REFUSED;
    }
    const double omega = dmax(o->wx, o->wy);
    if (with_step && h != o->h_cached && omega * h > OMEGA_H_MAX) {
        snprintf(msg, n, "communication step %.4g s too coarse for the observer: it samples the "
                 "gyro's guessed resonance (%.5g Hz) at omega h = %.3g > %g (aliasing: the "
                 "motion cannot be told from the samples); use a step <= %.3g s", h,
                 omega / (2 * GYRO_PI), omega * h, OMEGA_H_MAX, OMEGA_H_MAX / omega);
        return GYRO_OBS_TOO_COARSE;
    }
    return 0;
}

int gyro_observer_step_warning(const GyroObserver *o, double h, char *msg, size_t n) {
    const double omega = dmax(o->wx, o->wy);
    if (n) msg[0] = '\0';
    if (!(omega * h > OMEGA_H_WARN && omega * h <= OMEGA_H_MAX)) return 0;
    snprintf(msg, n, "communication step %.4g s is coarse for the observer: it samples the "
             "gyro's guessed resonance (%.5g Hz) at omega h = %.3g, above %g, where the "
             "estimates and their sigmas degrade well before the refusal at %g; use a step "
             "<= %.3g s", h, omega / (2 * GYRO_PI), omega * h, OMEGA_H_WARN, OMEGA_H_MAX,
             OMEGA_H_WARN / omega);
    return 1;
}

/* Act on a monitor verdict after a step of h. */
static int verdict(GyroObserver *o, int code, double h, char *msg, size_t n) {
    if (code == o->status) return code;
    if (code < 2) {
        o->status = code;
        return code;
    }
    lose(o, h);
    snprintf(msg, n, "%s", o->lost_message);
    return GYRO_OBS_STEP_LOST;
}

int gyro_observer_step(GyroObserver *o, double ux, double uy, double z1, double z2, double h,
                       char *msg, size_t n) {
    static const char *const names[4] = {"ux", "uy", "z1", "z2"};
    const double values[4] = {ux, uy, z1, z2};
    const int refused = refusal(o, h, names, values, 4, 1, msg, n);
    if (refused) return refused;
    if (h != o->h_cached) gyro_observer_set_step(o, h);
    double pv = 0.0, pk0 = 0.0, pk1 = 0.0; /* a prior started by the drive: before predict */
    if (o->auto_prior) {
        start_prior(o, 0.0, 0.0, z1, z2);
        if (o->auto_prior) {
            const double size = prior_size(o, ux, uy, 0.0, 0.0);
            if (size > 0.0) {
                const double q = PRIOR_FRACTION * size;
                pv = q * q, pk0 = size * o->hgain[0], pk1 = size * o->hgain[1];
                o->auto_prior = 0;
            }
        }
    }
    imm_update(o, z1, z2, h);
    if (pv > 0.0) {
        o->peak[0] = dmax(o->peak[0], pk0);
        o->peak[1] = dmax(o->peak[1], pk1);
        for (int i = 0; i < 4; i++) /* every filter; P is their mixture after the predict */
            for (int j = 0; j < o->n_models; j++) o->Ps[j][i][i] += pv;
    }
    imm_predict(o, ux, uy, h);
    const int code = monitor_check(o);
    o->t += h;
    return verdict(o, code, h, msg, n);
}

int gyro_observer_update(GyroObserver *o, double z1, double z2, double h, char *msg, size_t n) {
    static const char *const names[2] = {"z1", "z2"};
    const double values[2] = {z1, z2};
    const int refused = refusal(o, h, names, values, 2, 0, msg, n);
    if (refused) return refused;
    if (o->auto_prior) start_prior(o, 0.0, 0.0, z1, z2);
    imm_update(o, z1, z2, h);
    return o->status;
}

int gyro_observer_predict(GyroObserver *o, double ux, double uy, double h, char *msg,
                          size_t n) {
    static const char *const names[2] = {"ux", "uy"};
    const double values[2] = {ux, uy};
    const int refused = refusal(o, h, names, values, 2, 1, msg, n);
    if (refused) return refused;
    if (h != o->h_cached) gyro_observer_set_step(o, h);
    if (o->auto_prior) start_prior(o, ux, uy, 0.0, 0.0);
    imm_predict(o, ux, uy, h);
    o->t += h;
    return verdict(o, monitor_check(o), h, msg, n);
}

void gyro_observer_outputs(const GyroObserver *o, double out[20]) {
    const double *x = o->x;
    const double T[4] = {1.0, 1.0 / o->wx, 1.0, 1.0 / o->wy};
    for (int i = 0; i < 4; i++) out[i] = x[i] / T[i];
    out[4] = x[IOM];
    for (int i = 0; i < 6; i++) out[5 + i] = o->theta0[i] + o->scale[i] * x[IPAR + i];
    const double b = o->theta0[6] + o->scale[6] * x[IPAR + 6];
    out[11] = 1.0 / b;
    out[12] = sqrt(dmax(o->P[IOM][IOM], 0.0));
    for (int i = 0; i < 6; i++) out[13 + i] = sqrt(dmax(o->P[IPAR + i][IPAR + i], 0.0)) * o->scale[i];
    out[19] = sqrt(dmax(o->P[IPAR + 6][IPAR + 6], 0.0)) * o->scale[6] / (b * b);
}

void gyro_observer_rate_probabilities(const GyroObserver *o, double p[4]) {
    p[0] = p[1] = p[2] = p[3] = 0.0;
    switch (o->tuning.rate_model) {
    case 0:
        memcpy(p, o->c, 4 * sizeof(double));
        for (int j = 4; j < o->n_models; j++) p[1] += o->c[j]; /* graded rough models */
        break;
    case 1: p[0] = 1.0; break;
    case 2: p[3] = 1.0; break;
    default: break;
    }
}

static int all_finite(const double *v, size_t count) {
    for (size_t i = 0; i < count; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* Every field of a restored state that the step reads, checked (NULL: usable): finite
 * numbers, probabilities in [0, 1], indices and counts in their ranges, a terminated
 * message. The rate models over h_cached are rebuilt at the next step (not trusted). */
static const char *restored_state_problem(const GyroObserver *o) {
    const int n = o->n, M = o->n_models;
    if (!(isfinite(o->t) && o->t >= 0.0)) return "a time that is not finite and >= 0";
    if (!(all_finite(o->peak, 2) && o->peak[0] >= 0.0 && o->peak[1] >= 0.0))
        return "signal peaks that are not finite and >= 0";
    if (!all_finite(o->nu2, 2)) return "innovation powers that are not finite";
    for (int i = 0; i < n; i++)
        if (!(isfinite(o->x[i]) && all_finite(o->P[i], (size_t)n)))
            return "a combined estimate or covariance that is not finite";
    for (int j = 0; j < M; j++) {
        if (!all_finite(o->xs[j], (size_t)n)) return "a rate model's estimate that is not finite";
        for (int i = 0; i < n; i++)
            if (!all_finite(o->Ps[j][i], (size_t)n))
                return "a rate model's covariance that is not finite";
        if (!(o->mu[j] >= 0.0 && o->mu[j] <= 1.0 && o->c[j] >= 0.0 && o->c[j] <= 1.0))
            return "model probabilities outside [0, 1]";
    }
    const GyroMonitor *m = &o->mon;
    if (!all_finite(&m->nis, sizeof *m / sizeof(double))) return "monitor numbers not finite";
    if (!(m->count >= 0.0 && m->count <= o->lim.block && m->block >= 0.0 &&
          m->status >= 0.0 && m->status <= GYRO_MON_INNOVATIONS && m->cause >= 0.0 &&
          m->cause <= GYRO_MON_INNOVATIONS && m->which >= -1.0 && m->which <= 7.0 &&
          m->status == floor(m->status) && m->cause == floor(m->cause) &&
          m->which == floor(m->which)))
        return "a monitor count, verdict or index out of its range";
    const GyroRefit *r = &o->refit;
    if (!all_finite(&r->W[0][0], sizeof *r / sizeof(double))) return "re-fit numbers not finite";
    if (!(r->restarts >= 0.0 && r->restarts <= 1e9 && r->weight >= 0.0))
        return "a re-fit count out of its range";
    if (o->status < 0 || o->status > 2 || (o->lost != 0 && o->lost != 1) ||
        (o->auto_prior != 0 && o->auto_prior != 1))
        return "an unknown status";
    if (!memchr(o->lost_message, '\0', sizeof o->lost_message)) return "an unterminated message";
    return NULL;
}

int gyro_observer_restored_problem(GyroObserver *o, const GyroParams *guess,
                                   double Omega_z_0, int pair, const GyroObserverTuning *tun,
                                   char *msg, size_t n) {
    GyroObserver fresh;
    if (gyro_observer_init(&fresh, guess, Omega_z_0, pair, tun, msg, n)) return 1;
    const int same = memcmp(&fresh.tuning, &o->tuning, sizeof fresh.tuning) == 0 &&
                     fresh.pair == o->pair && fresh.n == o->n && fresh.order == o->order &&
                     fresh.n_models == o->n_models && fresh.i0 == o->i0 &&
                     memcmp(fresh.theta0, o->theta0, sizeof fresh.theta0) == 0 &&
                     memcmp(fresh.scale, o->scale, sizeof fresh.scale) == 0 &&
                     memcmp(&fresh.lim, &o->lim, sizeof fresh.lim) == 0 &&
                     memcmp(fresh.MgT, o->MgT, sizeof fresh.MgT) == 0 &&
                     memcmp(&fresh.wx, &o->wx, sizeof o->wx) == 0 &&
                     memcmp(&fresh.wy, &o->wy, sizeof o->wy) == 0 &&
                     memcmp(fresh.hgain, o->hgain, sizeof o->hgain) == 0;
    if (!same) {
        snprintf(msg, n, "the saved observer was built from other parameters (initial guesses, "
                 "measured_pair or tuning) than this instance's");
        return 1;
    }
    const char *bad = restored_state_problem(o);
    if (bad) {
        snprintf(msg, n, "the saved observer holds %s: restore a state this FMU saved", bad);
        return 1;
    }
    o->h_cached = -1.0; /* the rate models (Fr, Qr, Pi, qpar) are rebuilt at the next step */
    return 0;
}
