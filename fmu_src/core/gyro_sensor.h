/* The gyroscope as a sensor: the two-tone drive, the plant and the observer of
 * US 2011/0314910 A1 (Fig. 2) run together at a fixed internal step, followed by a readout
 * (output filter, full-scale limit, quantization) sampled whenever the host asks.
 *
 * Per internal step k (t_k = t0 + k h, Jacobi order, as the four FMUs run in a master):
 *     ux_k = A1 sin(2 pi f1 t_k) + A2 sin(2 pi f2 t_k)            (eq. 10)
 *     z_k  = the plant's measured pair at t_k (noisy)
 *     observer: correct with z_k, predict to t_k+1 with ux_k held  (eqs. 5-9)
 *     plant: t_k -> t_k+1 with ux_k and the host's Omega_z held    (eqs. 3-4)
 *     y_k+1 = readout filter of the observer's Omega_hat at t_k+1
 * The readout filter is a 2nd-order Butterworth low-pass of -3 dB bandwidth f_c, by the
 * bilinear transform prewarped at f_c; the output is y clamped to +-full_scale, then
 * rounded to a multiple of resolution (0: none). A communication point between internal
 * steps reads the output of the last internal step at or before it (held: the sensor's
 * output data is sampled, not interpolated). */
#ifndef GYRO_SENSOR_H
#define GYRO_SENSOR_H

#include <stddef.h>
#include <stdint.h>

#include "gyro_observer.h"
#include "gyro_plant.h"
#include "gyro_signals.h"
#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */

/* Most internal steps one call may do (bounded work: 1 s of sensor time at 5 us, about
 * 3 s of CPU with the adaptive observer). */
#define GYRO_SENSOR_MAX_STEPS 200000
/* internal_step 0 (auto): h = min(GYRO_SENSOR_STEP_MAX, GYRO_SENSOR_OMEGA_H / omega), omega
 * the larger design resonance (rad/s): 12.6 samples per period of the faster mode. The
 * observer's accuracy at a fixed noise density is the same at 5 and 20 us on the default
 * gyro (docs/gyro-sensor.md), and the cost is a quarter. */
#define GYRO_SENSOR_STEP_MAX 20e-6
#define GYRO_SENSOR_OMEGA_H 0.5
/* The pick-off noise is given as its std per sample at this step; at another internal step
 * h the std per sample is noise sqrt(GYRO_SENSOR_NOISE_STEP / h): the density is the same. */
#define GYRO_SENSOR_NOISE_STEP 5e-6

typedef struct {
    GyroTwoToneDrive drive;
    GyroReadout readout; /* as given */
    double h;            /* the internal step used, s */
    GyroPlant plant;
    GyroObserver observer;
    double b[3], a[3];   /* the filter's coefficients (a[0] = 1) */
    double w[2];         /* its state (direct form II transposed) */
    double y;            /* the filter's output at the last internal step, rad/s */
    double t0;           /* s, start time */
    int64_t k;           /* internal steps done */
} GyroSensor;

/* The internal step the sensor runs at: r->internal_step, or for 0 the auto rule above
 * from the design's larger resonance. */
double gyro_sensor_step(const GyroReadout *r, const GyroParams *design);

/* Build the sensor: truth and noise are the gyro as fabricated (noise: the std per sample
 * at GYRO_SENSOR_NOISE_STEP), design the observer's start (its initial guesses),
 * Omega_z_0 its initial rate. Returns 0, or 1 with msg. */
int gyro_sensor_init(GyroSensor *s, const GyroParams *truth, const GyroPickoffNoise *noise,
                     uint64_t seed, const GyroParams *design, double Omega_z_0,
                     const GyroObserverTuning *tuning, const GyroTwoToneDrive *drive,
                     const GyroReadout *readout, double t0, char *msg, size_t n);

/* Internal steps from the current internal time up to the last one at or before t_end,
 * with Omega_z (rad/s) held. Returns the observer's step code of the last step
 * (GYRO_OBS_STEP_OK, _WARNING, _LOST or a refusal < 0, msg says why); on a refusal or
 * a lost filter the steps before it stand. Refuses (GYRO_OBS_BAD_INPUT) an Omega_z that
 * is not finite or beyond the gyro's rate limit, or more than GYRO_SENSOR_MAX_STEPS. */
int gyro_sensor_advance(GyroSensor *s, double Omega_z, double t_end, char *msg, size_t n);

/* The internal time reached (s). */
double gyro_sensor_time(const GyroSensor *s);

/* Outputs: [0] Omega_meas (rad/s, filtered, clamped, quantized), [1] its 1-sigma (the
 * observer's sigma of Omega_z with the quantization's q^2 / 12), [2] Omega_hat (the
 * observer's estimate before the readout), [3] status (0 ok, 1 warning, 2 lost),
 * [4] saturated (1: clamped at full scale). */
void gyro_sensor_outputs(const GyroSensor *s, double out[5]);

/* A sensor restored from saved bytes, checked against the settings it must have (the
 * plant's and the observer's own checks, the filter finite, the clock sane). */
int gyro_sensor_restored_problem(GyroSensor *s, const GyroParams *truth,
                                 const GyroPickoffNoise *noise, const GyroParams *design,
                                 double Omega_z_0, const GyroObserverTuning *tuning,
                                 const GyroTwoToneDrive *drive, const GyroReadout *readout,
                                 char *msg, size_t n);

size_t gyro_sensor_size(void);

#endif
