/* The resonator of US 9,482,553 (eq. 1), voltages in and out (GyroResonator.fmu and the
 * self-calibration library step the same code). Per unit modal mass, q = (x, y):
 *     x'' + dxx x' + (dxy - 2 kappa Omega_z) y' + kxx x + kxy y = fx          (eq. 1)
 *     y'' + dyy y' + (dxy + 2 kappa Omega_z) x' + kyy y + kxy x = fy
 *     fx = Bx (Vx + alpha_y Vy),   fy = By (Vy + alpha_x Vx)
 * kxx = (2 pi f_x)^2, dxx = 2 pi f_x / Q_x (y alike); kappa the Bryant factor. Pick-offs:
 * V_p = P z + E V + noise, tau z' = q_s - z + c_ring V_ring (tan phi = 2 pi f_x tau; tau = 0:
 * z = q_s + c_ring V_ring at once), sensed q_s = cos(beta) own + sin(beta) other;
 * V_ring = ring_amplitude (cos w1 t + cos w2 t) from two oscillator states. Optional cubic
 * stiffness k3x x^3 + k3xy y^3, k3y y^3 + k3yx x^3 (eqs. 20-23) by Strang splitting (n
 * substeps: linear flow h/2n, cubic kick h/n, linear flow h/2n); thermomechanical force
 * noise of two-sided intensity 2 k_B T D / m_modal, white drive-voltage noise, and a
 * temperature history dT(t) = temperature_rate t + warmup_span (1 - exp(-t / warmup_tau))
 * (f by tc_f, Q by tc_Q per kelvin; step matrices recomputed every thermal_update_steps
 * steps at the interval's mid temperature) with a temperature sensor T_sensor =
 * temperature + dT(t) + white noise of std temperature_noise (its own stream).
 * docs/resonator-physics.md derives each term.
 *
 * State s = (x, y, vx, vy, zx, zy, ring1 cos, sin, ring2 cos, sin). Each step holds
 * (Vx, Vy, Omega_z) and is the exact zero-order-hold solution (Van Loan: one matrix
 * exponential, cached while Omega_z, h and the temperature stay). Noise: pick-off noise
 * from one seeded generator (2 normals a step), force and drive noise from a second one
 * (8 a step), so the FMU and the in-process run draw the same sequence. */
#ifndef GYRO_RESONATOR_H
#define GYRO_RESONATOR_H

/* Bound of cubic_substeps: a step does this many (the model description declares it). */
#define GYRO_CUBIC_SUBSTEPS_MAX 1000

#include <stddef.h>
#include <stdint.h>

#include "gyro_linalg.h" /* gyro_expm, gyro_white_noise_covariance */
#include "gyro_rng.h"
#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */

#define GYRO_RES_DRAWS 8    /* normals of the second generator per step: 6 force, 2 drive */
#define GYRO_K_B 1.380649e-23 /* Boltzmann constant, J/K */

/* Problems with p (0 when usable), "; "-separated in msg, each naming the value and the
 * remedy. */
int gyro_resonator_problems(const GyroResonatorParams *p, char *msg, size_t n);

/* K from the start temperature t seconds into the run (the history above). */
double gyro_resonator_temperature_offset(const GyroResonatorParams *p, double t);

/* (kxx, kyy, dxx, dyy) dT kelvin from the start temperature; 1 (and msg) where f or Q
 * would reach 0. */
int gyro_resonator_at_temperature(const GyroResonatorParams *p, double dT, double out[4],
                                  char *msg, size_t n);

/* Continuous A (10x10) and B (10x2), dT kelvin from the start; 1 (and msg) as above. */
int gyro_resonator_system(const GyroResonatorParams *p, double Omega_z, double dT,
                          double A[GYRO_RES_N][GYRO_RES_N], double B[GYRO_RES_N][2],
                          char *msg, size_t n);

/* Exact zero-order-hold step over h (a zero-lag pick-off's rows set algebraically). */
int gyro_resonator_discretize(const GyroResonatorParams *p, double Omega_z, double h,
                              double dT, double Phi[GYRO_RES_N][GYRO_RES_N],
                              double Gamma[GYRO_RES_N][2], char *msg, size_t n);

/* Covariance (6x6) of the force noise's increment of (x, y, vx, vy, zx, zy) over h. */
int gyro_resonator_force_covariance(const GyroResonatorParams *p, double Omega_z, double h,
                                    double dT, double Q[GYRO_RES_FORCED][GYRO_RES_FORCED],
                                    char *msg, size_t n);

/* From rest (ring tones at cos = 1) or from initial_state (10 values; NULL for rest);
 * 1 (and msg) when p is unusable. */
int gyro_resonator_init(GyroResonator *r, const GyroResonatorParams *p, uint64_t seed,
                        const double *initial_state, char *msg, size_t n);

/* The maps of the current step (recomputed when Omega_z, h or the thermal interval
 * changed); 1 (and msg) when the ramp took f or Q to 0. */
int gyro_resonator_maps(GyroResonator *r, double Omega_z, double h, char *msg, size_t n);

/* Hold (Vx, Vy, Omega_z) over h; r->out then holds the pick-off voltages at the end.
 * 1 (and msg, nothing changed) when the step matrices cannot be computed. */
int gyro_resonator_step(GyroResonator *r, double Vx, double Vy, double Omega_z, double h,
                        char *msg, size_t n);

/* Steps until the temperature ramp re-discretizes (INT64_MAX without a ramp). */
int64_t gyro_resonator_steps_left(const GyroResonator *r);

/* 1 (and msg) when a restored resonator does not belong to p. */
int gyro_resonator_restored_problem(const GyroResonator *r, const GyroResonatorParams *p,
                                    char *msg, size_t n);

size_t gyro_resonator_size(void);
size_t gyro_resonator_params_size(void);

#endif
