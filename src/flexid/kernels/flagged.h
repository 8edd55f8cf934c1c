/*
 * flagged.h: the fitted numerator in the orthogonal numerators' basis of flexid._kernels
 * (flagged.c), for the Python glue.
 */
#ifndef FLEXID_FLAGGED_H
#define FLEXID_FLAGGED_H

#include "simd.h"

#if defined(__GNUC__)
#define FL_MAXN 24  /* orders n of den (BJ's C F reaches 18 at BJ(16, 2, 2, 16, 1)) */
#define FL_MAXNB 16 /* numerator terms nb */
#define FL_MAXNL 8  /* terms of the lead numerator (D: nd + 1) */

/* flagged_fit: the arrays and sizes of one call (rec: set by flexid_flagged_fit) */
typedef struct fl_ctx fl_ctx;
typedef void (*fl_rec_fn)(const v4d *A, const v4d *f, v4d *y, Py_ssize_t len, v4d *Z);
struct fl_ctx {
    const double *a;      /* (P, n), rows a_stride apart */
    const double *lead;   /* (P, nl), rows lead_stride apart, or NULL: 1 */
    const double *sig;    /* (N,): the input delayed by nk */
    const double *target; /* (K,), or NULL with targets */
    const double *targets; /* (P, K), or NULL */
    const double *state;   /* (n,): y(-1) .. y(-n) before t = N - K, the target less the free
                            * response of 1/den from them; or NULL */
    Py_ssize_t P, n, nb, nl, N, K, a_stride, lead_stride;
    int free_state; /* the n free responses from t = N - K are unknowns too (the rule
                     * "estimate") */
    int restart;    /* the regressors from rest at t = N - K (the rule "measured") */
    double tol;  /* the refinement's tolerance (polynomial._REFINE_TOL) */
    double *coef, *sse; /* (P, nb): B in powers of q^-1; (P,) */
    unsigned char *ok;  /* (P,) */
};

/* The whole call on up to n_threads threads (blocks of 4 candidates, 8 with AVX-512); 0, or
 * -1 out of memory. */
int flexid_flagged_fit(const fl_ctx *problem, int n_threads);
#endif

#endif /* FLEXID_FLAGGED_H */
