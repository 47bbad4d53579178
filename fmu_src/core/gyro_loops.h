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
#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */

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
