/*
 * modal.h: the regressors of the modal state-space cost (modal.c).
 */
#ifndef FLEXID_MODAL_H
#define FLEXID_MODAL_H

#include "simd.h"

/* One job: the population's poles, the record's inputs and the regressors to write. */
typedef struct {
    const double *poles; /* (P, 2 m + r): a1, a2 of each mode, then each real pole */
    const double *u;     /* (N, nu) */
    double *phi;         /* (P, N, k) */
    Py_ssize_t P, m, r, N, nu, k;
    int feedthrough;     /* nu columns of u after the filtered ones */
    int free_response;   /* 2 m + r free-response columns last */
} modal_job;

/* modal_regressors: the whole job on up to n_threads threads; 0, or -1 out of memory. */
int flexid_modal_regressors(const modal_job *J, int n_threads);

#endif /* FLEXID_MODAL_H */
