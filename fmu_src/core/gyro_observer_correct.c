/* The observer's correction (US 2011/0314910 A1 eq. 8): the noise variances of the
 * measured pair (given or estimated from the innovations), the Kalman gain and update of
 * one filter, the innovations' statistics the monitor judges. */
#include "gyro_observer_internal.h"

/* Relative-mode noise variance: (noise_rel peak)^2, floored by the innovations' running
 * mean square: an EWMA of time constant INNOV_TAU_START at first, whose memory then
 * grows as a plain mean's (t) until innov_tau. (An EWMA of a slow innov_tau started at
 * the first square stayed near that one sample: at 50 ms it lost a good gyro at 85 us.
 * A plain mean from the start slowed far noise-free starts: 30 % off, 20 ms, -3 rad/s.)
 * That variance sets the gain. The covariance takes in the noise as *Rc, the larger of
 * it and the same EWMA started from 0 and divided by the weight it has taken in (a plain
 * mean of the first squares, not the first square alone: issue 44, the over-confidence
 * of the first milliseconds that P kept). */
static double rel_R(GyroObserver *o, int j, double nu, double w, double *Rc) {
    const GyroObserverTuning *tun = &o->tuning;
    const double v2 = nu * nu;
    double e = o->nu2[j];
    e = e < 0.0 ? v2 : e + w * (v2 - e);
    o->nu2[j] = e;
    o->nu2_zero[j] += w * (v2 - o->nu2_zero[j]);
    const double floor_ = tun->noise_rel * o->peak[j];
    const double R = dmax(floor_ * floor_, tun->innov_floor * e);
    const double mass = o->nu2_mass + w * (1.0 - o->nu2_mass);
    *Rc = dmax(R, tun->innov_floor * o->nu2_zero[j] / mass);
    return R;
}

/* Noise variances of the measured pair at t, R (the gain's) and Rc (the covariance's),
 * and the innovations nu of the combined prediction; updates the running peaks and the
 * innovation EWMAs (time base: h). */
void obs_noise_variances(GyroObserver *o, double z1, double z2, double h, double R[2],
                         double Rc[2], double nu[2]) {
    const GyroObserverTuning *tun = &o->tuning;
    const int i0 = o->i0;
    nu[0] = z1 - o->hgain[0] * o->x[i0];
    nu[1] = z2 - o->hgain[1] * o->x[i0 + 2];
    if (fabs(z1) > o->peak[0]) o->peak[0] = fabs(z1);
    if (fabs(z2) > o->peak[1]) o->peak[1] = fabs(z2);
    const double w = dmax(dmin(h / tun->innov_tau, 1.0),
                          dmin(h / (o->t + h), h / INNOV_TAU_START));
    const double sigma[2] = {tun->sigma_z1, tun->sigma_z2};
    for (int j = 0; j < 2; j++) {
        if (sigma[j] > 0.0) R[j] = Rc[j] = sigma[j] * sigma[j];
        else R[j] = rel_R(o, j, nu[j], w, &Rc[j]);
    }
    if (!(sigma[0] > 0.0 && sigma[1] > 0.0)) o->nu2_mass += w * (1.0 - o->nu2_mass);
}

/* 1 when x and P's diagonal from `rows` on (to n) are zero, so that (P a covariance) the
 * rows and columns there are zero: the correction leaves them zero (their gain is zero)
 * and need not compute them. The prediction makes them so (model_rows); a restored P
 * with a zero variance and a nonzero covariance is no covariance (the monitor's Cholesky
 * check loses it). */
static int zero_beyond(int rows, int n, const double *x, const double P[NMAX][NMAX]) {
    for (int i = rows; i < n; i++)
        if (x[i] != 0.0 || P[i][i] != 0.0) return 0;
    return 1;
}

/* (I - K H) P (I - K H)' + K Rc K' in place, O(n^2) (H picks i0, i1 with gains g0, g1),
 * symmetric to the last bit, for P's first n rows over its first `cols` columns (the rest
 * zeros, kept zeros). Called with a constant cols, so that each row's loop has a fixed
 * length the compiler unrolls and vectorizes; every element's expression as before. */
FIXED_LENGTH void joseph(double P[NMAX][NMAX], int n, const int cols, int i0, int i1,
                         double g0, double g1, const double K0[NMAX], const double K1[NMAX],
                         const double Rc[2]) {
    double P0[NMAX], P1[NMAX]; /* the measured rows before the update: every row reads them */
    memcpy(P0, P[i0], sizeof P0);
    memcpy(P1, P[i1], sizeof P1);
    for (int i = 0; i < n; i++) { /* M = (I - K H) P a row at a time, then that row of P */
        const double k0 = K0[i] * g0, k1 = K1[i] * g1;
        double M[NMAX];
        for (int j = 0; j < cols; j++) M[j] = P[i][j] - (k0 * P0[j] + k1 * P1[j]);
        const double m0 = M[i0] * g0, m1 = M[i1] * g1;
        const double kr0 = K0[i] * Rc[0], kr1 = K1[i] * Rc[1];
        for (int j = 0; j < cols; j++)
            P[i][j] = (M[j] - (m0 * K0[j] + m1 * K1[j])) + (kr0 * K0[j] + kr1 * K1[j]);
    }
    for (int i = 0; i < n; i++) /* symmetric to the last bit */
        for (int j = 0; j < i; j++) {
            const double v = 0.5 * (P[i][j] + P[j][i]);
            P[i][j] = v;
            P[j][i] = v;
        }
}

/* Measurement update (eq. 8) of one filter's x, P in place: x += K (z - H x), K from R,
 * P by Joseph with Rc, (I - K H) P (I - K H)' + K Rc K' (symmetrized: the covariance of
 * that gain's error when the noise is Rc), or P - K H P (the optimal gain's, Rc unused).
 * Rows past `rows` (model_rows) are skipped when they are zero: the same numbers (a zero's
 * sign aside). Returns the NIS of its innovation (2 dof; < 0: S singular, no update) and
 * *logdet = log det S. */
double obs_correct_with(const GyroObserver *o, double *x, double P[NMAX][NMAX], int rows,
                        double z1, double z2, const double R[2], const double Rc[2],
                        double *logdet) {
    const int i0 = o->i0, i1 = i0 + 2;
    const double g0 = o->hgain[0], g1 = o->hgain[1];
    const double nu0 = z1 - g0 * x[i0], nu1 = z2 - g1 * x[i1];
    const double a = P[i0][i0] * g0 * g0 + R[0];
    const double b_ = P[i0][i1] * g0 * g1;
    const double c = P[i1][i0] * g0 * g1;
    const double d = P[i1][i1] * g1 * g1 + R[1];
    const double det = a * d - b_ * c;
    *logdet = 0.0;
    if (!(det > 0.0 && a > 0.0)) return -1.0;
    const int n = rows < o->n && zero_beyond(rows, o->n, x, (const double(*)[NMAX])P) ? rows
                                                                                    : o->n;
    const double s00 = d / det, s01 = -b_ / det, s10 = -c / det, s11 = a / det;
    /* the gain's two columns K0, K1 and P H' as separate rows: the loops over j below run
     * over contiguous memory (vectorized) with every expression as it was */
    double PHt0[NMAX] = {0.0}, PHt1[NMAX] = {0.0}, K0[NMAX] = {0.0}, K1[NMAX] = {0.0};
    for (int i = 0; i < n; i++) { /* P[i][i0] is P[i0][i]: a row, P symmetric to the bit */
        PHt0[i] = P[i0][i] * g0;
        PHt1[i] = P[i1][i] * g1;
    }
    for (int i = 0; i < n; i++) {
        K0[i] = PHt0[i] * s00 + PHt1[i] * s10;
        K1[i] = PHt0[i] * s01 + PHt1[i] * s11;
        x[i] = x[i] + (K0[i] * nu0 + K1[i] * nu1);
    }
    if (o->tuning.joseph) {
        if (n <= IOM + 1) /* a rate model of order 1: its columns past IOM + 1 are zeros */
            joseph(P, n, IOM + 1, i0, i1, g0, g1, K0, K1, Rc);
        else
            joseph(P, n, NMAX, i0, i1, g0, g1, K0, K1, Rc);
    } else {
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) P[i][j] -= K0[i] * PHt0[j] + K1[i] * PHt1[j];
    }
    *logdet = log(det);
    return nu0 * (s00 * nu0 + s01 * nu1) + nu1 * (s10 * nu0 + s11 * nu1);
}

/* S = H P H' + R of the combined prediction as [a, b, d, det] (S = [[a, b], [b, d]]);
 * 0 when it is not positive definite. */
int obs_innovation_covariance(const GyroObserver *o, const double R[2], double S[4]) {
    const int i0 = o->i0, i1 = i0 + 2;
    const double g0 = o->hgain[0], g1 = o->hgain[1];
    S[0] = o->P[i0][i0] * g0 * g0 + R[0];
    S[1] = o->P[i0][i1] * g0 * g1;
    S[2] = o->P[i1][i1] * g1 * g1 + R[1];
    S[3] = S[0] * S[2] - S[1] * S[1];
    return S[3] > 0.0 && S[0] > 0.0;
}

/* Add one correction's innovations (of the combined prediction) to the monitor's block. */
void obs_monitor_innovations(GyroObserver *o, const double nu[2], const double R[2]) {
    double S[4];
    if (!obs_innovation_covariance(o, R, S)) return;
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
