/*
 * recursion.h: the autoregressive recursion of flexid._kernels (recursion.c), for the
 * Python glue and for the numerator fit's sums of squares at its solution.
 */
#ifndef FLEXID_RECURSION_H
#define FLEXID_RECURSION_H

#include "simd.h"

#if defined(__GNUC__)
#define AR_MAXNA 16  /* orders whose state is held in registers (the numerator fits) */
#define AR_MAXREC 24 /* orders of ar_run/arx_run's block path (above 16: BJ's C F) */
#define AR_MAXNB 64  /* input terms computed in the kernel (more: the caller's GEMM) */
#define AR_UNIT 4    /* candidates per unit of work */
#else
#define AR_MAXNA 0
#define AR_MAXREC 0
#define AR_MAXNB 0
#define AR_UNIT 1
#endif

/* One recursion job: the population's arrays and sizes.  f(t) is forced[p, t] when forced is
 * given, else sum_j b[p, j] reg[t, j] (the input part computed here, from the regressor rows
 * shared by every candidate). */
typedef struct {
    const double *a;      /* (P, na), rows a_stride doubles apart */
    const double *forced; /* (P, K) or NULL */
    const double *b;      /* (P, nb), rows b_stride apart, with reg, when forced is NULL */
    const double *reg;    /* (K, nb) */
    const double *state;  /* [y(-1), ..., y(-na)] per candidate (stride state_stride) */
    Py_ssize_t state_stride;
    const double *target; /* (K - first,) or NULL */
    double *y;            /* (P, K) or NULL */
    double *sse;          /* (P,) or NULL: sum over t >= first of (target(t - first) - y(t))^2 */
    Py_ssize_t P, na, nb, K, a_stride, b_stride, first;
} ar_job;

/* ar_run and arx_run: the whole job on up to n_threads threads; 0, or -1 out of memory. */
int flexid_ar_run(const ar_job *J, int n_threads);

#if defined(__GNUC__)
/* The block of 4 candidates at q, order na (1 .. AR_MAXREC), of the instruction set in use */
typedef void (*ar_quad_fn)(const ar_job *, Py_ssize_t);
ar_quad_fn flexid_ar_quad(Py_ssize_t na);
#endif

#endif /* FLEXID_RECURSION_H */
