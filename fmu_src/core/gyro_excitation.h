/* How much the two-tone drive tells about the rate: the Cramer-Rao bound of Omega_z over a
 * window, and the warning for a drive whose tones sit far from the gyro's modes (issue 44:
 * a drive that leaves the rate weakly observable must say so before the run).
 *
 * The bound is that of the 8 unknowns (Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m; eq. 7)
 * from the measured pair sampled every h from rest, with white noise of std = one of
 * each channel's own peak over the window ("relative" noise: a ratio of two bounds
 * depends on neither the noise level nor the force). The sensitivities are exact for the
 * held-input model (eqs. 3-4): [s, ds/dtheta_i] is stepped with the exponential of
 * [[A, 0, B], [dA_i, A, dB_i], [0, 0, 0]] h (Van Loan), in the scaling of
 * gyro_fmu.estimation.sensitivity, whose scipy version tests/test_excitation_core.py
 * compares with this one. */
#ifndef GYRO_EXCITATION_H
#define GYRO_EXCITATION_H

#include <stddef.h>

#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */

/* A drive loses information when its bound on Omega_z is more than this times the best of
 * the tones placed around the guessed modes (gyro_drive_information_loss). */
#define GYRO_DRIVE_LOSS_WARN 2.0
/* The window the bounds are taken over (s), and the most samples it holds: at a step below
 * GYRO_EXCITATION_WINDOW / GYRO_EXCITATION_MAX_SAMPLES the window is that many steps
 * (bounded work: about 40 ms of CPU for the five bounds of a loss). */
#define GYRO_EXCITATION_WINDOW 0.04
#define GYRO_EXCITATION_MAX_SAMPLES 40000

/* The Cramer-Rao 1-sigma of Omega_z (rad/s) per unit relative noise, from rest over
 * `window` at step h, measured_pair 1 (x, y) or 2 (vx, vy); inf when the window does not
 * identify Omega_z, NaN when the arguments cannot give a bound. */
double gyro_drive_rate_bound(const GyroParams *p, const GyroTwoToneDrive *drive,
                             double Omega_z, double h, int measured_pair, double window);

/* The bound of `drive` divided by the smallest of the mode-placed drives (tones at
 * (0.97 lo, 1.03 hi), (0.99 lo, 1.01 hi), (0.9 lo, 1.1 hi), (0.98 lo, 0.98 hi + 0.02 lo),
 * lo and hi the guess's undamped modes sqrt(kxx) / 2 pi and sqrt(kyy) / 2 pi in order,
 * the drive's amplitudes, each tone below the Nyquist frequency of h), over
 * GYRO_EXCITATION_WINDOW; `proposal` gets the best of them (the drive itself, loss 1,
 * when none fits below Nyquist). NaN when no bound can be taken. */
double gyro_drive_information_loss(const GyroParams *guess, const GyroTwoToneDrive *drive,
                                   double Omega_z, double h, int measured_pair,
                                   GyroTwoToneDrive *proposal);

/* The warning for a drive that loses more than GYRO_DRIVE_LOSS_WARN (its cause, the
 * factor and the tones to use) in msg, returning 1; "" and 0 when the drive is fine or
 * has no force. Omega_z 0 is taken as 1 rad/s (the bound is of a rate, not of none). */
int gyro_drive_warning(const GyroParams *guess, const GyroTwoToneDrive *drive,
                       double Omega_z, double h, int measured_pair, char *msg, size_t n);

#endif
