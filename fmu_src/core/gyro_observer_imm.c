/* The interacting multiple models over the observer's rate models (Bar-Shalom, Li &
 * Kirubarajan 2001, sec. 11.6.6, eqs. 11.6.6-1 to -22): mixing, each model's correction
 * and likelihood, the probabilities, each model's prediction, the combined estimate. */
#include "gyro_observer_internal.h"

/* x = the mean of the filters' mixture with weights w (eq. 11.6.6-21). */
static void mixture_mean(const GyroObserver *o, const double xs[][NMAX], const double *w,
                         double *x) {
    const int M = o->n_models, n = o->n;
    double acc[NMAX] = {0.0}; /* each row's sum over j in order, all rows at once */
    for (int j = 0; j < M; j++)
        for (int i = 0; i < NMAX; i++) acc[i] += w[j] * xs[j][i];
    memcpy(x, acc, n * sizeof(double));
}

/* x, P = the mixture of the filters (xs, Ps) with weights w (eqs. 11.6.6-21, -22). */
static void combine(const GyroObserver *o, const double xs[][NMAX],
                    const double Ps[][NMAX][NMAX], const double *w, double *x,
                    double P[NMAX][NMAX]) {
    const int M = o->n_models, n = o->n;
    mixture_mean(o, xs, w, x);
    if (M == 1) {
        memcpy(P, Ps[0], sizeof(double) * NMAX * NMAX);
        return;
    }
    /* P[a][b] = sum_j w_j (Ps_j[a][b] + d_j[a] d_j[b]), d_j = xs_j - x, summed over j in
     * order for every b at once. The inner loop runs over all NMAX columns (a fixed length
     * the compiler unrolls and vectorizes; it left a triangle's varying one scalar; columns
     * past n hold what the filters' rows hold there, finite). The filters' P are symmetric
     * to the bit (restored_state_problem checks a restored one), and so is each entry's
     * expression in (a, b), so the rows make a P symmetric to the bit. */
    double d[GYRO_OBS_MMAX][NMAX] = {{0.0}};
    for (int j = 0; j < M; j++)
        for (int a = 0; a < n; a++) d[j][a] = xs[j][a] - x[a];
    for (int a = 0; a < n; a++) {
        double acc[NMAX] = {0.0};
        for (int j = 0; j < M; j++) {
            const double wj = w[j], dja = d[j][a], *Pja = Ps[j][a], *dj = d[j];
            for (int b = 0; b < NMAX; b++) acc[b] += wj * (Pja[b] + dja * dj[b]);
        }
        memcpy(P[a], acc, n * sizeof(double));
    }
}

/* x and the entries of P the step reads between predictions: the diagonal (the sigmas)
 * and the columns of the measured rows i0, i1 (the innovations' covariance and the re-fit
 * test's gain), each the same sum as combine's, so the same bits. The rest waits for
 * gyro_observer_complete_covariance (o->P_partial). */
static void combine_partial(const GyroObserver *o, const double xs[][NMAX],
                            const double Ps[][NMAX][NMAX], const double *w, double *x,
                            double P[NMAX][NMAX]) {
    const int M = o->n_models, n = o->n, i0 = o->i0, i1 = o->i0 + 2;
    mixture_mean(o, xs, w, x);
    double d[GYRO_OBS_MMAX][NMAX] = {{0.0}};
    for (int j = 0; j < M; j++)
        for (int a = 0; a < n; a++) d[j][a] = xs[j][a] - x[a];
    /* the measured rows over all NMAX columns (Ps_j symmetric to the bit, so row i0 is
     * column i0: contiguous, vectorized), and the diagonal */
    double r0[NMAX] = {0.0}, r1[NMAX] = {0.0}, dg[NMAX] = {0.0};
    for (int j = 0; j < M; j++) {
        const double wj = w[j], d0 = d[j][i0], d1 = d[j][i1], *dj = d[j];
        const double *P0 = Ps[j][i0], *P1 = Ps[j][i1];
        for (int a = 0; a < NMAX; a++) {
            r0[a] += wj * (P0[a] + dj[a] * d0);
            r1[a] += wj * (P1[a] + dj[a] * d1);
        }
        for (int a = 0; a < n; a++) dg[a] += wj * (Ps[j][a][a] + dj[a] * dj[a]);
    }
    for (int a = 0; a < n; a++) {
        P[a][i0] = P[i0][a] = r0[a];
        P[a][i1] = P[i1][a] = r1[a];
        P[a][a] = dg[a];
    }
}

void gyro_observer_complete_covariance(GyroObserver *o) {
    if (!o->P_partial) return;
    combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, o->c, o->x,
            o->P);
    o->P_partial = 0;
}

/* 1 when Pi is the uniform switching matrix obs_set_rates builds (stay = Pi[j][j] on the
 * diagonal, leave = Pi[i][j] off it, for every i, j). */
static int uniform_switching(const GyroObserver *o, double *stay, double *leave) {
    const int M = o->n_models;
    *stay = o->Pi[0][0], *leave = o->Pi[1][0];
    for (int i = 0; i < M; i++)
        for (int j = 0; j < M; j++)
            if (o->Pi[i][j] != (i == j ? *stay : *leave)) return 0;
    return 1;
}

/* P = aj P + bj T + ab e e' over P's first `rows` rows and `cols` columns (a constant:
 * fixed-length rows the compiler vectorizes). Each entry is the same expression of (a, b)
 * and (b, a) (ab (e_a e_b), not (ab e_a) e_b), so a symmetric P and T give a P symmetric
 * to the bit without a mirrored triangle. */
FIXED_LENGTH void mix_rows(double P[NMAX][NMAX], const double T[NMAX][NMAX],
                           const double e[NMAX], double aj, double bj, double ab, int rows,
                           const int cols) {
    for (int a = 0; a < rows; a++) {
        const double ea = e[a];
        for (int b = 0; b < cols; b++) P[a][b] = aj * P[a][b] + bj * T[a][b] + ab * (ea * e[b]);
    }
}

/* Mixing (eqs. 11.6.6-6 to -11): model j starts from the mixture of the filters with
 * weights Pi[i][j] mu_i / c_j, c_j = sum_i Pi[i][j] mu_i (the predicted probabilities).
 * For the uniform switching of obs_set_rates (stay on the diagonal, leave off it) the
 * weights are leave mu_i / c_j plus (stay - leave) mu_j / c_j on j's own filter, so with
 * xbar, T the mu-mixture of all the filters (one mixture, not M) and e_j = x_j - xbar:
 *     x0j = a_j x_j + (1 - a_j) xbar,    a_j = (stay - leave) mu_j / c_j,
 *     P0j = a_j P_j + (1 - a_j) T + a_j (1 - a_j) e_j e_j'
 * (the same mixture in exact arithmetic: sum_i w_i (P_i + d_i d_i') with d_i = e_i -
 * a_j e_j; every term positive semi-definite, as before). obs_set_rates always builds Pi
 * so (a restored state's too: it is rebuilt at the next step); a Pi set otherwise
 * through the struct takes the general sum. With for_predict, the uniform switching's
 * filters are mixed only in their model_rows: the prediction that follows sets the rest
 * to zero from any finite values, so its results are the same numbers (a zero's sign
 * aside). */
static void mix(GyroObserver *o, int for_predict) {
    const int M = o->n_models, n = o->n;
    if (M == 1) {
        o->c[0] = 1.0;
        return;
    }
    double stay, leave;
    if (!uniform_switching(o, &stay, &leave)) {
        double x0[GYRO_OBS_MMAX][NMAX], P0[GYRO_OBS_MMAX][NMAX][NMAX], wj[GYRO_OBS_MMAX];
        for (int j = 0; j < M; j++) {
            double acc = 0.0;
            for (int i = 0; i < M; i++) acc += o->Pi[i][j] * o->mu[i];
            o->c[j] = acc;
            for (int i = 0; i < M; i++) wj[i] = o->Pi[i][j] * o->mu[i] / acc;
            combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, wj,
                    x0[j], P0[j]);
        }
        for (int j = 0; j < M; j++) {
            memcpy(o->xs[j], x0[j], n * sizeof(double));
            for (int a = 0; a < n; a++) memcpy(o->Ps[j][a], P0[j][a], n * sizeof(double));
        }
        return;
    }
    double total = 0.0, w[GYRO_OBS_MMAX], xbar[NMAX], T[NMAX][NMAX];
    for (int i = 0; i < M; i++) total += o->mu[i];
    for (int i = 0; i < M; i++) w[i] = o->mu[i] / total;
    combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, w, xbar, T);
    for (int j = 0; j < M; j++) {
        const double own = (stay - leave) * o->mu[j];
        o->c[j] = own + leave * total;
        const double aj = own / o->c[j], bj = 1.0 - aj, ab = aj * bj;
        const int rows = for_predict ? model_rows(o, j) : n;
        double e[NMAX] = {0.0};
        for (int a = 0; a < rows; a++) e[a] = o->xs[j][a] - xbar[a];
        if (rows <= IOM + 1)
            mix_rows(o->Ps[j], (const double(*)[NMAX])T, e, aj, bj, ab, rows, IOM + 1);
        else
            mix_rows(o->Ps[j], (const double(*)[NMAX])T, e, aj, bj, ab, rows, NMAX);
        for (int a = 0; a < rows; a++) o->xs[j][a] = aj * o->xs[j][a] + bj * xbar[a];
    }
}

void gyro_observer_mix(GyroObserver *o) { mix(o, 0); }

void gyro_observer_combine(const GyroObserver *o, const double *w, double *x,
                           double P[GYRO_OBS_NMAX][GYRO_OBS_NMAX]) {
    combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, w, x, P);
}

/* IMM correction at t: every filter corrected with the noise variances of the combined
 * prediction; mu = c x likelihood, normalized (eqs. 11.6.6-15 to -19); x combined, and P
 * when with_P (the split API's update, whose P the outputs read; in gyro_observer_step
 * the prediction's mixture replaces P before anything reads it, so it is not made). */
void obs_imm_update(GyroObserver *o, double z1, double z2, double h, int with_P) {
    double R[2], Rc[2], nu[2], ll[GYRO_OBS_MMAX];
    obs_noise_variances(o, z1, z2, h, R, Rc, nu);
    obs_monitor_innovations(o, nu, R);
    obs_refit_correct(o, nu, R, h);
    const int M = o->n_models;
    const double wander_x0 = o->xs[0][IOM], wander_p0 = o->Ps[0][IOM][IOM];
    for (int j = 0; j < M; j++) {
        double logdet;
        const double nis = obs_correct_with(o, o->xs[j], o->Ps[j], model_rows(o, j), z1, z2, R,
                                            Rc, &logdet);
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
        if (o->tuning.rate_model == 4) obs_bank_move(o);
        if (o->tuning.rate_model == 0) obs_wander_step(o, wander_x0, wander_p0, h);
    } else {
        o->mu[0] = 1.0;
    }
    if (with_P) {
        combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, o->mu,
                o->x, o->P);
        o->P_partial = 0;
    } else
        mixture_mean(o, (const double(*)[NMAX])o->xs, o->mu, o->x);
}

/* Propagate one filter's x, P to t + h linearized about xbar ((s1, Phi, S) its held step):
 * x[:4] -> s1 + Phi (x[:4] - xbar[:4]) + S (x[4:12] - xbar[4:12]), process noise q0 on x,
 * vx and q1 on y, vy; parameters a random walk of qpar per step; the rate block
 * x[IOM:] -> Fr x[IOM:] with noise Qr. P -> F P F' + Q, symmetrized.
 * F's structure is used: F = [[Phi S], [0 I], [0 Fr]] by blocks (plant, parameters, rate;
 * S reaches Omega_z too), so A = F P has new rows only for the plant and the rate block,
 * and B = A F' only where a plant or rate row meets a plant or rate column: the
 * parameters' block is P's, and a parameter row of B is a column of A (P is symmetric bit
 * for bit, so A F' and (F P)' agree there to the bit). Every entry is the same sum, in
 * the same order, as the full products (F P) F' symmetrized by halves: the bits of the
 * unstructured propagation (tests/test_native_observer.py, against the numba oracle).
 * The rate block's rows and columns past the model's order ro are zero (Fr's rows there
 * are zero, and its columns there multiply nothing): they are set, not summed; every other
 * sum drops only Fr's zero terms, so the numbers are the same (a zero's sign aside). */
static inline void times_plant_rows(const double *a, const double FpT[12][4], double out[4]) {
    double acc[4] = {0.0}; /* sum_c a[c] F[j][c] over the plant rows j of F (Phi, then S),
                            * FpT[c][j] = F[j][c]: the four sums side by side, each in order */
    for (int c = 0; c < 12; c++)
        for (int j = 0; j < 4; j++) acc[j] += a[c] * FpT[c][j];
    memcpy(out, acc, sizeof acc);
}

/* A = F P's plant rows over P's first `cols` columns (the rest zeros). Called with a
 * constant cols: the innermost loop has a fixed length the compiler unrolls and
 * vectorizes. */
FIXED_LENGTH void plant_rows_of_FP(const double P[NMAX][NMAX], const double Phi[4][4],
                                  const double S[4][8], const int cols, double A[4][NMAX]) {
    for (int i = 0; i < 4; i++) {
        double acc[NMAX] = {0.0};
        for (int c = 0; c < 4; c++)
            for (int k = 0; k < cols; k++) acc[k] += Phi[i][c] * P[c][k];
        for (int c = 0; c < 8; c++)
            for (int k = 0; k < cols; k++) acc[k] += S[i][c] * P[4 + c][k];
        memcpy(A[i], acc, sizeof acc);
    }
}

static void predict_about(const GyroObserver *o, const double *xbar, const double s1[4],
                          const double Phi[4][4], const double S[4][8],
                          const double FpT[12][4], double *x,
                          double P[NMAX][NMAX], const double Fr[][GYRO_OBS_RMAX],
                          const double Qr[][GYRO_OBS_RMAX], int ro, double q0, double q1) {
    const int n = o->n, r = n - IOM;
    double d[12], om[GYRO_OBS_RMAX], A[4][NMAX], Ar[GYRO_OBS_RMAX][NMAX];
    for (int c = 0; c < 12; c++) d[c] = x[c] - xbar[c];
    for (int i = 0; i < 4; i++) {
        double acc = s1[i];
        for (int c = 0; c < 4; c++) acc += Phi[i][c] * d[c];
        for (int c = 0; c < 8; c++) acc += S[i][c] * d[4 + c];
        x[i] = acc;
    }
    for (int a = 0; a < r; a++) {
        double acc = 0.0;
        for (int c = 0; c < ro; c++) acc += Fr[a][c] * x[IOM + c];
        om[a] = a < ro ? acc : 0.0;
    }
    for (int a = 0; a < r; a++) x[IOM + a] = om[a];
    /* A = F P, the plant's rows (plant_rows_of_FP) and the rate block's, each row's
     * innermost loop of a fixed length the compiler vectorizes; columns past n are computed
     * and not used. */
    if (ro == 1) /* a rate model of order 1: A's columns past IOM + 1 are not read */
        plant_rows_of_FP(P, Phi, S, IOM + 1, A);
    else
        plant_rows_of_FP(P, Phi, S, NMAX, A);
    for (int a = 0; a < r; a++) {
        double acc[NMAX] = {0.0};
        for (int c = 0; c < ro && a < ro; c++)
            for (int k = 0; k < NMAX; k++) acc[k] += Fr[a][c] * P[IOM + c][k];
        memcpy(Ar[a], acc, sizeof acc);
    }
    /* B = A F' where a plant or rate row meets a plant or rate column (both halves of each
     * symmetric pair: they differ in their last bits), the process noise on its diagonal */
    double Bpp[4][4], Brp[GYRO_OBS_RMAX][4], Bpr[4][GYRO_OBS_RMAX];
    double Brr[GYRO_OBS_RMAX][GYRO_OBS_RMAX];
    for (int i = 0; i < 4; i++)
        times_plant_rows(A[i], FpT, Bpp[i]);
    for (int a = 0; a < r; a++)
        if (a < ro) times_plant_rows(Ar[a], FpT, Brp[a]);
        else memset(Brp[a], 0, sizeof Brp[a]);
    for (int j = 0; j < 4; j++)
        for (int a = 0; a < r; a++) {
            double acc = 0.0;
            for (int c = 0; c < ro && a < ro; c++) acc += A[j][IOM + c] * Fr[a][c];
            Bpr[j][a] = acc;
        }
    for (int a = 0; a < r; a++)
        for (int b = 0; b < r; b++) {
            double acc = 0.0;
            for (int c = 0; c < ro && a < ro && b < ro; c++) acc += Ar[a][IOM + c] * Fr[b][c];
            Brr[a][b] = acc + Qr[a][b];
        }
    const double q[4] = {q0, q0, q1, q1};
    for (int i = 0; i < 4; i++) { /* plant x plant */
        P[i][i] = Bpp[i][i] + q[i];
        for (int j = 0; j < i; j++) {
            const double v = 0.5 * (Bpp[j][i] + Bpp[i][j]);
            P[i][j] = v;
            P[j][i] = v;
        }
    }
    for (int i = IPAR; i < IOM; i++) { /* parameter x plant: A's; the parameters' own: P's */
        for (int j = 0; j < 4; j++) {
            P[i][j] = A[j][i];
            P[j][i] = A[j][i];
        }
        P[i][i] += o->qpar;
    }
    for (int a = 0; a < r; a++) { /* rate x (plant, parameters, rate) */
        const int i = IOM + a;
        for (int j = 0; j < 4; j++) {
            const double v = 0.5 * (Brp[a][j] + Bpr[j][a]);
            P[i][j] = v;
            P[j][i] = v;
        }
        for (int k = IPAR; k < IOM; k++) {
            P[i][k] = Ar[a][k];
            P[k][i] = Ar[a][k];
        }
        for (int b = 0; b < a; b++) {
            const double v = 0.5 * (Brr[b][a] + Brr[a][b]);
            P[i][IOM + b] = v;
            P[IOM + b][i] = v;
        }
        P[i][i] = Brr[a][a];
    }
}

/* IMM prediction to t + h: mix, propagate every filter about the combined estimate (one
 * held step, eq. 5), then x, P = their mixture with the predicted probabilities c. */
void obs_imm_predict(GyroObserver *o, double ux, double uy, double h) {
    double s1[4], Phi[4][4], S[4][8], xbar[NMAX];
    obs_linearize(o, o->x, ux, uy, h, s1, Phi, S);
    obs_refit_predict(o, (const double(*)[4])Phi, (const double(*)[8])S);
    mix(o, 1);
    const double a0 = STATE_NOISE * o->peak[0] / o->hgain[0];
    const double a1 = STATE_NOISE * o->peak[1] / o->hgain[1];
    memcpy(xbar, o->x, sizeof xbar); /* the linearization point is replaced only below */
    double FpT[12][4]; /* the plant rows of F, [Phi S], transposed: shared by the models */
    for (int j = 0; j < 4; j++) {
        for (int c = 0; c < 4; c++) FpT[c][j] = Phi[j][c];
        for (int c = 0; c < 8; c++) FpT[4 + c][j] = S[j][c];
    }
    for (int j = 0; j < o->n_models; j++)
        predict_about(o, xbar, s1, Phi, S, (const double(*)[4])FpT, o->xs[j], o->Ps[j],
                      (const double(*)[GYRO_OBS_RMAX])o->Fr[j],
                      (const double(*)[GYRO_OBS_RMAX])o->Qr[j], model_rows(o, j) - IOM, a0 * a0,
                      a1 * a1);
    /* the combined P: only what the next correction and the outputs read (the whole of it
     * is made where it is read: gyro_observer_complete_covariance) */
    if (o->n_models > 1) {
        combine_partial(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps,
                        o->c, o->x, o->P);
        o->P_partial = 1;
    } else {
        combine(o, (const double(*)[NMAX])o->xs, (const double(*)[NMAX][NMAX])o->Ps, o->c,
                o->x, o->P);
    }
}
