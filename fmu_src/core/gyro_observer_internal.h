/* The observer's internals, shared by its files and by nothing else (gyro_observer.h is
 * the API): shorthands, the tuned constants with the measurements behind them, and the
 * functions one file calls in another. One file per idea, as PX4's EKF:
 *   gyro_observer.c          construction, the step and its halves, outputs, restored states
 *   gyro_observer_held.c     the exact held-input step of eq. 5 and its sensitivities
 *   gyro_observer_correct.c  the correction of eq. 8: noise variances, gain, innovations
 *   gyro_observer_refit.c    the re-fit test: is the estimate still the data's best fit?
 *   gyro_observer_imm.c      the IMM over the rate models: mix, correct, predict, combine
 *   gyro_observer_rates.c    the rate models: transitions, process noise, switching
 *   gyro_observer_monitor.c  the divergence monitor and the words of its verdicts */
#ifndef GYRO_OBSERVER_INTERNAL_H
#define GYRO_OBSERVER_INTERNAL_H

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gyro_observer.h"
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
/* rate_model 4, the moving bank (a setting; the default is 0): constant, rough, slow, agile and
 * two more random walks, the rough ones at c x {1, 1/BANK_RATIO, BANK_RATIO} of the rough
 * intensity and the slow one at min(c, 1) of its own; log c moves each step by
 * (h / BANK_TAU) ln(BANK_RATIO) (mu_high - mu_low) / (mu_rough + mu_low + mu_high + mu_slow)
 * within [BANK_MIN, BANK_MAX] (a moving-bank estimator: Maybeck and Hentz, 1987). A sway of
 * 0.05 rad/s at 2 Hz, far below the fixed grades, had error/sigma 3.9 with rate_model 0
 * and 0.97 with the bank; the slow model's probability in the denominator stops c from
 * running down while the slow model holds (docs/observer-rate-model.md). */
#define BANK_MODELS 6
static const double BANK_RATIO = 10.0;
static const double BANK_TAU = 0.03;
static const double BANK_MIN = 1e-3;
static const double BANK_MAX = 10.0;
/* rate_model 0's constant model is tested along Omega_z at two time scales (GyroWander,
 * gyro_observer_rates.c): over blocks of WANDER_BLOCK[k], r = C^2 / V (1 on average while
 * the model is consistent); each block moves log q_k by WANDER_GAIN[k] (min(r,
 * WANDER_RMAX) - 1 - WANDER_BIAS[k]) within [log WANDER_MIN, log WANDER_MAX] of the rough
 * model's intensity; q_k is 0 at the floor, and the model's intensity is q_0 + q_1 (at
 * rest: 0, the constant model as before). Measured in process on GyroSensor's chain
 * (docs/observer-rate-model.md, "The constant model's wander test"):
 * - the 20 ms scale finds a 2 Hz sway within a few blocks; the 200 ms scale finds the
 *   slow ones (0.05 rad/s at 0.5 Hz moves too little in 20 ms: error/sigma 4.4 with that
 *   scale alone, 1.45 with both). At 100 ms with gain 1 and bias 0.25 the slow sways read
 *   1.4 but the noise at rest of a high-q seed rose 2x (a slowly converging estimate looks
 *   like a wandering rate there); at 200 ms with gain 0.5, 4.5;
 * - the bias pulls q to 0 unless the data ask for more. Without it, at rest q wandered up
 *   to 1e-3 on some seeds (a 20 ms block cannot tell an over-cautious q below that) and
 *   the noise over 10 s at rest rose 1.3-2.3x; with 0.5 at 20 ms, one high-q seed in 8
 *   still rose 1.4x (datasheet's arw). With these, the noise at rest is within 2 % of the
 *   constant model's on 20 preset seeds: the floor's depth keeps the excursions below 1e-7;
 * - the cap on r bounds one block's move (a chi-square outlier at rest);
 * - q does not rise in a block where the constant model's probability fell below
 *   WANDER_MU: a jump, the rough models' to follow. Without it, after a 10 rad/s jump q
 *   reached the rough intensity and took 0.6 s to come down, and the high-q datasheet's
 *   scale-factor error rose from 1 +- 17 to 44 +- 76 ppm. At 0.1 the sways in which the
 *   rough models share the probability were gated too (0.5 rad/s at 2 Hz: 1.0 -> 2.0). */
static const double WANDER_BLOCK[2] = {0.02, 0.2};
static const double WANDER_GAIN[2] = {0.5, 0.75};
static const double WANDER_BIAS[2] = {0.75, 0.5};
static const double WANDER_RMAX = 20.0;
static const double WANDER_MIN = 1e-12;
static const double WANDER_MAX = 1.0;
static const double WANDER_MU = 1e-6;
static const double WANDER_AVG = 0.2; /* r's average over blocks (a diagnostic) */
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
/* Held-step reuse (gyro_observer_held.c): the maps are rebuilt once the linearization
 * point moves so far that ||dA_aug h||_inf > HELD_TOL. s1 and Phi are corrected to first
 * order (O(HELD_TOL^2) left: 1e-14); S is taken at the maps' point, O(HELD_TOL) relative
 * off, and enters only the covariance. Measured effect on Omega_hat at most 1.5e-6 of its
 * sigma (GyroSensor's presets at 20 us, 1 s), every output of the 5 us chain 2.5e-9 of its
 * peak (docs/results/performance.md). 1e-8 reused 0.2-78 % of GyroSensor's first second
 * (its converged parameters move ~3e-9 a step there), 1e-7 66-96 %. Maps are built after
 * HELD_STEADY steps within HELD_TOL of one point (no builds while the filter converges). */
static const double HELD_TOL = 1e-7;
static const double HELD_STEADY = 8.0;
/* kxx, kyy and 1/m must stay within this factor of their initial guesses. */
static const double RATIO = 100.0;

/* float(k!) for k < 48 (GYRO_FACTORIAL, generated: gyro_fmu/core/structs/tables.py). */
#include "gyro_tables.h"
#define FACTORIAL GYRO_FACTORIAL

/* A function called with a constant argument that sizes its innermost loops, expanded at
 * each call so that each has loops of a fixed length (unrolled, vectorized). */
#if defined(__GNUC__) || defined(__clang__)
#define FIXED_LENGTH static inline __attribute__((always_inline))
#else
#define FIXED_LENGTH static inline
#endif

static inline double dmax(double a, double b) { return a >= b ? a : b; }
static inline double dmin(double a, double b) { return a <= b ? a : b; }
/* 1 when all count numbers from v on are finite (restored states, held-step maps). */
static inline int all_finite(const double *v, size_t count) {
    for (size_t i = 0; i < count; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* The rows of model j's filter that its rate model can make nonzero: the plant, the
 * parameters and the derivatives of Omega_z up to its order (Fr's unit diagonal). Its
 * prediction sets the rows and columns past them to zero (Fr's rows there are zero), so
 * the mixing before it and the correction after it need not compute them. */
static inline int model_rows(const GyroObserver *o, int j) {
    int rows = IOM;
    while (rows < o->n && o->Fr[j][rows - IOM][rows - IOM] != 0.0) rows++;
    return rows;
}

/* gyro_observer_held.c */
void obs_linearize(GyroObserver *o, const double *x, double ux, double uy, double h,
                   double s1[4], double Phi[4][4], double S[4][8]);
void obs_held_reset(GyroObserver *o);
const char *obs_held_restored(GyroObserver *o);

/* gyro_observer_correct.c */
void obs_noise_variances(GyroObserver *o, double z1, double z2, double h, double R[2],
                         double Rc[2], double nu[2]);
double obs_correct_with(const GyroObserver *o, double *x, double P[NMAX][NMAX], int rows,
                        double z1, double z2, const double R[2], const double Rc[2],
                        double *logdet);
int obs_innovation_covariance(const GyroObserver *o, const double R[2], double S[4]);
void obs_monitor_innovations(GyroObserver *o, const double nu[2], const double R[2]);

/* gyro_observer_refit.c */
void obs_refit_correct(GyroObserver *o, const double nu[2], const double R[2], double h);
void obs_refit_predict(GyroObserver *o, const double Phi[4][4], const double S[4][8]);
void obs_refit_restart(GyroObserver *o);
double obs_refit_judge(GyroObserver *o, double h);

/* gyro_observer_imm.c */
void obs_imm_update(GyroObserver *o, double z1, double z2, double h, int with_P);
/* gyro_observer_rates.c: rate_model 4's bank moved after a correction's probabilities. */
void obs_bank_move(GyroObserver *o);
void obs_wander_step(GyroObserver *o, double x0, double p0, double h);
void obs_imm_predict(GyroObserver *o, double ux, double uy, double h);

/* gyro_observer_monitor.c */
int obs_monitor_check(GyroObserver *o);
void obs_lose(GyroObserver *o, double h);

#endif
