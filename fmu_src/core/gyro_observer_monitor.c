/* The observer's divergence monitor and the words of its verdicts: positive definiteness,
 * bounds, innovation statistics per block (NIS, relative size, whiteness), the re-fit
 * test's verdict; a lost filter's cause and the warnings' messages. */
#include "gyro_observer_internal.h"

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
int obs_monitor_check(GyroObserver *o) {
    const GyroMonitorLimits *lim = &o->lim;
    GyroMonitor *m = &o->mon;
    const double *x = o->x;
    const int n = o->n;
    for (int i = 0; i < n; i++)
        if (!(isfinite(x[i]) && isfinite(o->P[i][i])))
            return lost_verdict(m, GYRO_MON_NONFINITE, i, x[i]);
    /* Positive definiteness at the rate it needs: the diagonal, which the sigmas are, at
     * every step; the whole Cholesky factor (3-4k instructions, a fifth of a constant-model
     * step) when a block of corrections is judged (every BLOCK steps) and at a step with no
     * correction since the last block. Joseph's form and the mixtures keep P positive
     * definite but for rounding, which would take many steps to break it; a P broken
     * otherwise (a restored state) is lost within one block (test_observer_soundness). */
    for (int i = 0; i < n; i++)
        if (!(o->P[i][i] >= 0.0)) return lost_verdict(m, GYRO_MON_NOT_SPD, -1, 0.0);
    if (m->count >= lim->block || m->count == 0.0) {
        gyro_observer_complete_covariance(o);
        if (!gyro_observer_cholesky_ok(&o->P[0][0], n))
            return lost_verdict(m, GYRO_MON_NOT_SPD, -1, 0.0);
    }
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
        const double T = obs_refit_judge(o, o->h_cached);
        if (T >= 0.0) o->refit.pending = T > REFIT_WARN;
        if (T > REFIT_WARN) obs_refit_restart(o);
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
void obs_lose(GyroObserver *o, double h) {
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
             "far, noise larger than told, or a rate jump faster than its rate models)",
             o->t, what);
    return 1;
}
