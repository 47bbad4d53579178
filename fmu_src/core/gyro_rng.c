#include "gyro_rng.h"

#include <math.h>

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void gyro_rng_seed(GyroRng *rng, uint64_t seed) {
    uint64_t x = seed;
    for (int i = 0; i < 4; i++) rng->s[i] = splitmix64(&x);
    rng->spare = 0.0;
    rng->has_spare = 0;
    rng->reserved = 0;
}

uint64_t gyro_rng_next(GyroRng *rng) {
    uint64_t *s = rng->s;
    const uint64_t result = rotl(s[1] * 5, 7) * 9;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double gyro_rng_uniform_pm1(GyroRng *rng) {
    /* 53-bit integer in [0, 2^53) mapped to (-1, 1) symmetric, never exactly +-1 */
    const double u = (double)(gyro_rng_next(rng) >> 11) * 0x1.0p-53;  /* [0, 1) */
    return 2.0 * u - 1.0 + 0x1.0p-53;
}

double gyro_rng_normal(GyroRng *rng) {
    if (rng->has_spare) {
        rng->has_spare = 0;
        return rng->spare;
    }
    double u, v, s;
    do {
        u = gyro_rng_uniform_pm1(rng);
        v = gyro_rng_uniform_pm1(rng);
        s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double f = sqrt(-2.0 * log(s) / s);
    rng->spare = v * f;
    rng->has_spare = 1;
    return u * f;
}
