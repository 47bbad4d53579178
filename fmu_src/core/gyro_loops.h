/* The closed-loop electronics of US 9,482,553 (GyroLoops.fmu and the self-calibration
 * library step the same code), one pick-off sample per step:
 * - feed-forward removal of the drive feed-through (the pick-off at t holds E V of the
 *   hold that ended at t; seed: "feed forward errors are removed from the position signal");
 * - oscillator loop: I/Q demodulation on the NCO phase theta, 3 low-pass sections, PI on
 *   the phase error (PLL); drive -g sin(theta + osc_phase), 90 deg ahead of the pick-off;
 *   PI amplitude control of g on the sideband-modulated position signal
 *   (1 + sum_k m sin(2 pi k df t + psi_k)), Schroeder phases psi_k = -pi k (k-1) / count;
 * - force rebalance of the secondary axis (eq. 7): demodulate, 2 low-pass sections,
 *   u = -i K (b + w_i int b), remodulate; rate = Im(u) (sign by mode), quad = Re(u);
 * - mode 1: x oscillates, y rebalanced; mode 2 swapped (mode reversal); mode 0 loops off,
 *   off-resonant tones on Vx and Vy (feed-forward measurement).
 * Drive outputs are computed at the middle of the next hold (theta + omega h / 2). */
#ifndef GYRO_LOOPS_H
#define GYRO_LOOPS_H

/* Bounds of the Integer settings (the model description declares the same). */
#define GYRO_SIDEBAND_COUNT_MAX 1000
#define GYRO_SIDEBAND_FIRST_MAX 1000000

#include <stddef.h>
#include <stdint.h>

/* The user's settings, in the order of gyro_fmu.selfcal.loops.LoopSettings (SI units;
 * tuning uses nominal plant values, not the true ones). */
typedef struct {
    int32_t mode;                /* 0 loops off, 1 x oscillator / y rebalanced, 2 reversed */
    double f_nominal;            /* Hz, NCO centre frequency */
    double amplitude;            /* V, primary pick-off amplitude setpoint */
    double q_nominal;            /* nominal Q, for the drive feed-forward */
    double plant_gain;           /* 1/s, nominal P B / (2 omega) of each axis */
    double pll_bandwidth;        /* Hz */
    double agc_bandwidth;        /* Hz */
    double rebalance_bandwidth;  /* Hz */
    double demod_cutoff;         /* Hz, each of 3 low-pass sections (PLL, AGC) */
    double rebalance_cutoff;     /* Hz, each of 2 low-pass sections (rebalance) */
    double drive_limit;          /* V, largest oscillator drive amplitude */
    double osc_phase;            /* rad, oscillator loop phase away from 90 deg */
    double sideband_index;       /* modulation index of each sideband tone */
    double sideband_spacing;     /* Hz, df */
    int32_t sideband_first;      /* first harmonic k of df, 0..GYRO_SIDEBAND_FIRST_MAX */
    int32_t sideband_count;      /* number of tones, 0..GYRO_SIDEBAND_COUNT_MAX (each step
                                    sums them: the bound keeps a step's work bounded) */
    double sideband_start;       /* s, modulation switches on here */
    double ff_xx, ff_xy, ff_yx, ff_yy; /* V/V, feed-forward corrections (pick-off, drive) */
    double excitation_amplitude; /* V, mode 0 tones on Vx and Vy */
    double excitation_offset_x;  /* Hz, Vx tones at f_nominal -/+ this */
    double excitation_offset_y;  /* Hz, Vy tones */
} GyroLoopSettings;

/* Gains derived once from the settings (gyro_loops_init). */
typedef struct {
    double w_nominal;             /* rad/s */
    double pll_kp, pll_ki;        /* PLL: (2 pi B), (2 pi B)^2 / 4 */
    double agc_kp, agc_ki;        /* AGC: 2 zeta wn / c, wn^2 / c (zeta 0.7) */
    double agc_feedforward;       /* V: amplitude / (c tau), tau = Q / (pi f) */
    double rebalance_gain;        /* 2 pi B / c */
    double rebalance_wi;          /* 1/s: 2 pi B / 5 */
} GyroLoopGains;

/* The loop state: NCO, integrators, low-pass sections (re, im pairs), held drives. */
typedef struct {
    double theta, omega;          /* NCO phase in [0, 2 pi) and frequency, rad/s */
    double pll_integral, agc_integral;
    double agc_lowpass[3][2];     /* the PLL/AGC demodulator's 3 sections */
    double rebalance_lowpass[2][2];
    double rebalance_integral[2];
    double v_held[2];             /* Vx, Vy of this hold */
    double v_previous[2];         /* of the previous hold (feed-forward removal) */
} GyroLoopState;

/* Outputs, in the order of gyro_fmu.selfcal.loops.OUTPUTS. */
typedef struct {
    double Vx, Vy, theta, omega, amplitude, phase_error, gain, rate, quad;
} GyroLoopOutputs;

typedef struct {
    GyroLoopSettings settings;
    GyroLoopGains gains;
    GyroLoopState state;
    GyroLoopOutputs out;
} GyroLoops;

/* Problems with the settings (0 when usable), "; "-separated in msg, each naming the value
 * and the remedy. */
int gyro_loop_settings_problems(const GyroLoopSettings *s, char *msg, size_t n);

/* Start from rest at the NCO centre frequency; 1 (and msg) when the settings are unusable. */
int gyro_loops_init(GyroLoops *l, const GyroLoopSettings *s, char *msg, size_t n);

/* Consume the pick-offs (px, py) sampled at t; write the outputs for the hold from t + h. */
void gyro_loops_step(GyroLoops *l, double px, double py, double t, double h);

/* 1 (and msg) when a restored loop state does not belong to these settings. */
int gyro_loops_restored_problem(const GyroLoops *l, const GyroLoopSettings *s, char *msg,
                                size_t n);

size_t gyro_loops_size(void);
size_t gyro_loop_settings_size(void);

#endif
