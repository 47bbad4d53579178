/* The state observer of US 2011/0314910 A1 (eqs. 5-9), run as an extended Kalman filter
 * on the augmented state of eq. 5, with an adaptive model of Omega_z(t) (interacting
 * multiple models) and a divergence monitor. Every per-step computation of the observer
 * lives here, once: GyroObserver.fmu and the Python library (GyroStateObserver) call it.
 *
 * Filter state x = [x, vx/wx, y, vy/wy, p_kxx, p_kyy, p_kxy, p_dxx, p_dyy, p_dxy, p_b,
 * Omega_z, dOmega_z/dt, d2Omega_z/dt2 (as many as the rate models use)], wx = sqrt(kxx_0),
 * wy = sqrt(kyy_0); the parameters theta = [kxx, kyy, kxy, dxx, dyy, dxy, b = 1/m] are
 * theta0 + scale p. Units: k's 1/s^2, d's 1/s, m kg, Omega_z rad/s, forces N.
 *
 * One step = update (eq. 8: correct with the measured pair at t) then predict (eq. 5: the
 * exact held-input step to t + h with ux, uy and Omega_z held, as the plant steps), then
 * the monitor's verdict. Design and measurements: docs/observer-design.md,
 * docs/observer-rate-model.md, docs/observer-soundness.md. */
#ifndef GYRO_OBSERVER_H
#define GYRO_OBSERVER_H

#include <stddef.h>
#include <stdint.h>

#include "gyro_plant.h"
#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */

#define GYRO_OBS_IPAR 4  /* filter-state row of the first parameter */
#define GYRO_OBS_IOM 11  /* filter-state row of Omega_z */
#define GYRO_OBS_KMAX 24 /* most Taylor terms of the held step (||A h|| <= 0.5 needs 18) */
/* omega h above which the observer warns that the step is coarse (gyro_observer_step_warning):
 * the estimates and their sigmas degrade well before the refusal. */
#define GYRO_OBS_OMEGA_H_WARN 1.2

/* Monitor verdicts: 0 ok, 1 warning, >= 2 lost, by cause. */
enum { GYRO_MON_OK, GYRO_MON_WARN, GYRO_MON_NONFINITE, GYRO_MON_NOT_SPD, GYRO_MON_BOUNDS,
       GYRO_MON_INNOVATIONS };
/* GyroMonitor.which of a warning: what tripped it. */
enum { GYRO_WARN_NIS, GYRO_WARN_REL, GYRO_WARN_CORR, GYRO_WARN_REFIT };

/* Results of the calls below that take a message buffer. */
enum {
    GYRO_OBS_STEP_OK = 0,      /* status 0 */
    GYRO_OBS_STEP_WARNING = 1, /* status 1: gyro_observer_warning says why */
    GYRO_OBS_STEP_LOST = 2,    /* the filter was lost in this step: msg says why */
    GYRO_OBS_BAD_INPUT = -1,   /* a non-finite input or step: nothing changed */
    GYRO_OBS_TOO_COARSE = -2,  /* the step aliases the resonance: nothing changed */
    GYRO_OBS_REFUSED = -3      /* lost before: msg repeats why */
};

/* Why a tuning is unusable (names and remedies; non-zero), or 0. */
int gyro_observer_tuning_problems(const GyroObserverTuning *tun, char *msg, size_t n);

/* Build an observer from a parameter guess, Omega_z_0 (rad/s), pair (1 or 2) and tuning;
 * non-zero with msg naming the value and the remedy when they are unusable. */
int gyro_observer_init(GyroObserver *o, const GyroParams *guess, double Omega_z_0, int pair,
                       const GyroObserverTuning *tun, char *msg, size_t n);

/* One step: correct with (z1, z2) at t (eq. 8), propagate to t + h with ux, uy (N) held
 * (eq. 5), judge. Returns GYRO_OBS_* (msg for the negative ones and LOST). */
int gyro_observer_step(GyroObserver *o, double ux, double uy, double z1, double z2, double h,
                       char *msg, size_t n);

/* The two halves of a step (filterpy's update() and predict()); the same codes. */
int gyro_observer_update(GyroObserver *o, double z1, double z2, double h, char *msg, size_t n);
int gyro_observer_predict(GyroObserver *o, double ux, double uy, double h, char *msg,
                          size_t n);

/* The exact held-input step of eq. 5 of a scaled plant state s = [x, vx/wx, y, vy/wy] at
 * theta, Omega_z, ux, uy held over h: s1 = s(t + h), Phi = ds1/ds (4x4), S = ds1/d(p,
 * Omega_z) (4x8), in the filter's scaling. The rate models' predict shares one per step. */
void gyro_observer_held_step(const GyroObserver *o, const double theta[GYRO_OBS_NPAR],
                             double Omega_z, const double s[4], double ux, double uy, double h,
                             double s1[4], double Phi[4][4], double S[4][8]);

/* out[20] = [x, vx, y, vy] (m, m/s), Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m, then the
 * 1-sigmas of those 8 (m by the delta method from 1/m). */
void gyro_observer_outputs(const GyroObserver *o, double out[20]);

/* p[4] = P(the rate is constant / rough / slow / agile): the adaptive set's predicted
 * model probabilities; a fixed model 1 for its kind (agile for tracking); expert all 0. */
void gyro_observer_rate_probabilities(const GyroObserver *o, double p[4]);

/* The re-fit test's last restart in words (0 when it never restarted): what the FMU logs
 * at each restart, whatever the status. */
int gyro_observer_restart_message(const GyroObserver *o, char *msg, size_t n);
/* A step h that the observer takes but that is coarse for the guessed resonance (omega h
 * above 1.2, up to the refusal at 2.5): 1 with msg naming the step and the remedy. */
int gyro_observer_step_warning(const GyroObserver *o, double h, char *msg, size_t n);

/* The warning of status 1 in words (0 when the status is not 1). */
int gyro_observer_warning(const GyroObserver *o, char *msg, size_t n);

/* A state from outside (a restored FMU state): non-zero with msg when it is not one this
 * tuning, pair and guess could have made, or a field its step reads is out of range; when
 * usable, its cached rate models are dropped (rebuilt at the next step). */
int gyro_observer_restored_problem(GyroObserver *o, const GyroParams *guess,
                                   double Omega_z_0, int pair, const GyroObserverTuning *tun,
                                   char *msg, size_t n);

/* After a saved state's fields were written into a set-up observer (the library's
 * set_state): every field the step reads checked as an FMU's restored state is (finite,
 * in range, each rate model's covariance symmetric to the bit), then the held-step
 * cache's maps rebuilt from its watch fields (the same bits as the saved ones). Nonzero, a
 * message and an empty cache when a field is out of its range. */
int gyro_observer_state_restored(GyroObserver *o, char *msg, size_t n);

/* Set the constants of the filter's scaling (wx, wy, theta0, scale) and what derives from
 * them (hgain, MgT, monitor limits); gyro_observer_init does it from the guess, a restored
 * state from the numbers it saved. */
void gyro_observer_set_scaling(GyroObserver *o, double wx, double wy,
                               const double theta0[GYRO_OBS_NPAR],
                               const double scale[GYRO_OBS_NPAR]);

/* The rate models' transitions Fr, process noise Qr, switching probabilities Pi and the
 * parameter random walk qpar over a step h (cached: step and predict call it when h
 * changes). */
void gyro_observer_set_step(GyroObserver *o, double h);

/* The IMM's two steps on the rate models' filters (xs, Ps), Bar-Shalom et al. eqs.
 * 11.6.6-6 to -10 and -21, -22: mix sets c = Pi' mu and restarts each filter j from the
 * mixture of all with weights mu_i Pi[i][j] / c_j; combine writes the mixture of the
 * filters with weights w (mean, and covariance with the spread of the means) to x, P. */
void gyro_observer_mix(GyroObserver *o);
void gyro_observer_combine(const GyroObserver *o, const double *w, double *x,
                           double P[GYRO_OBS_NMAX][GYRO_OBS_NMAX]);

/* After a prediction with more than one rate model, P holds only what the step reads (its
 * diagonal and the measured rows' columns; P_partial 1). This fills the rest, the mixture
 * of the filters with the predicted probabilities c, the same bits as made whole at the
 * prediction. The monitor calls it before its Cholesky check and a restart; a host that
 * reads all of P calls it first (the library's GyroStateObserver.P does). */
void gyro_observer_complete_covariance(GyroObserver *o);

/* Auto prior started by the drive: 1-sigma of [x, y] as this fraction of the static
 * deflection b |u| / k of the guess. */
extern const double gyro_observer_prior_fraction;

/* Monitor check alone: 1 if P (n x n, row stride GYRO_OBS_NMAX) has a Cholesky factor
 * (positive pivots, or a zero pivot with its whole column zero). */
int gyro_observer_cholesky_ok(const double *P, int n);

/* float(k!) for k <= 47 (the Frechet series' weights); -1 beyond. */
double gyro_observer_factorial(int k);
/* The held step's table j! m! / (j + m + 1)! for j, m < GYRO_OBS_KMAX; -1 beyond. */
double gyro_observer_beta(int j, int m);

size_t gyro_observer_size(void);

/* The adaptive set's graded rough models after its four named ones: writes up to n of
 * their intensities as multiples of the rough model's; returns how many there are. */
int gyro_observer_rough_grades(double *grades, int n);

#endif
