/*
 * initial_state.h: the estimated initial state of flexid._kernels (initial_state.c), for
 * the Python glue.
 */
#ifndef FLEXID_INITIAL_STATE_H
#define FLEXID_INITIAL_STATE_H

#include "simd.h"

#if defined(__GNUC__)
#define FREE_MAXN 24 /* orders n of den */
#define FREE_MAXNB 64 /* input terms nb */

/* free_fit: the arrays and sizes of one call */
typedef struct {
    const double *a, *num, *reg, *target, *basis, *energies;
    Py_ssize_t P, n, nb, K, L, num_stride;
    double *errors, *sse, *coef;
    double cancel;      /* see initial_state.c */
    const double *first, *noise; /* the cascade (see initial_state.c), or NULL */
    const Py_ssize_t *order;     /* the rows in the order of the blocks, or NULL: 0 .. P-1 */
} free_job;

/* The whole call on up to n_threads threads (blocks of 4 candidates, in the order of a decay
 * probe; J->order is not read, the run sets its own); 0, or -1 out of memory. */
int flexid_free_fit(const free_job *J, int n_threads);
#endif

#endif /* FLEXID_INITIAL_STATE_H */
