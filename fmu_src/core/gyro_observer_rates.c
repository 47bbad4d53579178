/* The observer's rate models: each an order-th random walk of Omega_z of an intensity set
 * by rate_span and rate_bandwidth; their transitions and process noise over a step and the
 * switching probabilities between them (docs/observer-rate-model.md). */
#include "gyro_observer_internal.h"

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

/* rate_model 4's intensities at its scale c = exp(rate_scale): [constant, rough c, slow
 * min(c, 1), agile, rough c / BANK_RATIO, rough c BANK_RATIO]. */
static void bank_models(const GyroObserver *o, int orders[BANK_MODELS],
                        double qs[BANK_MODELS]) {
    const GyroObserverTuning *tun = &o->tuning;
    const double slow = tun->rate_bandwidth / SLOW_FRACTION, c = exp(o->rate_scale);
    const double rough = intensity(1, tun->rate_span, slow) * c;
    orders[0] = 1, qs[0] = 0.0;
    orders[1] = 1, qs[1] = rough;
    orders[2] = 2, qs[2] = intensity(2, tun->rate_span, slow) * (c < 1.0 ? c : 1.0);
    orders[3] = 3, qs[3] = intensity(3, tun->rate_span, tun->rate_bandwidth);
    orders[4] = 1, qs[4] = rough / BANK_RATIO;
    orders[5] = 1, qs[5] = rough * BANK_RATIO;
}

/* After a correction's probabilities: log c moves by the slope of the probabilities across
 * the rough models (BANK_* in gyro_observer_internal.h), and the moving models' process
 * noise over the step follows it. */
void obs_bank_move(GyroObserver *o) {
    const double *mu = o->mu, h = o->h_cached;
    const double W = mu[1] + mu[2] + mu[4] + mu[5];
    const double g = (mu[5] - mu[4]) / W;
    if (!(W > 0.0 && isfinite(g) && h > 0.0)) return;
    const double lo = log(BANK_MIN), hi = log(BANK_MAX);
    const double s = o->rate_scale + h / BANK_TAU * g * log(BANK_RATIO);
    o->rate_scale = s < lo ? lo : s > hi ? hi : s;
    int orders[BANK_MODELS];
    double qs[BANK_MODELS];
    bank_models(o, orders, qs);
    static const int moving[4] = {1, 2, 4, 5};
    for (int k = 0; k < 4; k++) {
        const int j = moving[k];
        rate_process(orders[j], qs[j], h, o->Fr[j], o->Qr[j]);
    }
}

/* rate_model 0's constant model: the intensity of its random walk, the sum of the two
 * scales' (each 0 at its floor). */
static double wander_q(const GyroObserver *o) {
    double c = 0.0;
    for (int k = 0; k < 2; k++)
        if (o->wander.log_q[k] > log(WANDER_MIN)) c += exp(o->wander.log_q[k]);
    return c * intensity(1, o->tuning.rate_span, o->tuning.rate_bandwidth / SLOW_FRACTION);
}

/* After a correction (x0, p0: the constant model's Omega_z and its variance before it):
 * each scale's block sums take it; a full block moves its log q (GyroWander), and the
 * model's process noise over the step follows. */
void obs_wander_step(GyroObserver *o, double x0, double p0, double h) {
    GyroWander *w = &o->wander;
    const double c = o->xs[0][IOM] - x0, v = p0 - o->Ps[0][IOM][IOM];
    const double lo = log(WANDER_MIN), hi = log(WANDER_MAX);
    int moved = 0;
    for (int k = 0; k < 2; k++) {
        w->C[k] += c;
        w->V[k] += v;
        w->time[k] += h;
        if (o->mu[0] < w->mu_min[k]) w->mu_min[k] = o->mu[0];
        if (w->time[k] < WANDER_BLOCK[k] * (1.0 - 1e-9)) continue;
        if (w->V[k] > 0.0 && isfinite(w->C[k])) {
            const double r = w->C[k] * w->C[k] / w->V[k];
            w->r[k] += WANDER_AVG * (r - w->r[k]);
            double d = WANDER_GAIN[k] *
                       ((r < WANDER_RMAX ? r : WANDER_RMAX) - 1.0 - WANDER_BIAS[k]);
            if (w->mu_min[k] < WANDER_MU && d > 0.0) d = 0.0; /* a jump: the rough models' */
            const double s = w->log_q[k] + d;
            w->log_q[k] = s < lo ? lo : s > hi ? hi : s;
            moved = 1;
        }
        w->C[k] = w->V[k] = w->time[k] = 0.0;
        w->mu_min[k] = 1.0;
    }
    if (moved) rate_process(1, wander_q(o), h, o->Fr[0], o->Qr[0]);
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
        orders[0] = 1, qs[0] = wander_q(o);
        orders[1] = 1, qs[1] = intensity(1, span, slow);
        orders[2] = 2, qs[2] = intensity(2, span, slow);
        orders[3] = 3, qs[3] = intensity(3, span, f);
        M = GYRO_OBS_MMAX;
        for (int j = 4; j < M; j++) orders[j] = 1, qs[j] = ROUGH_GRADES[j - 4] * qs[1];
        break;
    }
    case 4: bank_models(o, orders, qs), M = BANK_MODELS; break;
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
