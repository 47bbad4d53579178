/* The observer of US 2011/0314910 A1 (eqs. 5-9): see gyro_observer.h for the contract.
 * This file: its construction (tuning checks, scaling, prior), the step and its halves
 * (filterpy's update() and predict()), outputs, and restored states; each idea of the
 * step lives in its own file (gyro_observer_internal.h lists them).
 *
 * The operation order is that of gyro_fmu 0.3.0's compiled kernels (tests/oracle_observer/),
 * so IEEE arithmetic gives the same bits; compiled with -ffp-contract=off. */
#include "gyro_observer_internal.h"

const double gyro_observer_prior_fraction = PRIOR_FRACTION;

double gyro_observer_factorial(int k) { return k >= 0 && k < 48 ? FACTORIAL[k] : -1.0; }

size_t gyro_observer_size(void) { return sizeof(GyroObserver); }

int gyro_observer_rough_grades(double *grades, int n) {
    const int m = GYRO_OBS_MMAX - 4;
    for (int i = 0; i < m && i < n; i++) grades[i] = ROUGH_GRADES[i];
    return m;
}

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
    if (tun->rate_model < 0 || tun->rate_model > 4) {
        snprintf(msg, n, "rate_model=%d: use 0 (adaptive), 1 (constant), 2 (tracking at "
                 "rate_bandwidth), 3 (expert: q_Omega, omega_order) or 4 (adaptive with a "
                 "moving bank)", (int)tun->rate_model);
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
    obs_held_reset(o);
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
    o->n_models = tun->rate_model == 0 ? GYRO_OBS_MMAX : tun->rate_model == 4 ? BANK_MODELS : 1;
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
    o->nu2_zero[0] = o->nu2_zero[1] = o->nu2_mass = 0.0;
    o->refit.last_T = -1.0;
    for (int k = 0; k < 2; k++)
        o->wander.log_q[k] = log(WANDER_MIN), o->wander.r[k] = o->wander.mu_min[k] = 1.0;
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
 * (drive) or PRIOR_FRACTION_MEASURED of the measured displacement. A measurement whose
 * noise was not told may be that noise (any nonzero value starts it): the drive's prior
 * is then still added at the first drive (auto_prior 2). Started by the first sample's
 * noise alone (1e-12 m where the drive's is 6e-12 m), the state was known so well that
 * the first milliseconds' linearization error stayed: issue 44, a 12 kHz gyro started at
 * its true parameters ended 7.5 sigma off with status 0; the drive's prior: 0.6 sigma. */
static void start_prior(GyroObserver *o, double ux, double uy, double z1, double z2) {
    double size = prior_size(o, ux, uy, z1, z2);
    if (!(size > 0.0)) return;
    const int driven = ux != 0.0 || uy != 0.0;
    for (int j = 0; j < 2; j++) o->peak[j] = dmax(o->peak[j], size * o->hgain[j]);
    size *= driven ? PRIOR_FRACTION : PRIOR_FRACTION_MEASURED;
    for (int i = 0; i < 4; i++) {
        o->P[i][i] += size * size;
        for (int j = 0; j < o->n_models; j++) o->Ps[j][i][i] += size * size;
    }
    o->auto_prior = !driven && o->auto_prior == 1 && !o->lim.absolute ? 2 : 0;
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
    obs_lose(o, h);
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
        if (o->auto_prior == 1) start_prior(o, 0.0, 0.0, z1, z2);
        if (o->auto_prior) {
            const double size = prior_size(o, ux, uy, 0.0, 0.0);
            if (size > 0.0) {
                const double q = PRIOR_FRACTION * size;
                pv = q * q, pk0 = size * o->hgain[0], pk1 = size * o->hgain[1];
                o->auto_prior = 0;
            }
        }
    }
    obs_imm_update(o, z1, z2, h, 0);
    if (pv > 0.0) {
        o->peak[0] = dmax(o->peak[0], pk0);
        o->peak[1] = dmax(o->peak[1], pk1);
        for (int i = 0; i < 4; i++) /* every filter; P is their mixture after the predict */
            for (int j = 0; j < o->n_models; j++) o->Ps[j][i][i] += pv;
    }
    obs_imm_predict(o, ux, uy, h);
    const int code = obs_monitor_check(o);
    o->t += h;
    return verdict(o, code, h, msg, n);
}

int gyro_observer_update(GyroObserver *o, double z1, double z2, double h, char *msg, size_t n) {
    static const char *const names[2] = {"z1", "z2"};
    const double values[2] = {z1, z2};
    const int refused = refusal(o, h, names, values, 2, 0, msg, n);
    if (refused) return refused;
    if (o->auto_prior == 1) start_prior(o, 0.0, 0.0, z1, z2);
    obs_imm_update(o, z1, z2, h, 1);
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
    obs_imm_predict(o, ux, uy, h);
    o->t += h;
    return verdict(o, obs_monitor_check(o), h, msg, n);
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
    case 4:
        memcpy(p, o->c, 4 * sizeof(double));
        for (int j = 4; j < o->n_models; j++) p[1] += o->c[j]; /* graded rough models */
        break;
    case 1: p[0] = 1.0; break;
    case 2: p[3] = 1.0; break;
    default: break;
    }
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
    if (!(all_finite(o->nu2_zero, 2) && o->nu2_zero[0] >= 0.0 && o->nu2_zero[1] >= 0.0 &&
          o->nu2_mass >= 0.0 && o->nu2_mass <= 1.0))
        return "innovation powers (the covariance's) that no run can have";
    for (int i = 0; i < n; i++)
        if (!(isfinite(o->x[i]) && all_finite(o->P[i], (size_t)n)))
            return "a combined estimate or covariance that is not finite";
    for (int j = 0; j < M; j++) {
        if (!all_finite(o->xs[j], (size_t)n)) return "a rate model's estimate that is not finite";
        for (int i = 0; i < n; i++) {
            if (!all_finite(o->Ps[j][i], (size_t)n))
                return "a rate model's covariance that is not finite";
            for (int k = 0; k < i; k++) /* every step keeps it so to the bit */
                if (o->Ps[j][i][k] != o->Ps[j][k][i])
                    return "a rate model's covariance that is not symmetric";
        }
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
        (o->P_partial != 0 && o->P_partial != 1))
        return "an unknown status";
    if (o->auto_prior < 0 || o->auto_prior > 2) return "an auto prior state not 0, 1 or 2";
    if (!(o->rate_scale >= log(BANK_MIN) && o->rate_scale <= log(BANK_MAX)))
        return "a moving bank's scale outside its range";
    const GyroWander *w = &o->wander;
    if (!all_finite(w->log_q, sizeof *w / sizeof(double)))
        return "a constant model's wander test not finite";
    for (int k = 0; k < 2; k++)
        if (!(w->log_q[k] >= log(WANDER_MIN) && w->log_q[k] <= log(WANDER_MAX) &&
              w->time[k] >= 0.0 && w->r[k] > 0.0 && w->mu_min[k] >= 0.0 &&
              w->mu_min[k] <= 1.0))
            return "a constant model's wander test out of its range";
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
    if (!bad) bad = obs_held_restored(o);
    if (bad) {
        snprintf(msg, n, "the saved observer holds %s: restore a state this FMU saved", bad);
        return 1;
    }
    o->h_cached = -1.0; /* the rate models (Fr, Qr, Pi, qpar) are rebuilt at the next step */
    return 0;
}

int gyro_observer_state_restored(GyroObserver *o, char *msg, size_t n) {
    const char *bad = restored_state_problem(o);
    if (!bad) bad = obs_held_restored(o);
    if (n) msg[0] = '\0';
    if (!bad) return 0;
    snprintf(msg, n, "the saved observer holds %s: restore a state this observer saved", bad);
    obs_held_reset(o);
    return 1;
}
