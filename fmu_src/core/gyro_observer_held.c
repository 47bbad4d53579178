/* The observer's held step (US 2011/0314910 A1 eq. 5): the exact held-input step of the
 * scaled plant state and its sensitivities to the parameters and Omega_z, by a Taylor
 * (Frechet) series, split into sub-steps when ||A h|| is large (docs/bounded-work.md). Its
 * weights GYRO_OBS_BETA come from the generated gyro_tables.h. */
#include "gyro_observer_internal.h"

double gyro_observer_beta(int j, int m) {
    return j >= 0 && j < KMAX && m >= 0 && m < KMAX ? GYRO_OBS_BETA[j][m] : -1.0;
}

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
    double st[KMAX][5][5], G[KMAX][16], Gb[KMAX][16];
    memset(st[0], 0, sizeof st[0]);
    for (int a = 0; a < 5; a++) st[0][a][a] = 1.0;
    const int K = n_terms(inf_norm_4x5(Ah));
    /* Loops below run their innermost index over contiguous memory (the compiler
     * vectorizes them) while every sum keeps its order: the same bits as a dot product. */
    for (int j = 0; j < K - 1; j++) {
        const double inv = 1.0 / (j + 1);
        double Ahi[5][5];
        for (int b = 0; b < 5; b++)
            for (int c = 0; c < 5; c++) Ahi[b][c] = Ah[b][c] * inv;
        for (int a = 0; a < 5; a++) {
            double acc[5] = {0.0, 0.0, 0.0, 0.0, 0.0};
            for (int b = 0; b < 5; b++)
                for (int c = 0; c < 5; c++) acc[c] += st[j][a][b] * Ahi[b][c];
            for (int c = 0; c < 5; c++) st[j + 1][a][c] = acc[c];
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
    for (int j = 0; j < K; j++) { /* Gb[j] = sum_m beta[j][m] G[m] */
        const double *beta = GYRO_OBS_BETA[j]; /* j! m! / (j + m + 1)! */
        double acc[16] = {0.0};
        for (int m = 0; m < K; m++)
            for (int q = 0; q < 16; q++) acc[q] += beta[m] * G[m][q];
        for (int q = 0; q < 16; q++) Gb[j][q] = acc[q];
    }
    for (int i = 0; i < 4; i++) {
        double acc[8] = {0.0};
        for (int j = 0; j < K; j++)
            for (int q = 0; q < 8; q++) acc[q] += st[j][i][1] * Gb[j][q] + st[j][i][3] * Gb[j][8 + q];
        for (int q = 0; q < 8; q++) S[i][q] = acc[q] * h;
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

/* ||dA_aug h||_inf for a move of the filter's point from the maps' xc, by the triangle
 * inequality over the 8 coordinates (dA_aug is linear in the move; rows 1 and 3 only). */
static double held_move(const GyroObserver *o, const double *x, double ux, double uy,
                        double h) {
    const GyroObsHeld *c = &o->held;
    const double force = o->scale[6] * dmax(fabs(ux) / o->wx, fabs(uy) / o->wy) * h;
    double bound = 0.0;
    for (int q = 0; q < 8; q++)
        bound += fabs(x[IPAR + q] - c->xc[q]) * (c->norm[q] + (q == 6 ? force : 0.0));
    return bound;
}

/* Start watching a new point: xc = x's, the maps not valid, the norms for h. */
static void held_watch(GyroObserver *o, const double *x, double h) {
    GyroObsHeld *c = &o->held;
    c->valid = 0.0;
    c->steady = 0.0;
    c->h = h;
    memcpy(c->xc, x + IPAR, sizeof c->xc);
    for (int q = 0; q < 8; q++) {
        double r1 = 0.0, r3 = 0.0;
        for (int a = 0; a < 4; a++) r1 += fabs(o->MgT[a][q]), r3 += fabs(o->MgT[a][8 + q]);
        c->norm[q] = dmax(r1, r3) * h;
    }
}

/* The maps at (xc, h): six exact held steps, one per unit coordinate of [s, ux, uy] (the
 * held step is linear in them). 0 when a map is not finite (the maps stay not valid). */
static int held_build(GyroObserver *o) {
    GyroObsHeld *c = &o->held;
    double theta[GYRO_OBS_NPAR], s1[4], Phi[4][4];
    for (int i = 0; i < GYRO_OBS_NPAR; i++) theta[i] = o->theta0[i] + o->scale[i] * c->xc[i];
    for (int k = 0; k < 6; k++) {
        double s[4] = {0.0, 0.0, 0.0, 0.0};
        if (k < 4) s[k] = 1.0;
        gyro_observer_held_step(o, theta, c->xc[7], s, k == 4, k == 5, c->h, s1, Phi, c->Sk[k]);
        if (k < 4) memcpy(c->Phi, Phi, sizeof Phi);
        else memcpy(c->psi[k - 4], s1, sizeof s1);
    }
    const int finite = all_finite(&c->Phi[0][0], 16) && all_finite(&c->psi[0][0], 8) &&
                       all_finite(&c->Sk[0][0][0], 6 * 32);
    c->valid = finite;
    return finite;
}

/* The held step from the maps, corrected to first order for d = x - xc: S at xc from [s, u];
 * Phi + dPhi/dx d; s1 = Phi_c s + psi u + S d (the neglected terms are O(||dA_aug h||^2)). */
static void held_reuse(const GyroObsHeld *c, const double *x, double ux, double uy,
                       double s1[4], double Phi[4][4], double S[4][8]) {
    const double w[6] = {x[0], x[1], x[2], x[3], ux, uy};
    double d[8];
    for (int q = 0; q < 8; q++) d[q] = x[IPAR + q] - c->xc[q];
    for (int i = 0; i < 4; i++) {
        double acc[8] = {0.0};
        for (int k = 0; k < 6; k++)
            for (int q = 0; q < 8; q++) acc[q] += w[k] * c->Sk[k][i][q];
        memcpy(S[i], acc, sizeof acc);
        double e = c->psi[0][i] * ux + c->psi[1][i] * uy;
        for (int k = 0; k < 4; k++) {
            double dphi = 0.0;
            for (int q = 0; q < 8; q++) dphi += c->Sk[k][i][q] * d[q];
            Phi[i][k] = c->Phi[i][k] + dphi;
            e += c->Phi[i][k] * x[k];
        }
        for (int q = 0; q < 8; q++) e += acc[q] * d[q];
        s1[i] = e;
    }
}

/* The held step of x's plant state at x's parameters and Omega_z (the linearization).
 * Converged parameters move 1e-16 to 1e-12 relative a step, so the maps are built once the
 * point has stayed within HELD_TOL of one xc for HELD_STEADY steps and reused while it
 * stays there (docs/results/performance.md); otherwise the exact held step. */
void obs_linearize(GyroObserver *o, const double *x, double ux, double uy, double h,
                   double s1[4], double Phi[4][4], double S[4][8]) {
    GyroObsHeld *c = &o->held;
    if (c->tol > 0.0) {
        const double move = c->h == h ? held_move(o, x, ux, uy, h) : INFINITY;
        if (c->valid && move <= c->tol) {
            c->reused += 1.0;
            held_reuse(c, x, ux, uy, s1, Phi, S);
            return;
        }
        if (move <= c->tol) {
            c->steady += 1.0;
        } else {
            held_watch(o, x, h);
        }
        if (c->steady >= HELD_STEADY) {
            held_watch(o, x, h);
            c->built += 1.0;
            if (held_build(o)) {
                c->reused += 1.0;
                held_reuse(c, x, ux, uy, s1, Phi, S);
                return;
            }
        }
    }
    double theta[GYRO_OBS_NPAR];
    for (int i = 0; i < GYRO_OBS_NPAR; i++) theta[i] = o->theta0[i] + o->scale[i] * x[IPAR + i];
    gyro_observer_held_step(o, theta, x[IOM], x, ux, uy, h, s1, Phi, S);
}

void obs_held_reset(GyroObserver *o) {
    GyroObsHeld *c = &o->held;
    memset(c, 0, sizeof *c);
    c->tol = HELD_TOL;
    c->h = -1.0;
}

const char *obs_held_restored(GyroObserver *o) {
    GyroObsHeld *c = &o->held;
    if (!(c->tol == 0.0 || c->tol == HELD_TOL) || !(c->valid == 0.0 || c->valid == 1.0) ||
        !(c->steady >= 0.0 && c->steady <= HELD_STEADY) || !isfinite(c->h))
        return "a held-step cache out of its range";
    for (int q = 0; q < 8; q++)
        if (!isfinite(c->xc[q])) return "a held-step cache not finite";
    /* the maps and norms are rebuilt from (xc, h): the same bits as the saved ones */
    const double valid = c->valid, steady = c->steady;
    double xc[IPAR + 8];
    memcpy(xc + IPAR, c->xc, sizeof c->xc);
    if (c->h > 0.0) held_watch(o, xc, c->h);
    c->steady = steady;
    if (valid == 1.0 && !(c->h > 0.0 && held_build(o))) return "a held-step cache not valid";
    return NULL;
}
