/* The observer's held step (US 2011/0314910 A1 eq. 5): the exact held-input step of the
 * scaled plant state and its sensitivities to the parameters and Omega_z, by a Taylor
 * (Frechet) series, split into sub-steps when ||A h|| is large (docs/bounded-work.md). */
#include "gyro_observer_internal.h"

const double gyro_obs_factorial_table[48] = {
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
void obs_linearize(const GyroObserver *o, const double *x, double ux, double uy, double h,
                      double s1[4], double Phi[4][4], double S[4][8]) {
    double theta[GYRO_OBS_NPAR];
    for (int i = 0; i < GYRO_OBS_NPAR; i++) theta[i] = o->theta0[i] + o->scale[i] * x[IPAR + i];
    gyro_observer_held_step(o, theta, x[IOM], x, ux, uy, h, s1, Phi, S);
}
