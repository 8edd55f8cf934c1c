/*
 * twin_rotor.h: the twin rotor's RK4 of flexid._kernels (twin_rotor.c), for the Python glue.
 */
#ifndef FLEXID_TWIN_ROTOR_H
#define FLEXID_TWIN_ROTOR_H

#include "simd.h"

/* params order: I1 I2 a1 b1 a2 b2 Mg B1psi B2psi B1phi B2phi Kgy k1 k2 T11 T10 T21 T20 Tp T0
 * kc eps (eps: the Coulomb smoothing velocity) */
#define TRS_PARAMS 22

/* A twin rotor run: B rotors over S samples (see twin_rotor.c). */
typedef struct {
    const double *p;      /* (TRS_PARAMS,) shared (p_stride 0) or (B, TRS_PARAMS) */
    Py_ssize_t p_stride;
    double *x;            /* (B, 7), updated in place */
    const double *u;      /* (S, B, 2) */
    double *out;          /* (S, B, 7) or NULL */
    Py_ssize_t S, B;
    long n_sub;
    double h;
    int lock, square;
} trs_job;

/* twin_rotor_run: the whole run on up to n_threads threads (4 rotors a unit); 0, or -1. */
int flexid_twin_rotor_run(const trs_job *J, int n_threads);

#endif /* FLEXID_TWIN_ROTOR_H */
