/*
 * numerator.h: the fitted numerators of flexid._kernels (numerator.c), for the Python glue.
 */
#ifndef FLEXID_NUMERATOR_H
#define FLEXID_NUMERATOR_H

#include "simd.h"

#if defined(__GNUC__)
#define FIT_MAXNB 16 /* numerator terms nb of both fits */
#define VP_MAXNA 24  /* orders of A of arx_fit_shifted (BJ's C F reaches 18 at BJ(16, 2, 2, 16, 1)) */

#define FIT_ARGS                                                                              \
    const double *a, Py_ssize_t a_stride, Py_ssize_t P, Py_ssize_t na, const double *reg,     \
        Py_ssize_t T, const double *state0, const double *target, Py_ssize_t offset,          \
        double *b_out, unsigned char *ok, Py_ssize_t q, v4d *hist
typedef void (*fit_quad_fn)(FIT_ARGS);

/* arx_fit: the arrays and sizes of one call (fn: set by flexid_arx_fit) */
typedef struct {
    const double *a;
    Py_ssize_t a_stride, P, na, nb;
    const double *reg;
    Py_ssize_t T;
    const double *state0, *target;
    Py_ssize_t offset;
    double *b_out;
    unsigned char *ok;
    fit_quad_fn fn;
} fit_ctx;

/* arx_fit_shifted: the arrays and sizes of one call (rec, solve: set by
 * flexid_arx_fit_shifted) */
typedef struct vp_ctx vp_ctx;
typedef void (*vp_rec_fn)(const vp_ctx *, Py_ssize_t, v4d *, v4d *);
typedef void (*vp_solve_fn)(const vp_ctx *, Py_ssize_t, const v4d *, const v4d *, v4d *);
struct vp_ctx {
    const double *a;
    Py_ssize_t a_stride, P, na, nb, L;
    const double *reg; /* (T, nb) */
    Py_ssize_t T;
    const double *state0, *target; /* (na,), (T - offset,) */
    Py_ssize_t offset;
    double *b_out;
    unsigned char *ok;
    double *sse; /* (P,) or NULL */
    double tol;
    Py_ssize_t nfree; /* 0, or na: the free response's coefficients are unknowns too */
    /* per candidate (NULL: none): an FIR numerator d (P, nd + 1) on x, so that v is the
     * response of d/A, and targets (P, T - offset) in place of target */
    const double *d, *targets;
    Py_ssize_t d_stride, nd, t_stride;
    vp_rec_fn rec;
    vp_solve_fn solve;
};

/* The whole call on up to n_threads threads (blocks of 4 candidates); 0, or -1 out of
 * memory. */
int flexid_arx_fit(const fit_ctx *problem, int n_threads);
int flexid_arx_fit_shifted(const vp_ctx *problem, int n_threads);
#endif

#endif /* FLEXID_NUMERATOR_H */
