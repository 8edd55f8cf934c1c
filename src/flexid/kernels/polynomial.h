/*
 * polynomial.h: the plain polynomial operations of flexid._kernels (polynomial.c).
 */
#ifndef FLEXID_POLYNOMIAL_H
#define FLEXID_POLYNOMIAL_H

#include "simd.h"

/* schur_cohn: out[p] = 1 where row p of a (P, n), rows stride doubles apart, is a strictly
 * stable monic denominator; 0, or -1 out of memory. */
int flexid_schur_cohn(const double *a, Py_ssize_t stride, Py_ssize_t P, Py_ssize_t n,
                      unsigned char *out);
/* The step-down of the monic 1 + a_1 q^-1 + ... + a_n q^-n (a (n,)): its reflection
 * coefficients k_1 .. k_n into k (n,; NULL: not kept), c (n,) scratch.  1 where every
 * |k_m| < 1 (strictly stable), 0 where a coefficient is not finite or some |k_m| >= 1 (k
 * then incomplete).  Without contracted multiply-adds (this file's flags): bit for bit the
 * NumPy route's. */
int flexid_reflection(const double *a, Py_ssize_t n, double *c, double *k);
/* poly_mul: out (P, a + b - 1) the row-wise products of p (P, a) and q (P, b), rows ps and
 * qs doubles apart. */
void flexid_poly_mul(const double *p, Py_ssize_t ps, Py_ssize_t a, const double *q,
                     Py_ssize_t qs, Py_ssize_t b, Py_ssize_t P, double *out);

#endif /* FLEXID_POLYNOMIAL_H */
