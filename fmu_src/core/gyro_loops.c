#include "gyro_loops.h"

#include "gyro_text.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define TWO_PI (2.0 * GYRO_PI)

/* The Real settings by name, for the finiteness and sign checks. */
#define REAL(name) {#name, offsetof(GyroLoopSettings, name)}
static const struct {
    const char *name;
    size_t offset;
} REALS[] = {
    REAL(f_nominal), REAL(amplitude), REAL(q_nominal), REAL(plant_gain), REAL(pll_bandwidth),
    REAL(agc_bandwidth), REAL(rebalance_bandwidth), REAL(demod_cutoff), REAL(rebalance_cutoff),
    REAL(drive_limit), REAL(osc_phase), REAL(sideband_index), REAL(sideband_spacing),
    REAL(sideband_start), REAL(ff_xx), REAL(ff_xy), REAL(ff_yx), REAL(ff_yy),
    REAL(excitation_amplitude), REAL(excitation_offset_x), REAL(excitation_offset_y)};
#define N_REALS (sizeof REALS / sizeof REALS[0])
/* REALS[0..N_POSITIVE-1] but osc_phase, sideband_index must be > 0. */
static const char *const POSITIVE[] = {"f_nominal", "amplitude", "q_nominal", "plant_gain",
                                       "pll_bandwidth", "agc_bandwidth", "rebalance_bandwidth",
                                       "demod_cutoff", "rebalance_cutoff", "drive_limit",
                                       "sideband_spacing"};

static double real_of(const GyroLoopSettings *s, size_t i) {
    return *(const double *)((const char *)s + REALS[i].offset);
}

static double real_named(const GyroLoopSettings *s, const char *name) {
    for (size_t i = 0; i < N_REALS; i++)
        if (!strcmp(REALS[i].name, name)) return real_of(s, i);
    return NAN;
}

int gyro_loop_settings_problems(const GyroLoopSettings *s, char *msg, size_t n) {
    char text[256], v[GYRO_REAL_TEXT];
    if (n) msg[0] = '\0';
    for (size_t i = 0; i < N_REALS; i++)
        if (!isfinite(real_of(s, i))) {
            snprintf(text, sizeof text, "%s=%s is not finite: give a finite number",
                     REALS[i].name, gyro_real_text(real_of(s, i), v));
            gyro_text_add(msg, n, text);
        }
    if (msg[0]) return 1;
    if (s->mode < 0 || s->mode > 2) {
        snprintf(text, sizeof text, "mode=%d must be 0 (off), 1 (x oscillator) or 2 (y)",
                 (int)s->mode);
        gyro_text_add(msg, n, text);
    }
    for (size_t i = 0; i < sizeof POSITIVE / sizeof POSITIVE[0]; i++) {
        const double x = real_named(s, POSITIVE[i]);
        if (!(x > 0.0)) {
            snprintf(text, sizeof text, "%s=%s must be > 0", POSITIVE[i], gyro_real_text(x, v));
            gyro_text_add(msg, n, text);
        }
    }
    if (s->sideband_index < 0.0 || s->sideband_count < 0 || s->sideband_first < 0)
        gyro_text_add(msg, n, "sideband_index, sideband_count and sideband_first must be >= 0");
    if (s->sideband_count > GYRO_SIDEBAND_COUNT_MAX) {
        snprintf(text, sizeof text, "sideband_count=%d is above its maximum %d (each step sums "
                 "every tone): use <= %d", (int)s->sideband_count, GYRO_SIDEBAND_COUNT_MAX,
                 GYRO_SIDEBAND_COUNT_MAX);
        gyro_text_add(msg, n, text);
    }
    if (s->sideband_first > GYRO_SIDEBAND_FIRST_MAX) {
        snprintf(text, sizeof text, "sideband_first=%d is above its maximum %d: use <= %d",
                 (int)s->sideband_first, GYRO_SIDEBAND_FIRST_MAX, GYRO_SIDEBAND_FIRST_MAX);
        gyro_text_add(msg, n, text);
    }
    return msg[0] ? 1 : 0;
}

int gyro_loops_init(GyroLoops *l, const GyroLoopSettings *s, char *msg, size_t n) {
    if (gyro_loop_settings_problems(s, msg, n)) return 1;
    memset(l, 0, sizeof *l);
    l->settings = *s;
    GyroLoopGains *g = &l->gains;
    const double w = TWO_PI, c = s->plant_gain;
    const double zeta = 0.7, wn = w * s->agc_bandwidth;
    const double tau = s->q_nominal / (GYRO_PI * s->f_nominal); /* amplitude time constant */
    const double wb = w * s->pll_bandwidth;
    g->w_nominal = w * s->f_nominal;
    g->pll_kp = wb;
    g->pll_ki = wb * wb / 4;
    g->agc_kp = 2 * zeta * wn / c;
    g->agc_ki = wn * wn / c;
    g->agc_feedforward = s->amplitude / (c * tau);
    g->rebalance_gain = w * s->rebalance_bandwidth / c;
    g->rebalance_wi = w * s->rebalance_bandwidth / 5;
    l->state.omega = g->w_nominal;
    l->out.theta = l->state.theta, l->out.omega = l->state.omega;
    return 0;
}

/* angle in [0, 2 pi): keeps the NCO phase exact over long records */
static double wrap(double angle) { return angle - TWO_PI * floor(angle / TWO_PI); }

/* Cascade of low-pass sections z += alpha (in - z); returns the last in re, im. */
static void lowpass(double (*z)[2], int sections, double alpha, double *re, double *im) {
    for (int k = 0; k < sections; k++) {
        z[k][0] += alpha * (*re - z[k][0]);
        z[k][1] += alpha * (*im - z[k][1]);
        *re = z[k][0], *im = z[k][1];
    }
}

void gyro_loops_step(GyroLoops *l, double px, double py, double t, double h) {
    const GyroLoopSettings *p = &l->settings;
    const GyroLoopGains *g = &l->gains;
    GyroLoopState *st = &l->state;
    GyroLoopOutputs *out = &l->out;
    const double w_nom = g->w_nominal;
    /* feed-forward removal: the pick-off at t holds E V of the hold that ended at t */
    const double pcx = px - (p->ff_xx * st->v_previous[0] + p->ff_xy * st->v_previous[1]);
    const double pcy = py - (p->ff_yx * st->v_previous[0] + p->ff_yy * st->v_previous[1]);
    const double t_next = t + h;
    double vx, vy, gain, rate, quad, amp, perr;
    if (p->mode == 0) {
        const double f0 = w_nom / TWO_PI, a = p->excitation_amplitude;
        vx = a * (cos(TWO_PI * (f0 - p->excitation_offset_x) * t_next) +
                  cos(TWO_PI * (f0 + p->excitation_offset_x) * t_next));
        vy = a * (cos(TWO_PI * (f0 - p->excitation_offset_y) * t_next) +
                  cos(TWO_PI * (f0 + p->excitation_offset_y) * t_next));
        st->theta = wrap(st->theta + w_nom * h);
        st->omega = w_nom;
        gain = rate = quad = amp = perr = 0.0;
    } else {
        const double p1 = p->mode == 1 ? pcx : pcy, p2 = p->mode == 1 ? pcy : pcx;
        const double th = st->theta, c = cos(th), s = sin(th);
        const double alpha1 = 1.0 - exp(-TWO_PI * p->demod_cutoff * h);
        double a_re = 2.0 * p1 * c, a_im = -2.0 * p1 * s;
        lowpass(st->agc_lowpass, 3, alpha1, &a_re, &a_im);
        amp = hypot(a_re, a_im);
        perr = atan2(a_im, a_re);
        /* PLL: PI on the phase error drives the NCO frequency */
        st->pll_integral += g->pll_ki * perr * h;
        const double omega = w_nom + g->pll_kp * perr + st->pll_integral;
        /* amplitude control on the sideband-modulated position signal */
        double m = 0.0;
        if (p->sideband_index > 0.0 && t >= p->sideband_start) {
            const int count = p->sideband_count;
            for (int j = 0; j < count; j++) {
                const double k = (double)p->sideband_first + j;
                const double psi = -GYRO_PI * (j + 1) * j / count;
                m += p->sideband_index * sin(TWO_PI * k * p->sideband_spacing * t + psi);
            }
        }
        const double e = p->amplitude - amp * (1.0 + m);
        gain = g->agc_feedforward + g->agc_kp * e + st->agc_integral;
        if (0.0 < gain && gain < p->drive_limit) st->agc_integral += g->agc_ki * e * h;
        gain = fmin(fmax(gain, 0.0), p->drive_limit);
        /* force rebalance (eq. 7): u = -i K (b + w_i int b) */
        const double alpha2 = 1.0 - exp(-TWO_PI * p->rebalance_cutoff * h);
        double b_re = 2.0 * p2 * c, b_im = -2.0 * p2 * s;
        lowpass(st->rebalance_lowpass, 2, alpha2, &b_re, &b_im);
        st->rebalance_integral[0] += b_re * h;
        st->rebalance_integral[1] += b_im * h;
        const double v_re = b_re + g->rebalance_wi * st->rebalance_integral[0];
        const double v_im = b_im + g->rebalance_wi * st->rebalance_integral[1];
        const double u_re = g->rebalance_gain * v_im, u_im = -g->rebalance_gain * v_re;
        /* NCO advance; outputs at the middle of the next hold */
        const double th_next = wrap(th + omega * h);
        st->theta = th_next, st->omega = omega;
        const double psi_mid = th_next + 0.5 * omega * h;
        const double v1 = -gain * sin(psi_mid + p->osc_phase);
        const double v2 = u_re * cos(psi_mid) - u_im * sin(psi_mid);
        vx = p->mode == 1 ? v1 : v2;
        vy = p->mode == 1 ? v2 : v1;
        rate = p->mode == 1 ? u_im : -u_im;
        quad = u_re;
    }
    st->v_previous[0] = st->v_held[0], st->v_previous[1] = st->v_held[1];
    st->v_held[0] = vx, st->v_held[1] = vy;
    *out = (GyroLoopOutputs){vx, vy, st->theta, st->omega, amp, perr, gain, rate, quad};
}

int gyro_loops_restored_problem(const GyroLoops *l, const GyroLoopSettings *s, char *msg,
                                size_t n) {
    int same = l->settings.mode == s->mode && l->settings.sideband_first == s->sideband_first &&
               l->settings.sideband_count == s->sideband_count;
    for (size_t i = 0; i < N_REALS; i++) /* bitwise: -0.0 and 0.0 differ, NaN equals NaN */
        same = same && !memcmp((const char *)&l->settings + REALS[i].offset,
                               (const char *)s + REALS[i].offset, sizeof(double));
    if (!same) {
        snprintf(msg, n, "the restored loop state was saved with other settings: set the "
                         "parameters it was saved with, or re-initialize");
        return 1;
    }
    const double *x = (const double *)&l->state;
    for (size_t i = 0; i < sizeof l->state / sizeof(double); i++)
        if (!isfinite(x[i])) {
            snprintf(msg, n, "the restored loop state holds a non-finite value (slot %d): "
                             "restore a state this FMU saved", (int)i);
            return 1;
        }
    if (!(l->state.theta >= 0.0 && l->state.theta < TWO_PI)) {
        snprintf(msg, n, "the restored NCO phase %g rad is outside [0, 2 pi): restore a state "
                         "this FMU saved", l->state.theta);
        return 1;
    }
    return 0;
}

size_t gyro_loops_size(void) { return sizeof(GyroLoops); }
size_t gyro_loop_settings_size(void) { return sizeof(GyroLoopSettings); }
