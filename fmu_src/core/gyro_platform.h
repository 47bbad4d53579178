/* A single-axis stabilized platform: the system example that needs a gyroscope (a rate
 * loop fed by GyroSensor; docs/tutorials/sensor-in-system.md). Not of the patents: the
 * smallest closed loop whose quality the gyro's noise, bias and lag set.
 *
 * The platform (inertia J) sits on a vehicle of rate w_b through bearing friction c; a
 * motor torque tau, from a PI loop on the measured rate w_meas, holds it still in
 * inertial space:
 *     J dw/dt = c (w_b - w) + tau,        theta = integral of w  (the pointing error)
 *     I += w_meas h,  tau = -Kp w_meas - Ki I                     (the rate loop)
 * Over a step h with w_b, w_meas (hence tau) held, exactly (a first-order system):
 *     w_inf = w_b + tau / c,  a = exp(-c h / J)
 *     w(t+h) = w_inf + (w - w_inf) a
 *     theta(t+h) = theta + w_inf h + (w - w_inf) (1 - a) J / c */
#ifndef GYRO_PLATFORM_H
#define GYRO_PLATFORM_H

#include <stddef.h>
#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */

typedef struct {
    double w;     /* rad/s, the platform's inertial rate */
    double theta; /* rad, its pointing error */
    double I;     /* rad, the rate loop's integral of w_meas */
    double tau;   /* N m, the torque of the last step */
} GyroPlatform;

/* Why p is no platform ("" and 0 when it is one). */
int gyro_platform_problems(const GyroPlatformParams *p, char *msg, size_t n);

/* One step of h s with the vehicle's rate w_b and the measured rate w_meas held. */
void gyro_platform_step(GyroPlatform *s, const GyroPlatformParams *p, double w_b,
                        double w_meas, double h);

#endif
