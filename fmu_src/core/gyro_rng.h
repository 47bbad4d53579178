/* Seeded white Gaussian noise, reproducible on every platform.
 *
 * xoshiro256** (Blackman & Vigna 2018) seeded through splitmix64, so any 64-bit seed
 * gives a well-mixed state; normals by Marsaglia's polar method, whose accept/reject
 * decision uses only + and *, so the sequence of draws is the same on every platform
 * (the values differ at most by the last bits of the libm log). */
#ifndef GYRO_RNG_H
#define GYRO_RNG_H

#include <stdint.h>
#include "gyro_structs.h" /* generated: gyro_fmu/core/structs/ */

void gyro_rng_seed(GyroRng *rng, uint64_t seed);
uint64_t gyro_rng_next(GyroRng *rng);
/* Uniform in (-1, 1), 53 random bits. */
double gyro_rng_uniform_pm1(GyroRng *rng);
/* Standard normal N(0, 1). */
double gyro_rng_normal(GyroRng *rng);

#endif
