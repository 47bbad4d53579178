/* The drive's information on the rate: see gyro_excitation.h for the contract. */
#include "gyro_excitation.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gyro_linalg.h"
#include "gyro_plant.h"
#include "gyro_signals.h"
#include "gyro_text.h"

#define NU 8 /* the unknowns of eq. 7: Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m */

/* The eigenvalue cut and the null-direction share of gyro_fmu.estimation.fisher (RTOL,
 * _NULL_COMPONENT): directions below RTOL^2 of the largest are not identified. */
static const double RTOL = 1e-7, NULL_COMPONENT = 1e-12;

/* One step of [s, c_i ds/dtheta_i] in the scaled coordinates T s (T = [1, 1/w0, 1, 1/w0])
 * with ux / u_ref held: s' = Phi s + G u, d_i' = Phi d_i + Phi_i s + G_i u. */
typedef struct {
    double Phi[4][4], G[4];
    double Phi_i[NU][4][4], G_i[NU][4];
    double T[4], u_ref, scale[NU];
} SensitivityMaps;

/* dA/dtheta_i and dB/dtheta_i (ux column) of eqs. 3-4 in [x, x', y, y']. */
static void derivatives(const GyroParams *p, int i, double dA[4][4], double dB[4]) {
    memset(dA, 0, 16 * sizeof(double));
    memset(dB, 0, 4 * sizeof(double));
    switch (i) {
    case 0: dA[1][3] = 2.0, dA[3][1] = -2.0; break; /* Omega_z: the Coriolis terms */
    case 1: dA[1][0] = -1.0; break;                  /* kxx */
    case 2: dA[3][2] = -1.0; break;                  /* kyy */
    case 3: dA[1][2] = dA[3][0] = -1.0; break;       /* kxy */
    case 4: dA[1][1] = -1.0; break;                  /* dxx */
    case 5: dA[3][3] = -1.0; break;                  /* dyy */
    case 6: dA[1][3] = dA[3][1] = -1.0; break;       /* dxy */
    default: dB[1] = -1.0 / (p->m * p->m); break;    /* m: ux / m */
    }
}

static void build_maps(const GyroParams *p, double Omega_z, double h, SensitivityMaps *S) {
    const double w0 = sqrt(fabs(p->kxx)) > 0.0 ? sqrt(fabs(p->kxx)) : 1.0;
    const double T[4] = {1.0, 1.0 / w0, 1.0, 1.0 / w0};
    const double value[NU] = {Omega_z, p->kxx, p->kyy, p->kxy, p->dxx, p->dyy, p->dxy, p->m};
    const double kxx = fabs(p->kxx) > 0.0 ? fabs(p->kxx) : 1.0;
    const double fallback[NU] = {1.0, 1.0, kxx, 1e-3 * kxx, 1.0, 1.0, 1.0, 1.0};
    double A[4][4];
    gyro_system_matrix(p, Omega_z, A);
    memcpy(S->T, T, sizeof T);
    S->u_ref = fabs(p->m) * w0 * w0;
    for (int i = 0; i < NU; i++) {
        S->scale[i] = fabs(value[i]) > 0.0 ? fabs(value[i]) : fallback[i];
        double dA[4][4], dB[4], M[9][9] = {{0}}, E[9][9];
        derivatives(p, i, dA, dB);
        for (int r = 0; r < 4; r++) {
            for (int c = 0; c < 4; c++) {
                M[r][c] = M[r + 4][c + 4] = A[r][c] * T[r] / T[c] * h;
                M[r + 4][c] = S->scale[i] * dA[r][c] * T[r] / T[c] * h;
            }
            M[r + 4][8] = S->scale[i] * dB[r] * T[r] * S->u_ref * h;
        }
        M[1][8] = T[1] * S->u_ref / p->m * h; /* B: ux / m on x'' */
        gyro_expm(9, &M[0][0], &E[0][0]);
        for (int r = 0; r < 4; r++) {
            for (int c = 0; c < 4; c++) {
                S->Phi_i[i][r][c] = E[r + 4][c];
                if (i == 0) S->Phi[r][c] = E[r][c];
            }
            S->G_i[i][r] = E[r + 4][8];
            if (i == 0) S->G[r] = E[r][8];
        }
    }
}

/* Add the row r (NU) to the upper-triangular R of a QR factorization (Givens). */
static void qr_add_row(double R[NU][NU], double r[NU]) {
    for (int j = 0; j < NU; j++) {
        if (r[j] == 0.0) continue;
        const double rho = hypot(R[j][j], r[j]), c = R[j][j] / rho, s = r[j] / rho;
        for (int k = j; k < NU; k++) {
            const double a = R[j][k], b = r[k];
            R[j][k] = c * a + s * b;
            r[k] = c * b - s * a;
        }
    }
}

/* The standard deviation of the first unknown from R (J = Q R), as
 * gyro_fmu.estimation.fisher.standard_deviations does from J: the columns equilibrated,
 * then the singular values and right vectors of R by one-sided Jacobi rotations (their
 * relative accuracy does not square the conditioning, as F = J'J would); inf when the
 * first unknown has a share in a direction below RTOL of the largest. */
static double first_sigma(const double R[NU][NU]) {
    double A[NU][NU], V[NU][NU] = {{0.0}}, norm[NU];
    for (int j = 0; j < NU; j++) {
        double acc = 0.0;
        for (int i = 0; i <= j; i++) acc += R[i][j] * R[i][j];
        norm[j] = acc > 0.0 ? sqrt(acc) : 1.0;
        V[j][j] = 1.0;
    }
    for (int i = 0; i < NU; i++)
        for (int j = 0; j < NU; j++) A[i][j] = R[i][j] / norm[j];
    for (int sweep = 0; sweep < 60; sweep++) {
        int rotated = 0;
        for (int p = 0; p < NU - 1; p++)
            for (int q = p + 1; q < NU; q++) {
                double alpha = 0.0, beta = 0.0, gamma = 0.0;
                for (int i = 0; i < NU; i++) {
                    alpha += A[i][p] * A[i][p];
                    beta += A[i][q] * A[i][q];
                    gamma += A[i][p] * A[i][q];
                }
                if (!(fabs(gamma) > 1e-15 * sqrt(alpha * beta))) continue;
                rotated = 1;
                const double zeta = (beta - alpha) / (2.0 * gamma);
                const double t = (zeta >= 0.0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta));
                const double c = 1.0 / sqrt(1.0 + t * t), s = c * t;
                for (int i = 0; i < NU; i++) {
                    const double a = A[i][p], b = A[i][q], v = V[i][p], w = V[i][q];
                    A[i][p] = c * a - s * b, A[i][q] = s * a + c * b;
                    V[i][p] = c * v - s * w, V[i][q] = s * v + c * w;
                }
            }
        if (!rotated) break;
    }
    double sv[NU], top = 0.0;
    for (int j = 0; j < NU; j++) {
        double acc = 0.0;
        for (int i = 0; i < NU; i++) acc += A[i][j] * A[i][j];
        sv[j] = sqrt(acc);
        top = fmax(top, sv[j]);
    }
    if (!(top > 0.0)) return INFINITY;
    double var = 0.0, null_share = 0.0;
    for (int j = 0; j < NU; j++) {
        const double v2 = V[0][j] * V[0][j];
        if (sv[j] > RTOL * top) var += v2 / (sv[j] * sv[j]);
        else null_share += v2;
    }
    return null_share > NULL_COMPONENT ? INFINITY : sqrt(var) / norm[0];
}

/* The bound from maps already built for (p, Omega_z, h): each channel's rows of the
 * Jacobian go into their own R (their noise, one of the channel's peak over the window,
 * is known only at the end), then both, divided by their noise, into one. */
static double bound_with(const SensitivityMaps *S, const GyroTwoToneDrive *drive, double h,
                         int measured_pair, int n_samples) {
    const int rows[2] = {measured_pair == 1 ? 0 : 1, measured_pair == 1 ? 2 : 3};
    double s[4] = {0.0}, d[NU][4] = {{0.0}}, Rc[2][NU][NU] = {{{0.0}}}, peak[2] = {0.0, 0.0};
    for (int k = 0; k < n_samples; k++) {
        for (int ch = 0; ch < 2; ch++) { /* the sample at t_k, then the step to t_k+1 */
            const int r = rows[ch];
            double dz[NU];
            for (int i = 0; i < NU; i++) dz[i] = d[i][r] / S->T[r];
            peak[ch] = fmax(peak[ch], fabs(s[r] / S->T[r]));
            qr_add_row(Rc[ch], dz);
        }
        const double u = gyro_drive_ux(drive, k * h) / S->u_ref;
        double s1[4], d1[NU][4];
        for (int r = 0; r < 4; r++) {
            double acc = S->G[r] * u;
            for (int c = 0; c < 4; c++) acc += S->Phi[r][c] * s[c];
            s1[r] = acc;
        }
        for (int i = 0; i < NU; i++)
            for (int r = 0; r < 4; r++) {
                double acc = S->G_i[i][r] * u;
                for (int c = 0; c < 4; c++) acc += S->Phi[r][c] * d[i][c] + S->Phi_i[i][r][c] * s[c];
                d1[i][r] = acc;
            }
        memcpy(s, s1, sizeof s);
        memcpy(d, d1, sizeof d);
    }
    double R[NU][NU] = {{0.0}};
    for (int ch = 0; ch < 2; ch++) {
        const double std = peak[ch] > 0.0 ? peak[ch] : 1.0; /* relative noise 1 */
        for (int i = 0; i < NU; i++) {
            double row[NU];
            for (int j = 0; j < NU; j++) row[j] = Rc[ch][i][j] / std;
            qr_add_row(R, row);
        }
    }
    for (int i = 0; i < NU; i++)
        for (int j = 0; j < NU; j++)
            if (!isfinite(R[i][j])) return NAN;
    return first_sigma(R) * S->scale[0];
}

static int usable(const GyroParams *p, double Omega_z, double h, int measured_pair) {
    char text[512];
    return gyro_params_problems(p, text, sizeof text) == 0 && isfinite(Omega_z) &&
           isfinite(h) && h > 0.0 && (measured_pair == 1 || measured_pair == 2);
}

static int samples_of(double window, double h) {
    const double n = floor(window / h + 0.5);
    return n < 1.0 ? 1 : n > GYRO_EXCITATION_MAX_SAMPLES ? GYRO_EXCITATION_MAX_SAMPLES : (int)n;
}

double gyro_drive_rate_bound(const GyroParams *p, const GyroTwoToneDrive *drive,
                             double Omega_z, double h, int measured_pair, double window) {
    if (!usable(p, Omega_z, h, measured_pair) || !(isfinite(window) && window >= h))
        return NAN;
    SensitivityMaps S;
    build_maps(p, Omega_z, h, &S);
    return bound_with(&S, drive, h, measured_pair, samples_of(window, h));
}

/* f1 = a lo + b hi, f2 = c lo + d hi (gyro_excitation.h; measured on 16 random gyros over
 * 40 ms at noise 1e-4: the best beat the default 4000 + 1200 Hz by 1.5-61x on 13 of them,
 * and lost to it on both presets, by 0.65-0.79). */
static const double MODE_TONES[4][4] = {
    {0.97, 0.0, 0.0, 1.03}, {0.99, 0.0, 0.0, 1.01}, {0.9, 0.0, 0.0, 1.1}, {0.98, 0.0, 0.02, 0.98}};

static void guessed_modes(const GyroParams *p, double *lo, double *hi) {
    const double fx = sqrt(p->kxx) / (2.0 * GYRO_PI), fy = sqrt(p->kyy) / (2.0 * GYRO_PI);
    *lo = fx < fy ? fx : fy;
    *hi = fx < fy ? fy : fx;
}

double gyro_drive_information_loss(const GyroParams *guess, const GyroTwoToneDrive *drive,
                                   double Omega_z, double h, int measured_pair,
                                   GyroTwoToneDrive *proposal) {
    *proposal = *drive;
    if (!usable(guess, Omega_z, h, measured_pair)) return NAN;
    SensitivityMaps S;
    build_maps(guess, Omega_z, h, &S);
    const int n = samples_of(GYRO_EXCITATION_WINDOW, h);
    const double here = bound_with(&S, drive, h, measured_pair, n);
    double lo, hi, best = INFINITY;
    guessed_modes(guess, &lo, &hi);
    for (int j = 0; j < 4; j++) {
        const double *r = MODE_TONES[j];
        const GyroTwoToneDrive candidate = {drive->A1, r[0] * lo + r[1] * hi, drive->A2,
                                            r[2] * lo + r[3] * hi};
        if (candidate.f2 >= 0.5 / h) continue;
        const double sigma = bound_with(&S, &candidate, h, measured_pair, n);
        if (sigma < best) best = sigma, *proposal = candidate;
    }
    if (!isfinite(best)) {
        *proposal = *drive;
        return isnan(here) ? NAN : 1.0;
    }
    return here / best;
}

int gyro_drive_warning(const GyroParams *guess, const GyroTwoToneDrive *drive,
                       double Omega_z, double h, int measured_pair, char *msg, size_t n) {
    if (n) msg[0] = '\0';
    if (drive->A1 == 0.0 && drive->A2 == 0.0) return 0;
    GyroTwoToneDrive best;
    const double loss = gyro_drive_information_loss(guess, drive, Omega_z != 0.0 ? Omega_z : 1.0,
                                                    h, measured_pair, &best);
    if (!(loss > GYRO_DRIVE_LOSS_WARN)) return 0;
    const double fx = sqrt(guess->kxx) / (2.0 * GYRO_PI), fy = sqrt(guess->kyy) / (2.0 * GYRO_PI);
    snprintf(msg, n, "the drive's tones %g + %g Hz are far from the guessed modes (%.0f and "
             "%.0f Hz): the Cramer-Rao bound on Omega_z over %g ms is %.3g times what tones "
             "at %.0f + %.0f Hz give; set f1=%.0f and f2=%.0f Hz, or design the drive with "
             "`gyro-fmu design-drive`", drive->f1, drive->f2, fx, fy,
             GYRO_EXCITATION_WINDOW * 1e3, loss, best.f1, best.f2, best.f1, best.f2);
    return 1;
}
