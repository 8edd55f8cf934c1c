/*
 * modal.c: the regressors of the modal state-space cost, and nothing else.
 *
 *   modal_regressors(poles, u, phi, m, feedthrough, free_response[, threads])
 *       For each candidate p (flexid.costs.modal.ModalCost): poles (P, 2 m + r) holds
 *       a1, a2 of each of its m modes and then its r real poles; u (N, nu) the inputs;
 *       phi (P, N, k) receives, column by column, the states of the structure's
 *       realisation from rest (each mode and input: x(t - 1), x(t - 2) of
 *       x(t) = u_j(t) - a1 x(t - 1) - a2 x(t - 2); each real pole and input: x(t - 1) of
 *       x(t) = u_j(t) + p x(t - 1)), then with feedthrough the inputs themselves, then with
 *       free_response the free-response basis (each mode: x(t - 1) of the input-free
 *       recursion from [x(-1), x(-2)] = e1 and e2; each real pole: p^t by the recursion).
 *       k must be nu (2 m + r) + nu feedthrough + (2 m + r) free_response.  Candidates are
 *       split between `threads` threads, one a unit; the results do not depend on it.
 *
 * All of a candidate's recursions advance together, one sample at a time: they are
 * independent, so their steps overlap in the pipeline where one recursion alone would wait
 * on each multiply-add, and each sample's row of phi is written whole.  They run with
 * subnormals flushed to zero (simd.h): a fast pole's free response decays through them.
 */
#include "modal.h"
#include "pool.h"

/* One candidate (its scratch: the recursions' coefficients and states). */
static int modal_unit(const void *ctx, Py_ssize_t q, void **scratch)
{
    const modal_job *J = (const modal_job *)ctx;
    const Py_ssize_t N = J->N, nu = J->nu, k = J->k, m = J->m, r = J->r;
    const Py_ssize_t n2 = m * nu + (J->free_response ? 2 * m : 0); /* second-order ones */
    const Py_ssize_t n1 = r * nu + (J->free_response ? r : 0);     /* first-order ones */
    if (*scratch == NULL) {
        *scratch = malloc(sizeof(double) * (size_t)(6 * (J->m * J->nu + 2 * J->m) +
                                                    3 * (J->r * J->nu + J->r) + 2));
        if (*scratch == NULL) return -1;
    }
    double *c1 = (double *)*scratch, *c2 = c1 + n2, *x1 = c2 + n2, *x2 = x1 + n2;
    double *p1 = x2 + n2, *y1 = p1 + n1;
    const double *poles = J->poles + q * (2 * m + r);
    /* the input-driven recursions first (mode g, input j), then the free ones */
    Py_ssize_t i = 0;
    for (Py_ssize_t g = 0; g < m; ++g)
        for (Py_ssize_t j = 0; j < nu; ++j, ++i) {
            c1[i] = poles[2 * g];
            c2[i] = poles[2 * g + 1];
            x1[i] = x2[i] = 0.0;
        }
    for (Py_ssize_t g = 0; g < m && J->free_response; ++g)
        for (int b = 0; b < 2; ++b, ++i) {
            c1[i] = poles[2 * g];
            c2[i] = poles[2 * g + 1];
            x1[i] = b == 0 ? 1.0 : 0.0; /* [x(-1), x(-2)] = e1, e2 */
            x2[i] = b == 0 ? 0.0 : 1.0;
        }
    i = 0;
    for (Py_ssize_t g = 0; g < r; ++g)
        for (Py_ssize_t j = 0; j < nu; ++j, ++i) {
            p1[i] = poles[2 * m + g];
            y1[i] = 0.0;
        }
    for (Py_ssize_t g = 0; g < r && J->free_response; ++g, ++i) {
        p1[i] = poles[2 * m + g];
        y1[i] = 1.0;
    }
    const Py_ssize_t driven2 = m * nu, driven1 = r * nu;
    const Py_ssize_t feed = 2 * driven2 + driven1, free0 = feed + (J->feedthrough ? nu : 0);
    double *row = J->phi + q * N * k;
    FLUSH_SUBNORMALS_BEGIN;
    for (Py_ssize_t t = 0; t < N; ++t, row += k) {
        const double *ut = J->u + t * nu;
        for (Py_ssize_t g = 0; g < driven2; ++g) {
            row[2 * g] = x1[g];
            row[2 * g + 1] = x2[g];
            const double x = ut[g % nu] - (c1[g] * x1[g] + c2[g] * x2[g]);
            x2[g] = x1[g];
            x1[g] = x;
        }
        for (Py_ssize_t g = 0; g < driven1; ++g) {
            row[2 * driven2 + g] = y1[g];
            y1[g] = ut[g % nu] + p1[g] * y1[g];
        }
        if (J->feedthrough)
            for (Py_ssize_t j = 0; j < nu; ++j) row[feed + j] = ut[j];
        for (Py_ssize_t g = driven2; g < n2; ++g) {
            row[free0 + g - driven2] = x1[g];
            const double x = -(c1[g] * x1[g] + c2[g] * x2[g]);
            x2[g] = x1[g];
            x1[g] = x;
        }
        for (Py_ssize_t g = driven1; g < n1; ++g) {
            row[free0 + n2 - driven2 + g - driven1] = y1[g];
            y1[g] *= p1[g];
        }
    }
    FLUSH_SUBNORMALS_END;
    return 0;
}

int flexid_modal_regressors(const modal_job *J, int n_threads)
{
    return flexid_run_units(J, modal_unit, J->P, n_threads < 1 ? 1 : n_threads);
}
