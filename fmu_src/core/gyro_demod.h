/* A self-calibration record demodulated while it runs, so that memory does not grow with
 * its length (US 9,482,553: "amplitude and phase ... by least squares, since the sideband
 * frequency is well known"; the least squares stay in gyro_fmu.selfcal.phasors).
 *
 * Each of the four channels Vx, Vy, Vpx, Vpy is mixed down with exp(-i omega0 t_k) and
 * low-pass filtered by GYRO_DEMOD_ORDER cascaded boxcars of B samples (a CIC filter,
 * normalized to unit gain at 0 Hz), decimated by B. Output b is centred on step
 * r0 + b B + (B - 1) / 2, b = 0 .. M - 1 with M = n / B, so the M outputs tile the
 * record's n steps r0 .. r0 + n - 1; its filter reaches 2 (B - 1) + 1 steps before the
 * record and 2 B + 1 after it (gyro_demod_first_step, gyro_demod_last_step). The filter's
 * response at f Hz from omega0 is real (zero phase about the centre),
 * H(f) = (sin(pi f B h) / (B sin(pi f h)))^ORDER (gyro_demod_response): the image at
 * -2 omega0 falls on its zeros' shoulders, at most (1 / (B sin(2 pi f0 h)))^ORDER.
 *
 * The loops' NCO phase goes through the same filter, as its departure from omega0 t
 * (unwrapped): its ripple at twice the carrier, which a plain subsample would alias to
 * near 0 Hz and read as a frequency offset, is rejected with the image. Beside them, per
 * record step: the largest |phase_error|, the sum of the amplitude, the largest drive
 * gain and its sum, the steps with the gain at its limit, and the last `tail` steps of Vpx and Vpy at full rate
 * (the pick-off noise above the carrier, alarms.pickoff_noise). */
#ifndef GYRO_DEMOD_H
#define GYRO_DEMOD_H

#include <stddef.h>
#include <stdint.h>
#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */


/* ORDER * B weights of the cascaded boxcars (B^-ORDER times the ORDER-fold convolution of
 * B ones; the last ORDER - 1 are 0). */
void gyro_demod_kernel(int64_t B, double *kernel);

/* Settings checked and the running state cleared; 1 and msg when they are unusable. */
int gyro_demod_init(GyroDemod *d, double omega0, double h, int64_t r0, int64_t n, int64_t B,
                    int64_t tail, double drive_limit, double *base, double *theta,
                    double *tail_po, const double *kernel, char *msg, size_t msg_size);

/* First and last step the demodulator reads. */
int64_t gyro_demod_first_step(const GyroDemod *d);
int64_t gyro_demod_last_step(const GyroDemod *d);

/* Feed rows of a carrier record (GYRO_CARRIER_COLUMNS columns, gyro_carrier.h) for the
 * consecutive steps k_first .. k_first + count - 1; steps before the first one read are
 * skipped, after the last one ignored. 1 and msg when a step is missing or repeated. */
int gyro_demod_feed(GyroDemod *d, const double *rows, int64_t k_first, int64_t count,
                    char *msg, size_t msg_size);

/* H(f), the filter's response f Hz from omega0 (real: the outputs are time-stamped at
 * their centres). */
double gyro_demod_response(const GyroDemod *d, double f);

/* sizeof(GyroDemod), for the library's check of its ctypes mirror. */
size_t gyro_demod_size(void);

#endif
