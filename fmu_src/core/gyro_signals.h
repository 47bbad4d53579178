/* The signal sources of the gyroscope's co-simulation: the two-tone single-axis drive
 * of US 2011/0314910 A1 eq. 10 and the angular-rate profiles Omega_z(t). */
#ifndef GYRO_SIGNALS_H
#define GYRO_SIGNALS_H

#include <stddef.h>
#include <stdint.h>
#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */

double gyro_drive_ux(const GyroTwoToneDrive *d, double t);
/* Why the drive is unusable ("" when fine); returns 0 when usable. */
int gyro_drive_problems(const GyroTwoToneDrive *d, char *msg, size_t n);

/* Shape of a rate profile: the Integer `kind` of RateProfile.fmu. */
typedef enum {
    GYRO_RATE_CONSTANT = 1, /* offset */
    GYRO_RATE_STEP = 2,     /* offset, plus amplitude from t_start on */
    GYRO_RATE_RAMP = 3,     /* offset, plus slope (t - t_start) from t_start on */
    GYRO_RATE_SINE = 4      /* offset + amplitude sin(2 pi frequency (t - t_start)) from t_start */
} GyroRateKind;

double gyro_rate_Omega_z(const GyroRateProfile *r, double t);
int gyro_rate_problems(const GyroRateProfile *r, char *msg, size_t n);

/* Sampled every h seconds (the communication step), a tone at or above the Nyquist
 * frequency 1 / (2 h) aliases: the plant sees another frequency than the one set, and
 * the run gives a wrong number with no error. "" and 0 when every tone is below it. */
int gyro_drive_nyquist_problem(const GyroTwoToneDrive *d, double h, char *msg, size_t n);
int gyro_rate_nyquist_problem(const GyroRateProfile *r, double h, char *msg, size_t n);

#endif
