/*
 * polynomial.c: the plain polynomial operations on populations, one polynomial per row,
 * scalar code compiled for the baseline (no target copies, so no contracted multiply-adds:
 * every product is rounded before it is added, as in NumPy).
 *
 *   schur_cohn(a, out)
 *       Strict stability of monic denominators z^n + a_1 z^(n-1) + ... + a_n, one row of
 *       the float64 array a (P, n) per candidate (rows contiguous, some stride apart), by the
 *       Schur-Cohn step-down recursion; writes 1/0 into the uint8 array out (P,).
 *
 *   poly_mul(p, q, out)
 *       Row-wise polynomial products out[r] = p[r] * q[r]: p (P, a) and q (P, b) with rows
 *       some stride apart, out (P, a + b - 1) C-contiguous; each coefficient summed over the
 *       shorter factor's coefficients in order, as flexid.costs.polynomial.poly_mul_rows's
 *       NumPy route does (without contracted multiply-adds on x86-64: bit for bit).
 */
#include "polynomial.h"

int flexid_reflection(const double *a, Py_ssize_t n, double *c, double *k)
{
    for (Py_ssize_t j = 0; j < n; ++j) {
        if (!isfinite(a[j])) return 0;
        c[j] = a[j];
    }
    for (Py_ssize_t m = n; m > 0; --m) {
        const double km = c[m - 1];
        if (!(fabs(km) < 1.0)) return 0;
        if (k) k[m - 1] = km;
        const double d = 1.0 - km * km;
        Py_ssize_t i = 0, j = m - 2;
        for (; i < j; ++i, --j) {
            const double lo = c[i], hi = c[j];
            c[i] = (lo - km * hi) / d;
            c[j] = (hi - km * lo) / d;
        }
        if (i == j) c[i] = (c[i] - km * c[i]) / d;
    }
    return 1;
}

static void schur_cohn_rows(const double *a, Py_ssize_t stride, Py_ssize_t P, Py_ssize_t n,
                            unsigned char *out, double *c)
{
    for (Py_ssize_t p = 0; p < P; ++p)
        out[p] = (unsigned char)flexid_reflection(a + p * stride, n, c, NULL);
}

int flexid_schur_cohn(const double *a, Py_ssize_t stride, Py_ssize_t P, Py_ssize_t n,
                      unsigned char *out)
{
    double *c = (double *)malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
    if (!c) return -1;
    schur_cohn_rows(a, stride, P, n, out, c);
    free(c);
    return 0;
}

void flexid_poly_mul(const double *p, Py_ssize_t ps, Py_ssize_t a, const double *q,
                     Py_ssize_t qs, Py_ssize_t b, Py_ssize_t P, double *out)
{
    const int swap = b > a; /* the loop runs over the shorter factor's coefficients */
    if (swap) {
        const double *t = p;
        p = q;
        q = t;
        Py_ssize_t u = ps;
        ps = qs;
        qs = u;
        u = a;
        a = b;
        b = u;
    }
    const Py_ssize_t w = a + b - 1;
    for (Py_ssize_t r = 0; r < P; ++r) {
        const double *pr = p + r * ps, *qr = q + r * qs;
        double *o = out + r * w;
        for (Py_ssize_t k = 0; k < w; ++k) o[k] = 0.0;
        for (Py_ssize_t i = 0; i < b; ++i) {
            const double qi = qr[i];
            for (Py_ssize_t j = 0; j < a; ++j) o[i + j] += qi * pr[j];
        }
    }
}
