/*
 * modal.h: the regressors, normal equations and residuals of the modal state-space cost
 * (modal.c).
 */
#ifndef FLEXID_MODAL_H
#define FLEXID_MODAL_H

#include "simd.h"

/* One job: the population's poles, the record, and what to compute. */
typedef struct {
    const double *poles;  /* (P, 2 m + r): a1, a2 of each mode, then each real pole */
    const double *u;      /* (N, nu) */
    const double *target; /* (N, ny), for normal and residual */
    const double *coef;   /* (P, k, ny), for residual */
    double *phi;          /* (P, N, k): the regressors, or NULL */
    double *gram;         /* (P, k, k): phi' phi, or NULL */
    double *rhs;          /* (P, k, ny): phi' target, or NULL */
    double *residual;     /* (P, N, ny): target - phi coef, or NULL */
    double *sse;          /* (P,): its sum of squares, or NULL */
    /* modal_fit: the fit of every candidate from its normal equations (gram, rhs set) */
    const double *yy;     /* (ny,): target' target */
    double *fitted;       /* (P, k, ny): the least-squares coefficients, or NULL */
    double *used;         /* (P, k, ny): those of the realised model */
    double *x0;           /* (P, nu (2 m + r)): its initial state */
    unsigned char *ok;    /* (P,): 1, or 0 where a solve met a non-positive pivot */
    double ridge, rounding, tolerance;
    int estimate;         /* fit the shared initial state (free_response) */
    Py_ssize_t P, m, r, N, nu, ny, k;
    int feedthrough;   /* nu columns of u after the filtered ones */
    int free_response; /* 2 m + r free-response columns last */
} modal_job;

/* modal_regressors, modal_normal, modal_residual, modal_fit: the job (what its non-NULL outputs ask
 * for) on up to n_threads threads; 0, or -1 out of memory. */
int flexid_modal_run(const modal_job *J, int n_threads);

#endif /* FLEXID_MODAL_H */
