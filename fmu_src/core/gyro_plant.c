#include "gyro_plant.h"

#include "gyro_text.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

void gyro_system_matrix(const GyroParams *p, double Omega_z, double A[4][4]) {
    memset(A, 0, 16 * sizeof(double));
    A[0][1] = 1.0;
    A[1][0] = -p->kxx;
    A[1][1] = -p->dxx;
    A[1][2] = -p->kxy;
    A[1][3] = 2.0 * Omega_z - p->dxy;
    A[2][3] = 1.0;
    A[3][0] = -p->kxy;
    A[3][1] = -p->dxy - 2.0 * Omega_z;
    A[3][2] = -p->kyy;
    A[3][3] = -p->dyy;
}

/* Top 4 rows E of expm([[M], [0]]) for the 4x6 top block M of a Van Loan matrix: scale
 * by 2^-s so that ||M 2^-s||_inf <= 0.5 (exact), Taylor terms until the next is below
 * 1e-17 of the sum, then s squarings ([[P, G], [0, I]]^2 = [[P P, P G + G], [0, I]]). */
static void expm_held(const double M[4][6], double E[4][6]) {
    double norm = 0.0;
    for (int i = 0; i < 4; i++) {
        double r = 0.0;
        for (int j = 0; j < 6; j++) r += fabs(M[i][j]);
        norm = norm > r ? norm : r;
    }
    int s = 0;
    double scale = 1.0;
    while (norm * scale > 0.5) {
        scale *= 0.5;
        s++;
    }
    double Ms[4][6], T[4][6], Tn[4][6];
    for (int i = 0; i < 4; i++) {
        for (int j = 0; j < 6; j++) {
            Ms[i][j] = M[i][j] * scale;
            T[i][j] = Ms[i][j];
            E[i][j] = Ms[i][j];
        }
        E[i][i] += 1.0;
    }
    const double nrm = norm * scale;
    double term = nrm;
    for (int k = 2; k < 30; k++) {
        if (term < 1e-17) break;
        const double inv = 1.0 / k;
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 6; j++) {
                double acc = 0.0;
                for (int q = 0; q < 4; q++) acc += T[i][q] * Ms[q][j];
                Tn[i][j] = acc * inv;
            }
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 6; j++) {
                T[i][j] = Tn[i][j];
                E[i][j] += Tn[i][j];
            }
        term *= nrm / k;
    }
    for (int r = 0; r < s; r++) {
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 6; j++) {
                double acc = 0.0;
                for (int q = 0; q < 4; q++) acc += E[i][q] * E[q][j];
                Tn[i][j] = acc + (j >= 4 ? E[i][j] : 0.0);
            }
        memcpy(E, Tn, sizeof Tn);
    }
}

void gyro_held_input_maps(const GyroParams *p, double Omega_z, double h,
                          double Phi[4][4], double Gamma[4][2]) {
    double w0 = sqrt(fabs(p->kxx));
    if (w0 == 0.0) w0 = 1.0;
    const double T[4] = {1.0, 1.0 / w0, 1.0, 1.0 / w0};
    double A[4][4], M[4][6], E[4][6];
    gyro_system_matrix(p, Omega_z, A);
    for (int i = 0; i < 4; i++) {
        for (int j = 0; j < 4; j++) M[i][j] = A[i][j] * T[i] / T[j] * h;
        M[i][4] = 0.0;
        M[i][5] = 0.0;
    }
    M[1][4] = T[1] / p->m * h;
    M[3][5] = T[3] / p->m * h;
    expm_held(M, E);
    for (int i = 0; i < 4; i++) {
        for (int j = 0; j < 4; j++) Phi[i][j] = E[i][j] / T[i] * T[j];
        Gamma[i][0] = E[i][4] / T[i];
        Gamma[i][1] = E[i][5] / T[i];
    }
}

/* kxx .. m: name, label, unit, nominal (declared with GyroParams: gyro_fmu/core/structs/). */
static const GyroFieldInfo PARAMS[7] = GYRO_PARAMS_INFO;

#define add gyro_text_add

int gyro_params_problems(const GyroParams *p, char *msg, size_t n) {
    const double v[7] = {p->kxx, p->kyy, p->kxy, p->dxx, p->dyy, p->dxy, p->m};
    char text[512];
    if (n) msg[0] = '\0';
    for (int i = 0; i < 7; i++)
        if (!isfinite(v[i])) {
            snprintf(text, sizeof text, "%s=%g is not finite", PARAMS[i].name, v[i]);
            add(msg, n, text);
        }
    if (msg[0]) return 1;
    if (p->m <= 0.0) {
        char m[GYRO_REAL_TEXT];
        snprintf(text, sizeof text, "mass m=%s kg must be > 0: give the proof mass in kg",
                 gyro_real_text(p->m, m));
        add(msg, n, text);
    }
    for (int i = 0; i < 6; i++) {
        const double limit = i < 3 ? GYRO_K_MAX : GYRO_D_MAX;
        if (fabs(v[i]) > limit) {
            snprintf(text, sizeof text,
                     "%s %s=%g %s is beyond |%s| <= %g %s, the range the model integrates "
                     "accurately in double precision: give it divided by the mass (a MEMS "
                     "gyroscope has %s near %g)",
                     PARAMS[i].label, PARAMS[i].name, v[i], PARAMS[i].unit, PARAMS[i].name,
                     limit, PARAMS[i].unit, PARAMS[i].name, PARAMS[i].nominal);
            add(msg, n, text);
        } else if (i < 2 && v[i] <= 0.0) {
            snprintf(text, sizeof text,
                     "%s %s=%g %s must be > 0 (a main-axis spring is neither negative nor "
                     "absent): give the stiffness divided by the mass, e.g. from preset "
                     "'park-horowitz'", PARAMS[i].label, PARAMS[i].name, v[i], PARAMS[i].unit);
            add(msg, n, text);
        } else if ((i == 3 || i == 4) && v[i] < 0.0) {
            snprintf(text, sizeof text,
                     "%s %s=%g %s must be >= 0 (a main-axis damping cannot feed energy in): "
                     "give the damping divided by the mass", PARAMS[i].label, PARAMS[i].name,
                     v[i], PARAMS[i].unit);
            add(msg, n, text);
        }
    }
    if (msg[0]) return 1;
    /* eigenvalues of K = [[kxx, kxy], [kxy, kyy]] */
    const double mean = 0.5 * (p->kxx + p->kyy), half = 0.5 * (p->kxx - p->kyy);
    const double rad = sqrt(half * half + p->kxy * p->kxy);
    const double e0 = mean - rad, e1 = mean + rad;
    if (e0 <= 0.0) {
        const double prod = p->kxx * p->kyy;
        snprintf(text, sizeof text,
                 "stiffness matrix K=[[kxx, kxy], [kxy, kyy]] is not positive definite: "
                 "eigenvalues %.4g and %.4g 1/s^2 (needs |kxy| < sqrt(kxx*kyy) = %.4g); the "
                 "plant would diverge. Use preset 'park-horowitz' or 'patent-table1-corrected',"
                 " or override kxy", e0, e1, sqrt(prod > 0.0 ? prod : 0.0));
        add(msg, n, text);
    }
    return msg[0] ? 1 : 0;
}

/* Complex arithmetic on pairs, for the quartic's roots (no complex.h: MSVC lacks it). */
typedef struct {
    double re, im;
} Cx;
static Cx cmul(Cx a, Cx b) { return (Cx){a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re}; }
static Cx csub(Cx a, Cx b) { return (Cx){a.re - b.re, a.im - b.im}; }
static Cx cdiv(Cx a, Cx b) {
    const double d = b.re * b.re + b.im * b.im;
    return (Cx){(a.re * b.re + a.im * b.im) / d, (a.im * b.re - a.re * b.im) / d};
}

double gyro_max_growth_rate(const GyroParams *p, double Omega_z) {
    /* det [[s^2 + dxx s + kxx, (dxy - 2 W) s + kxy], [(dxy + 2 W) s + kxy,
     * s^2 + dyy s + kyy]] in z = s / w with w = sqrt(max(kxx, kyy)) (monic quartic). */
    const double W = Omega_z;
    double w = sqrt(fmax(fabs(p->kxx), fabs(p->kyy)));
    if (!(w > 0.0)) w = 1.0;
    const double a = p->dxx / w, b = p->kxx / (w * w), c = p->dyy / w, d = p->kyy / (w * w);
    const double e = (p->dxy - 2.0 * W) / w, f = (p->dxy + 2.0 * W) / w,
                 g = p->kxy / (w * w);
    /* (z^2 + a z + b)(z^2 + c z + d) - (e z + g)(f z + g) */
    const double c3 = a + c, c2 = b + d + a * c - e * f, c1 = a * d + b * c - g * (e + f),
                 c0 = b * d - g * g;
    Cx z[4] = {{0.4, 0.9}, {-0.65, 0.72}, {0.3, -1.1}, {-0.8, -0.5}};
    for (int it = 0; it < 500; it++) {
        double change = 0.0;
        for (int i = 0; i < 4; i++) {
            Cx num = {1.0, 0.0};
            num = cmul(num, z[i]);
            num.re += c3;
            num = cmul(num, z[i]);
            num.re += c2;
            num = cmul(num, z[i]);
            num.re += c1;
            num = cmul(num, z[i]);
            num.re += c0;
            Cx den = {1.0, 0.0};
            for (int j = 0; j < 4; j++)
                if (j != i) den = cmul(den, csub(z[i], z[j]));
            if (den.re == 0.0 && den.im == 0.0) den.re = 1e-300;
            const Cx delta = cdiv(num, den);
            z[i] = csub(z[i], delta);
            change = fmax(change, fabs(delta.re) + fabs(delta.im));
        }
        if (change < 1e-15) break;
    }
    double growth = -INFINITY;
    for (int i = 0; i < 4; i++) growth = fmax(growth, z[i].re * w);
    return growth;
}

double gyro_rate_limit(const GyroParams *p) {
    const double k = p->kxx < p->kyy ? p->kxx : p->kyy;
    return k > 0.0 ? sqrt(k) : 0.0;
}

int gyro_rate_problem(const GyroParams *p, const char *name, double Omega_z, char *msg,
                      size_t n) {
    const double limit = gyro_rate_limit(p);
    if (n) msg[0] = '\0';
    if (isfinite(Omega_z) && fabs(Omega_z) < limit) return 0;
    char value[GYRO_REAL_TEXT];
    snprintf(msg, n, "%s=%s rad/s is not a rate this gyro can sense: give |%s| below the "
             "slowest axis's angular frequency sqrt(min(kxx, kyy)) = %.4g rad/s (2 pi x "
             "%.4g Hz)", name, gyro_real_text(Omega_z, value), name, limit,
             limit / 6.283185307179586);
    return 1;
}

int gyro_params_warning(const GyroParams *p, char *msg, size_t n) {
    const double growth = gyro_max_growth_rate(p, 0.0);
    if (n) msg[0] = '\0';
    if (!(growth > 0.0)) return 0;
    const double mean = 0.5 * (p->dxx + p->dyy), half = 0.5 * (p->dxx - p->dyy);
    const double rad = sqrt(half * half + p->dxy * p->dxy);
    const double x = growth * 0.1;
    char gain[64];
    if (x < 700.0)
        snprintf(gain, sizeof gain, "%.3f", exp(x));
    else
        snprintf(gain, sizeof gain, "e^%.3g", x);
    snprintf(msg, n,
             "damping matrix D=[[dxx, dxy], [dxy, dyy]] is indefinite (eigenvalues %.4g and "
             "%.4g 1/s): one mode grows at %.3g 1/s (amplitude x%s per 100 ms)",
             mean - rad, mean + rad, growth, gain);
    return 1;
}

static void draw_noise(GyroPlant *g) {
    const double *sd = &g->sigma.x;
    const int noisy = sd[0] != 0.0 || sd[1] != 0.0 || sd[2] != 0.0 || sd[3] != 0.0;
    for (int i = 0; i < 4; i++) g->noise[i] = noisy ? gyro_rng_normal(&g->rng) * sd[i] : 0.0;
}

void gyro_plant_init(GyroPlant *g, const GyroParams *p, const GyroPickoffNoise *sigma,
                     uint64_t seed, const GyroState *s0) {
    memset(g, 0, sizeof *g);
    g->p = *p;
    if (sigma) g->sigma = *sigma;
    if (s0) g->s = *s0;
    gyro_rng_seed(&g->rng, seed);
    draw_noise(g);
}

void gyro_plant_step(GyroPlant *g, double ux, double uy, double Omega_z, double h) {
    GyroHeldMaps *mp = &g->maps;
    if (!mp->valid || mp->Omega_z != Omega_z || mp->h != h) {
        gyro_held_input_maps(&g->p, Omega_z, h, mp->Phi, mp->Gamma);
        mp->Omega_z = Omega_z;
        mp->h = h;
        mp->valid = 1;
    }
    const double s[4] = {g->s.x, g->s.vx, g->s.y, g->s.vy};
    double out[4];
    for (int i = 0; i < 4; i++) {
        double acc = 0.0;
        for (int j = 0; j < 4; j++) acc += mp->Phi[i][j] * s[j];
        out[i] = acc + (mp->Gamma[i][0] * ux + mp->Gamma[i][1] * uy);
    }
    g->s = (GyroState){out[0], out[1], out[2], out[3]};
    g->ux = ux;
    g->uy = uy;
    g->Omega_z = Omega_z;
    draw_noise(g);
}

void gyro_plant_outputs(const GyroPlant *g, double out[6]) {
    const GyroParams *p = &g->p;
    const GyroState *s = &g->s;
    out[0] = s->x + g->noise[0];
    out[1] = s->vx + g->noise[1];
    out[2] = s->y + g->noise[2];
    out[3] = s->vy + g->noise[3];
    /* eqs. 3-4: rows 1 and 3 of A, plus the input over m */
    const double ax = -p->kxx * s->x - p->dxx * s->vx - p->kxy * s->y +
                      (2.0 * g->Omega_z - p->dxy) * s->vy;
    const double ay = -p->kxy * s->x + (-p->dxy - 2.0 * g->Omega_z) * s->vx - p->kyy * s->y -
                      p->dyy * s->vy;
    out[4] = ax + g->ux / p->m;
    out[5] = ay + g->uy / p->m;
}

int gyro_plant_restored_problem(GyroPlant *g, const GyroParams *p,
                                const GyroPickoffNoise *sigma, char *msg, size_t n) {
    if (n) msg[0] = '\0';
    if (memcmp(&g->p, p, sizeof *p) != 0 || memcmp(&g->sigma, sigma, sizeof *sigma) != 0) {
        snprintf(msg, n, "the saved plant has other parameters or noise than the variables "
                 "(kxx %g against %g): the state belongs to another plant", g->p.kxx, p->kxx);
        return 1;
    }
    const double v[11] = {g->s.x, g->s.vx, g->s.y, g->s.vy, g->ux, g->uy, g->Omega_z,
                          g->noise[0], g->noise[1], g->noise[2], g->noise[3]};
    static const char *const names[11] = {"x", "vx", "y", "vy", "ux", "uy", "Omega_z",
                                          "noise[0]", "noise[1]", "noise[2]", "noise[3]"};
    for (int i = 0; i < 11; i++)
        if (!isfinite(v[i])) {
            snprintf(msg, n, "the saved plant's %s=%g is not finite", names[i], v[i]);
            return 1;
        }
    if (g->rng.has_spare != 0 && g->rng.has_spare != 1) {
        snprintf(msg, n, "the saved noise generator is damaged (has_spare=%d)",
                 (int)g->rng.has_spare);
        return 1;
    }
    g->maps.valid = 0;
    return 0;
}

size_t gyro_plant_size(void) { return sizeof(GyroPlant); }
