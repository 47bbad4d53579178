/* The observer's re-fit test: would a re-fit of the last ~REFIT_TAU of data move the
 * estimate? Its score and covariance at each correction, its sensitivities at each
 * prediction, its verdict per block and the restart along the re-fit's move
 * (docs/observer-soundness.md). */
#include "gyro_observer_internal.h"

/* Re-fit test, at a correction: the score and its covariance take this correction (nu of
 * the combined prediction, S = H P H' + R), then W <- (I - K H) W. */
void obs_refit_correct(GyroObserver *o, const double nu[2], const double R[2], double h) {
    const int i0 = o->i0, i1 = i0 + 2;
    const double g0 = o->hgain[0], g1 = o->hgain[1];
    double S[4];
    if (!obs_innovation_covariance(o, R, S)) return;
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
void obs_refit_predict(GyroObserver *o, const double Phi[4][4], const double S[4][8]) {
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
void obs_refit_restart(GyroObserver *o) {
    GyroRefit *r = &o->refit;
    gyro_observer_complete_covariance(o); /* P as a whole, before the move is added */
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
double obs_refit_judge(GyroObserver *o, double h) {
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
