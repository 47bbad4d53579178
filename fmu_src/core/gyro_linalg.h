/* Small dense linear algebra (row-major n x n, no allocation): gyro_linalg.c. */
#ifndef GYRO_LINALG_H
#define GYRO_LINALG_H

/* Q(h) = integral over [0, h] of e^{As} Qc e^{A's} ds for an n x n A (n <= 6), row-major. */
void gyro_white_noise_covariance(int n, const double *A, const double *Qc, double h, double *Q);

/* E = e^M for an n x n row-major M (n <= 12): Higham's scaling and squaring with the
 * [13/13] Pade approximant (the method of scipy.linalg.expm for large norms). */
void gyro_expm(int n, const double *M, double *E);

/* Symmetric eigen-decomposition by cyclic Jacobi rotations: A (n x n) = U diag(w) U';
 * A is overwritten. */
void gyro_jacobi_eigen(int n, double *A, double *w, double *U);

#endif
