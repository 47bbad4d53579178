/* The gyroscope plant of US 2011/0314910 A1: exact held-input motion plus seeded
 * pick-off noise. Every equation of the plant lives here, once.
 *
 * Normalized form (eqs. 3-4, every stiffness and damping divided by the mass m; the
 * printed eqs. 1-5 mix up subscripts, this is the form the observability matrix C1 of
 * eq. 7 implies):
 *     x'' = -kxx x - kxy y - dxx x' - dxy y' + 2 Omega_z y' + ux / m
 *     y'' = -kxy x - kyy y - dxy x' - dyy y' - 2 Omega_z x' + uy / m
 * State [x, vx, y, vy] (m, m/s); inputs ux, uy (N) and Omega_z (rad/s) are held over each
 * communication step (zero-order hold), so each step is one matrix exponential. */
#ifndef GYRO_PLANT_H
#define GYRO_PLANT_H

#include <stddef.h>
#include <stdint.h>

#include "gyro_rng.h"
#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */

/* s(t+h) = Phi s(t) + Gamma [ux, uy], exact for held inputs, cached for (Omega_z, h). */
typedef struct {
    double Phi[4][4];
    double Gamma[4][2];
    double Omega_z, h;
    int32_t valid, reserved;
} GyroHeldMaps;

typedef struct {
    GyroParams p;
    GyroPickoffNoise sigma;
    GyroState s;                 /* true state at the current time */
    double ux, uy, Omega_z;      /* inputs held over the last step */
    double noise[4];             /* noise of the current communication point */
    GyroRng rng;
    GyroHeldMaps maps;
} GyroPlant;

/* GYRO_K_MAX, GYRO_D_MAX (gyro_structs.h): the largest |stiffness| (1/s^2) and |damping|
 * (1/s) the model integrates accurately. */

/* Continuous-time 4x4 matrix A of [x, x', y, y'] (eqs. 3-4). */
void gyro_system_matrix(const GyroParams *p, double Omega_z, double A[4][4]);

/* Phi (4x4) and Gamma (4x2) of one held-input step of length h (Van Loan: the
 * exponential of [[A, B], [0, 0]] h, velocities scaled by w0 = sqrt(kxx), scaled and
 * squared Taylor series accurate to rounding). */
void gyro_held_input_maps(const GyroParams *p, double Omega_z, double h,
                          double Phi[4][4], double Gamma[4][2]);

/* Why p cannot describe a physical gyroscope ("" when it can): the same texts as
 * gyro_fmu.model.parameters.check_parameters. Returns 0 when usable. */
int gyro_params_problems(const GyroParams *p, char *msg, size_t n);

/* Largest real part (1/s) of the eigenvalues of A: > 0 means a growing mode. Roots of
 * det(s^2 I + s (D + G) + K) = 0 by Durand-Kerner. */
double gyro_max_growth_rate(const GyroParams *p, double Omega_z);

/* sqrt(min(kxx, kyy)), rad/s: no vibratory gyroscope senses a rate that fast (the
 * Coriolis terms 2 Omega_z of eqs. 3-4 would outweigh the modes they couple). */
double gyro_rate_limit(const GyroParams *p);

/* Why Omega_z (rad/s, called `name`) cannot be a rate of p: not finite, or |Omega_z| at
 * or above gyro_rate_limit. Returns 0 ("" in msg) when it can. */
int gyro_rate_problem(const GyroParams *p, const char *name, double Omega_z, char *msg,
                      size_t n);

/* A warning for a growing mode ("" when none); returns 1 when there is one. */
int gyro_params_warning(const GyroParams *p, char *msg, size_t n);

/* Start at rest (or at s0) and draw the noise of t = start. Parameters must have been
 * checked with gyro_params_problems. */
void gyro_plant_init(GyroPlant *g, const GyroParams *p, const GyroPickoffNoise *sigma,
                     uint64_t seed, const GyroState *s0);

/* Advance from t to t+h, h > 0, with ux, uy (N) and Omega_z (rad/s) held. */
void gyro_plant_step(GyroPlant *g, double ux, double uy, double Omega_z, double h);

/* Measured outputs at the current time: [x, vx, y, vy] with noise, then ax, ay (m/s^2,
 * eqs. 3-4 with the inputs of the last step). */
void gyro_plant_outputs(const GyroPlant *g, double out[6]);

/* Check a plant restored from saved bytes against the parameters and noise it must have
 * (a saved state is data from outside): "" and 0 when it fits; the step cache is dropped
 * so that nothing computed before is trusted. */
int gyro_plant_restored_problem(GyroPlant *g, const GyroParams *p,
                                const GyroPickoffNoise *sigma, char *msg, size_t n);

/* Bytes of a GyroPlant, for bindings that allocate it. */
size_t gyro_plant_size(void);

#endif
