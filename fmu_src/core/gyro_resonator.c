#include "gyro_resonator.h"

#include "gyro_linalg.h"
#include "gyro_text.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#define N GYRO_RES_N
#define NF GYRO_RES_FORCED
#define TWO_PI (2.0 * GYRO_PI)

#define REAL(name) {#name, offsetof(GyroResonatorParams, name)}
static const struct {
    const char *name;
    size_t offset;
} REALS[] = {
    REAL(f_x), REAL(f_y), REAL(Q_x), REAL(Q_y), REAL(dxy), REAL(kxy), REAL(kappa), REAL(Bx),
    REAL(By), REAL(alpha_x), REAL(alpha_y), REAL(Px), REAL(Py), REAL(phi_x), REAL(phi_y),
    REAL(Exx), REAL(Exy), REAL(Eyx), REAL(Eyy), REAL(c_ring), REAL(k3x), REAL(k3y),
    REAL(ring_amplitude), REAL(ring_frequency_1), REAL(ring_frequency_2), REAL(noise),
    REAL(beta_x), REAL(beta_y), REAL(k3xy), REAL(k3yx), REAL(m_modal), REAL(temperature),
    REAL(drive_noise), REAL(temperature_rate), REAL(tc_f), REAL(tc_Q), REAL(warmup_span),
    REAL(warmup_tau), REAL(temperature_noise)};
#define N_REALS (sizeof REALS / sizeof REALS[0])

static double real_of(const GyroResonatorParams *p, size_t i) {
    return *(const double *)((const char *)p + REALS[i].offset);
}

static double omega_x(const GyroResonatorParams *p) { return TWO_PI * p->f_x; }
static double omega_y(const GyroResonatorParams *p) { return TWO_PI * p->f_y; }

/* tau of pick-off i (0: x, 1: y); both from tan(phi) / omega_x (phi given at f_x) */
static double tau_of(const GyroResonatorParams *p, int i) {
    return tan(i == 0 ? p->phi_x : p->phi_y) / omega_x(p);
}

static double beta_of(const GyroResonatorParams *p, int i) { return i == 0 ? p->beta_x : p->beta_y; }

int gyro_resonator_problems(const GyroResonatorParams *p, char *msg, size_t n) {
    char text[320], v[GYRO_REAL_TEXT];
    if (n) msg[0] = '\0';
    for (size_t i = 0; i < N_REALS; i++)
        if (!isfinite(real_of(p, i))) {
            snprintf(text, sizeof text, "%s=%s is not finite: give a finite number",
                     REALS[i].name, gyro_real_text(real_of(p, i), v));
            gyro_text_add(msg, n, text);
        }
    if (msg[0]) return 1;
    static const char *const positive[] = {"f_x", "f_y", "Q_x", "Q_y", "kappa",
                                           "Bx", "By", "Px", "Py"};
    for (size_t k = 0; k < sizeof positive / sizeof positive[0]; k++)
        for (size_t i = 0; i < N_REALS; i++)
            if (!strcmp(REALS[i].name, positive[k]) && !(real_of(p, i) > 0.0)) {
                snprintf(text, sizeof text, "%s=%s must be > 0", positive[k],
                         gyro_real_text(real_of(p, i), v));
                gyro_text_add(msg, n, text);
            }
    const double phis[2] = {p->phi_x, p->phi_y}, betas[2] = {p->beta_x, p->beta_y};
    for (int i = 0; i < 2; i++)
        if (!(0.0 <= phis[i] && phis[i] < 1.5)) {
            snprintf(text, sizeof text, "phi_%c=%s rad must lie in [0, 1.5): a pick-off lag "
                     "(0 = none)", "xy"[i], gyro_real_text(phis[i], v));
            gyro_text_add(msg, n, text);
        }
    for (int i = 0; i < 2; i++)
        if (!(fabs(betas[i]) < 0.5)) {
            snprintf(text, sizeof text, "beta_%c=%s rad must lie in (-0.5, 0.5): a small tilt "
                     "of the pick-off's axis (0 = on its mode axis)", "xy"[i],
                     gyro_real_text(betas[i], v));
            gyro_text_add(msg, n, text);
        }
    if (p->cubic_substeps < 1 || p->cubic_substeps > GYRO_CUBIC_SUBSTEPS_MAX) {
        snprintf(text, sizeof text, "cubic_substeps=%d must be in 1..%d (a step does that many)",
                 (int)p->cubic_substeps, GYRO_CUBIC_SUBSTEPS_MAX);
        gyro_text_add(msg, n, text);
    }
    if (p->thermal_update_steps < 1) {
        snprintf(text, sizeof text, "thermal_update_steps=%d must be >= 1",
                 (int)p->thermal_update_steps);
        gyro_text_add(msg, n, text);
    }
    const struct {
        const char *name, *unit;
        double value;
    } nonneg[] = {{"noise", "V", p->noise}, {"drive_noise", "V", p->drive_noise},
                  {"m_modal", "kg", p->m_modal}, {"temperature", "K", p->temperature},
                  {"temperature_noise", "K", p->temperature_noise}};
    for (int i = 0; i < 5; i++)
        if (nonneg[i].value < 0.0) {
            snprintf(text, sizeof text, "%s=%s %s must be >= 0", nonneg[i].name,
                     gyro_real_text(nonneg[i].value, v), nonneg[i].unit);
            gyro_text_add(msg, n, text);
        } else if (i < 2 && !(nonneg[i].value <= GYRO_RES_NOISE_MAX)) {
            /* a pick-off or drive noise a million times the 1 V carrier is no electronics:
             * the loops would fail on NaNs with no word of the noise */
            snprintf(text, sizeof text, "%s=%s V per sample must lie in [0, %g] V (the "
                     "carriers are about 1 V)", nonneg[i].name,
                     gyro_real_text(nonneg[i].value, v), GYRO_RES_NOISE_MAX);
            gyro_text_add(msg, n, text);
        }
    if (p->warmup_span != 0.0 && !(p->warmup_tau > 0.0)) {
        snprintf(text, sizeof text, "warmup_tau=%s s must be > 0 with a warm-up "
                 "(warmup_span != 0): the warm-up's time constant",
                 gyro_real_text(p->warmup_tau, v));
        gyro_text_add(msg, n, text);
    }
    if (msg[0]) return 1;
    const double wx = omega_x(p), wy = omega_y(p);
    if (p->kxy * p->kxy >= (wx * wx) * (wy * wy)) {
        snprintf(text, sizeof text, "kxy=%s 1/s^2 makes the stiffness indefinite (kxy^2 >= "
                 "kxx kyy): use |kxy| well below the mode stiffnesses", gyro_real_text(p->kxy, v));
        gyro_text_add(msg, n, text);
    } else if (p->m_modal > 0.0 && p->dxy * p->dxy >= (wx / p->Q_x) * (wy / p->Q_y)) {
        snprintf(text, sizeof text, "dxy=%s 1/s makes the damping indefinite (dxy^2 >= dxx "
                 "dyy): thermomechanical noise needs a dissipative damping matrix",
                 gyro_real_text(p->dxy, v));
        gyro_text_add(msg, n, text);
    }
    return msg[0] ? 1 : 0;
}

int gyro_resonator_at_temperature(const GyroResonatorParams *p, double dT, double out[4],
                                  char *msg, size_t n) {
    double wx = omega_x(p), wy = omega_y(p), sq = 1.0;
    if (dT != 0.0) {
        const double sf = 1.0 + p->tc_f * dT;
        sq = 1.0 + p->tc_Q * dT;
        if (!(sf > 0.0 && sq > 0.0)) {
            char a[GYRO_REAL_TEXT], b[GYRO_REAL_TEXT];
            snprintf(msg, n, "the temperature ramp reached %+g K, where f or Q would be <= 0 "
                     "(tc_f=%s, tc_Q=%s): shorten the run", dT, gyro_real_text(p->tc_f, a),
                     gyro_real_text(p->tc_Q, b));
            return 1;
        }
        wx *= sf, wy *= sf;
        out[2] = wx / (p->Q_x * sq), out[3] = wy / (p->Q_y * sq);
    } else {
        out[2] = wx / p->Q_x, out[3] = wy / p->Q_y;
    }
    out[0] = wx * wx, out[1] = wy * wy;
    return 0;
}

int gyro_resonator_system(const GyroResonatorParams *p, double Omega_z, double dT,
                          double A[N][N], double B[N][2], char *msg, size_t n) {
    double kd[4];
    if (gyro_resonator_at_temperature(p, dT, kd, msg, n)) return 1;
    memset(A, 0, sizeof(double) * N * N);
    memset(B, 0, sizeof(double) * N * 2);
    A[0][2] = A[1][3] = 1.0;
    A[2][0] = -kd[0], A[2][1] = -p->kxy, A[2][2] = -kd[2];
    A[2][3] = -(p->dxy - 2 * p->kappa * Omega_z);
    A[3][0] = -p->kxy, A[3][1] = -kd[1], A[3][2] = -(p->dxy + 2 * p->kappa * Omega_z);
    A[3][3] = -kd[3];
    B[2][0] = p->Bx, B[2][1] = p->Bx * p->alpha_y; /* the forcer matrix */
    B[3][0] = p->By * p->alpha_x, B[3][1] = p->By;
    const double f[2] = {p->ring_frequency_1, p->ring_frequency_2};
    for (int r = 0; r < 2; r++) {
        const int j = 6 + 2 * r;
        A[j][j + 1] = -TWO_PI * f[r];
        A[j + 1][j] = TWO_PI * f[r];
    }
    const double ring = p->c_ring * p->ring_amplitude;
    for (int i = 0; i < 2; i++) {
        const double tau = tau_of(p, i), beta = beta_of(p, i);
        if (tau > 0.0) {
            A[4 + i][i] = beta == 0.0 ? 1.0 / tau : cos(beta) / tau;
            A[4 + i][1 - i] = sin(beta) / tau;
            A[4 + i][4 + i] = -1.0 / tau;
            A[4 + i][6] = A[4 + i][8] = ring / tau;
        }
    }
    return 0;
}

/* Rows of a zero-lag pick-off (tau = 0) of an N-row matrix M with `cols` columns:
 * z = q_s, the sensed displacement. */
static void algebraic_pickoffs(const GyroResonatorParams *p, double *M, int cols) {
    for (int i = 0; i < 2; i++) {
        if (tau_of(p, i) > 0.0) continue;
        const double beta = beta_of(p, i), own = cos(beta), other = sin(beta);
        double *z = M + (4 + i) * cols;
        const double *q = M + i * cols, *o = M + (1 - i) * cols;
        for (int j = 0; j < cols; j++) z[j] = beta == 0.0 ? q[j] : own * q[j] + other * o[j];
    }
}

int gyro_resonator_discretize(const GyroResonatorParams *p, double Omega_z, double h,
                              double dT, double Phi[N][N], double Gamma[N][2], char *msg,
                              size_t n) {
    double A[N][N], B[N][2];
    if (gyro_resonator_system(p, Omega_z, dT, A, B, msg, n)) return 1;
    /* velocities in units of omega_x (T s): the Van Loan matrix is then balanced */
    double S[N + 2];
    for (int i = 0; i < N + 2; i++) S[i] = 1.0;
    S[2] = S[3] = 1.0 / omega_x(p);
    enum { M_ = N + 2 };
    double M[M_ * M_] = {0}, E[M_ * M_];
    for (int i = 0; i < N; i++) {
        for (int j = 0; j < N; j++) M[i * M_ + j] = A[i][j] * S[i] / S[j] * h;
        M[i * M_ + N] = B[i][0] * S[i] * h;
        M[i * M_ + N + 1] = B[i][1] * S[i] * h;
    }
    gyro_expm(M_, M, E);
    for (int i = 0; i < N; i++) {
        for (int j = 0; j < N; j++) Phi[i][j] = E[i * M_ + j] / S[i] * S[j];
        Gamma[i][0] = E[i * M_ + N] / S[i];
        Gamma[i][1] = E[i * M_ + N + 1] / S[i];
    }
    algebraic_pickoffs(p, &Phi[0][0], N);
    algebraic_pickoffs(p, &Gamma[0][0], 2);
    const double ring = p->c_ring * p->ring_amplitude;
    for (int i = 0; i < 2; i++) /* z = q_s + c_ring V_ring, instantaneous */
        if (tau_of(p, i) <= 0.0)
            for (int j = 0; j < N; j++) Phi[4 + i][j] += ring * (Phi[6][j] + Phi[8][j]);
    return 0;
}

/* The force noise's covariance with velocities in units of omega_x (positions keep
 * their precision); S is that scaling. */
static int scaled_force_covariance(const GyroResonatorParams *p, double Omega_z, double h,
                                   double dT, double Q[NF * NF], double S[NF], char *msg,
                                   size_t n) {
    double A[N][N], B[N][2], kd[4];
    if (gyro_resonator_system(p, Omega_z, dT, A, B, msg, n)) return 1;
    gyro_resonator_at_temperature(p, dT, kd, msg, n);
    const double wx = omega_x(p);
    for (int i = 0; i < NF; i++) S[i] = 1.0;
    S[2] = S[3] = 1.0 / wx;
    double As[NF * NF], Qc[NF * NF] = {0};
    for (int i = 0; i < NF; i++)
        for (int j = 0; j < NF; j++) As[i * NF + j] = A[i][j] * S[i] / S[j];
    const double c = 2.0 * GYRO_K_B * (p->temperature + dT) / p->m_modal / (wx * wx);
    Qc[2 * NF + 2] = kd[2] * c, Qc[2 * NF + 3] = Qc[3 * NF + 2] = p->dxy * c;
    Qc[3 * NF + 3] = kd[3] * c;
    gyro_white_noise_covariance(NF, As, Qc, h, Q);
    return 0;
}

int gyro_resonator_force_covariance(const GyroResonatorParams *p, double Omega_z, double h,
                                    double dT, double Q[NF][NF], char *msg, size_t n) {
    double Qs[NF * NF], S[NF];
    if (scaled_force_covariance(p, Omega_z, h, dT, Qs, S, msg, n)) return 1;
    for (int i = 0; i < NF; i++)
        for (int j = 0; j < NF; j++) Q[i][j] = Qs[i * NF + j] / S[i] / S[j];
    return 0;
}

/* L (10 x 6): the force noise's increment over h is L w, w standard normal, L L' the
 * covariance (factored with velocities in units of omega_x); a zero-lag pick-off copies
 * its q_s rows. */
static int force_input(const GyroResonatorParams *p, double Omega_z, double h, double dT,
                       double L[N][NF], char *msg, size_t n) {
    double Qs[NF * NF], S[NF], w[NF], U[NF * NF];
    if (scaled_force_covariance(p, Omega_z, h, dT, Qs, S, msg, n)) return 1;
    gyro_jacobi_eigen(NF, Qs, w, U);
    memset(L, 0, sizeof(double) * N * NF);
    for (int i = 0; i < NF; i++)
        for (int j = 0; j < NF; j++) L[i][j] = U[i * NF + j] * sqrt(w[j] > 0.0 ? w[j] : 0.0) / S[i];
    algebraic_pickoffs(p, &L[0][0], NF);
    return 0;
}

static int ramp(const GyroResonator *r) {
    return r->p.temperature_rate != 0.0 || r->p.warmup_span != 0.0;
}

double gyro_resonator_temperature_offset(const GyroResonatorParams *p, double t) {
    double dT = p->temperature_rate * t;
    if (p->warmup_span != 0.0) dT += p->warmup_span * -expm1(-t / p->warmup_tau);
    return dT;
}

/* K from the start temperature of the middle of the current thermal interval. */
static double temperature_offset(const GyroResonator *r, double h) {
    if (!ramp(r)) return 0.0;
    const int64_t N_ = r->p.thermal_update_steps;
    return gyro_resonator_temperature_offset(&r->p, ((double)((r->k / N_) * N_) + N_ / 2.0) * h);
}

/* The temperature sensor's sample at step k (time k h). */
static void sense_temperature(GyroResonator *r, double h) {
    const GyroResonatorParams *p = &r->p;
    r->T_sensor = p->temperature + gyro_resonator_temperature_offset(p, r->k * h);
    if (p->temperature_noise != 0.0)
        r->T_sensor += p->temperature_noise * gyro_rng_normal(&r->sensor_rng);
}

int64_t gyro_resonator_steps_left(const GyroResonator *r) {
    const int64_t N_ = r->p.thermal_update_steps;
    return ramp(r) ? N_ - r->k % N_ : INT64_MAX;
}

static int cubic(const GyroResonatorParams *p) {
    return p->k3x != 0.0 || p->k3y != 0.0 || p->k3xy != 0.0 || p->k3yx != 0.0;
}

static int forced(const GyroResonatorParams *p) { return p->m_modal > 0.0; }

int gyro_resonator_maps(GyroResonator *r, double Omega_z, double h, char *msg, size_t n) {
    GyroResonatorMaps *m = &r->maps;
    const double dT = temperature_offset(r, h);
    if (m->valid && m->Omega_z == Omega_z && m->h == h && m->dT == dT) return 0;
    GyroResonatorMaps fresh = {0};
    const double hs = cubic(&r->p) ? h / (2 * r->p.cubic_substeps) : h;
    if (gyro_resonator_discretize(&r->p, Omega_z, hs, dT, fresh.Phi, fresh.Gamma, msg, n))
        return 1;
    if (forced(&r->p) && force_input(&r->p, Omega_z, h, dT, fresh.L, msg, n)) return 1;
    fresh.Omega_z = Omega_z, fresh.h = h, fresh.dT = dT, fresh.valid = 1;
    *m = fresh;
    return 0;
}

static uint64_t second_stream(uint64_t seed) { return seed ^ 0x6A09E667F3BCC909ULL; }
static uint64_t third_stream(uint64_t seed) { return seed ^ 0xBB67AE8584CAA73BULL; }

int gyro_resonator_init(GyroResonator *r, const GyroResonatorParams *p, uint64_t seed,
                        const double *initial_state, char *msg, size_t n) {
    if (gyro_resonator_problems(p, msg, n)) return 1;
    memset(r, 0, sizeof *r);
    r->p = *p;
    r->seed = seed;
    gyro_rng_seed(&r->noise_rng, seed);
    gyro_rng_seed(&r->force_rng, second_stream(seed));
    gyro_rng_seed(&r->sensor_rng, third_stream(seed));
    if (initial_state) {
        memcpy(r->s, initial_state, sizeof r->s);
    } else {
        r->s[6] = r->s[8] = 1.0; /* ring tones: cos at t = 0 */
    }
    double z[N];
    memcpy(z, r->s, sizeof z);
    algebraic_pickoffs(p, z, 1); /* a zero-lag pick-off: z = q_s + the ring voltage */
    const double ring = p->c_ring * p->ring_amplitude * (r->s[6] + r->s[8]);
    const double gains[2] = {p->Px, p->Py};
    for (int i = 0; i < 2; i++) {
        const double z0 = z[4 + i] + (tau_of(p, i) > 0.0 ? 0.0 : ring);
        r->out[i] = gains[i] * z0;
    }
    if (p->noise != 0.0)
        for (int i = 0; i < 2; i++) r->out[i] += p->noise * gyro_rng_normal(&r->noise_rng);
    sense_temperature(r, 0.0);
    return 0;
}

/* s = Phi s + Gamma V */
static void linear(const GyroResonatorMaps *m, double s[N], const double V[2]) {
    double s_new[N];
    for (int i = 0; i < N; i++) {
        double acc = m->Gamma[i][0] * V[0] + m->Gamma[i][1] * V[1];
        for (int j = 0; j < N; j++) acc += m->Phi[i][j] * s[j];
        s_new[i] = acc;
    }
    memcpy(s, s_new, sizeof s_new);
}

int gyro_resonator_step(GyroResonator *r, double Vx, double Vy, double Omega_z, double h,
                        char *msg, size_t n) {
    if (gyro_resonator_maps(r, Omega_z, h, msg, n)) return 1;
    const GyroResonatorParams *p = &r->p;
    const GyroResonatorMaps *m = &r->maps;
    double noise[2] = {0.0, 0.0}, w[GYRO_RES_DRAWS] = {0};
    if (p->noise != 0.0)
        for (int i = 0; i < 2; i++) noise[i] = p->noise * gyro_rng_normal(&r->noise_rng);
    if (forced(p) || p->drive_noise > 0.0)
        for (int i = 0; i < GYRO_RES_DRAWS; i++) w[i] = gyro_rng_normal(&r->force_rng);
    double V[2] = {Vx, Vy};
    if (p->drive_noise != 0.0) V[0] += p->drive_noise * w[6], V[1] += p->drive_noise * w[7];
    double *s = r->s;
    if (!cubic(p)) {
        linear(m, s, V);
    } else {
        const double dt = h / p->cubic_substeps;
        for (int k = 0; k < p->cubic_substeps; k++) {
            linear(m, s, V);
            const double x = s[0], y = s[1];
            s[2] -= (p->k3x * (x * (x * x)) + p->k3xy * (y * (y * y))) * dt;
            s[3] -= (p->k3y * (y * (y * y)) + p->k3yx * (x * (x * x))) * dt;
            linear(m, s, V);
        }
    }
    if (forced(p))
        for (int i = 0; i < N; i++) {
            double acc = 0.0;
            for (int j = 0; j < NF; j++) acc += m->L[i][j] * w[j];
            s[i] += acc;
        }
    const double gains[2] = {p->Px, p->Py};
    const double E[2][2] = {{p->Exx, p->Exy}, {p->Eyx, p->Eyy}};
    for (int i = 0; i < 2; i++)
        r->out[i] = gains[i] * s[4 + i] + E[i][0] * V[0] + E[i][1] * V[1] + noise[i];
    r->k++;
    sense_temperature(r, h);
    return 0;
}

int gyro_resonator_restored_problem(const GyroResonator *r, const GyroResonatorParams *p,
                                    char *msg, size_t n) {
    int same = r->p.cubic_substeps == p->cubic_substeps &&
               r->p.thermal_update_steps == p->thermal_update_steps;
    for (size_t i = 0; i < N_REALS; i++) /* bitwise: -0.0 and 0.0 differ, NaN equals NaN */
        same = same && !memcmp((const char *)&r->p + REALS[i].offset,
                               (const char *)p + REALS[i].offset, sizeof(double));
    if (!same) {
        snprintf(msg, n, "the restored resonator state was saved with other parameters: set "
                         "the parameters it was saved with, or re-initialize");
        return 1;
    }
    for (int i = 0; i < N; i++)
        if (!isfinite(r->s[i])) {
            snprintf(msg, n, "the restored resonator state s[%d]=%g is not finite: restore a "
                             "state this FMU saved", i, r->s[i]);
            return 1;
        }
    if (r->k < 0) {
        snprintf(msg, n, "the restored step count %lld must be >= 0: restore a state this FMU "
                         "saved", (long long)r->k);
        return 1;
    }
    return 0;
}

size_t gyro_resonator_size(void) { return sizeof(GyroResonator); }
size_t gyro_resonator_params_size(void) { return sizeof(GyroResonatorParams); }
