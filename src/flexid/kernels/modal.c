/*
 * modal.c: the regressors of the modal state-space cost and the products it needs of them,
 * and nothing else.
 *
 *   modal_regressors(poles, u, phi, m, feedthrough, free_response[, threads])
 *   modal_normal(poles, u, target, gram, rhs, m, feedthrough, free_response[, threads])
 *   modal_residual(poles, u, target, coef, residual, sse, m, feedthrough, free_response
 *                  [, threads])
 *       For each candidate p (flexid.costs.modal.ModalCost): poles (P, 2 m + r) holds
 *       a1, a2 of each of its m modes and then its r real poles; u (N, nu) the inputs.  Its
 *       regressors, row t of phi (P, N, k), are, column by column, the states of the
 *       structure's realisation from rest (each mode and input: x(t - 1), x(t - 2) of
 *       x(t) = u_j(t) - a1 x(t - 1) - a2 x(t - 2); each real pole and input: x(t - 1) of
 *       x(t) = u_j(t) + p x(t - 1)), then with feedthrough the inputs themselves, then with
 *       free_response the free-response basis (each mode: x(t - 1) of the input-free
 *       recursion from [x(-1), x(-2)] = e1 and e2; each real pole: p^t by the recursion);
 *       k = nu (2 m + r) + nu feedthrough + (2 m + r) free_response.
 *       modal_regressors writes phi; modal_normal its normal equations, gram (P, k, k) =
 *       phi' phi and rhs (P, k, ny) = phi' target for target (N, ny); modal_residual the
 *       errors target - phi coef for coef (P, k, ny) into residual (P, N, ny) or None and
 *       their sum of squares into sse (P,).  The last two never store phi: each row is made,
 *       used and dropped.  Candidates are split between `threads` threads, one a unit; the
 *       results do not depend on it.
 *
 * All of a candidate's recursions advance together, one sample at a time: they are
 * independent, so their steps overlap in the pipeline where one recursion alone would wait
 * on each multiply-add.  They run with subnormals flushed to zero (simd.h): a fast pole's
 * free response decays through them.  gram and rhs are summed over blocks of MODAL_BLOCK
 * rows, held column by column, so that each entry is one contiguous dot product per block
 * (with an AVX2/FMA clone, SIMD_CLONES) rather than a load and a store per row.
 */
#include "modal.h"
#include "pool.h"

#define MODAL_BLOCK 64 /* rows per block of the normal equations' sums */

/* A candidate's recursions: second-order (coefficients c1, c2, states x1 = x(t - 1),
 * x2 = x(t - 2)) and first-order (pole p1, state y1); the input-driven ones first. */
typedef struct {
    double *c1, *c2, *x1, *x2, *p1, *y1, *row, *rows, *ys;
    Py_ssize_t n2, n1, driven2, driven1, feed, free0;
} modal_state;

/* The doubles of a unit's scratch: the recursions, one row, and a block of rows and
 * targets held column by column. */
static size_t modal_scratch(const modal_job *J)
{
    return (size_t)(4 * (J->m * J->nu + 2 * J->m) + 2 * (J->r * J->nu + J->r) + J->k + 1 +
                    MODAL_BLOCK * (J->k + J->ny));
}

/* The dot product of two columns of a block, b a multiple of 4 (the block is zero-padded) */
static inline double modal_dot(const double *restrict x, const double *restrict y, Py_ssize_t b)
{
#if defined(__GNUC__)
    v4d s0 = {0.0, 0.0, 0.0, 0.0}, s1 = s0;
    Py_ssize_t t = 0;
    for (; t + 8 <= b; t += 8) {
        s0 += *(const v4d *)(x + t) * *(const v4d *)(y + t);
        s1 += *(const v4d *)(x + t + 4) * *(const v4d *)(y + t + 4);
    }
    if (t < b) s0 += *(const v4d *)(x + t) * *(const v4d *)(y + t);
    s0 += s1;
    return (s0[0] + s0[1]) + (s0[2] + s0[3]);
#else
    double s = 0.0;
    for (Py_ssize_t t = 0; t < b; ++t) s += x[t] * y[t];
    return s;
#endif
}

/* gram (k, k, upper triangle) += R' R and rhs (k, ny) += R' Y for a block of b rows (a
 * multiple of 4), R column i at rows + i MODAL_BLOCK, Y column o at ys + o MODAL_BLOCK. */
SIMD_CLONES static void modal_block(const double *restrict rows, const double *restrict ys,
                                    Py_ssize_t b, Py_ssize_t k, Py_ssize_t ny,
                                    double *restrict gram, double *restrict rhs)
{
    for (Py_ssize_t i = 0; i < k; ++i) {
        const double *ri = rows + i * MODAL_BLOCK;
        for (Py_ssize_t j = i; j < k; ++j) gram[i * k + j] += modal_dot(ri, rows + j * MODAL_BLOCK, b);
        for (Py_ssize_t o = 0; o < ny; ++o) rhs[i * ny + o] += modal_dot(ri, ys + o * MODAL_BLOCK, b);
    }
}

static void modal_begin(const modal_job *J, Py_ssize_t q, double *buf, modal_state *S)
{
    const Py_ssize_t m = J->m, r = J->r, nu = J->nu;
    const int fr = J->free_response;
    S->driven2 = m * nu;
    S->driven1 = r * nu;
    S->n2 = S->driven2 + (fr ? 2 * m : 0);
    S->n1 = S->driven1 + (fr ? r : 0);
    S->c1 = buf;
    S->c2 = S->c1 + S->n2;
    S->x1 = S->c2 + S->n2;
    S->x2 = S->x1 + S->n2;
    S->p1 = S->x2 + S->n2;
    S->y1 = S->p1 + S->n1;
    S->row = S->y1 + S->n1;
    S->rows = S->row + J->k + 1;
    S->ys = S->rows + MODAL_BLOCK * J->k;
    S->feed = 2 * S->driven2 + S->driven1;
    S->free0 = S->feed + (J->feedthrough ? nu : 0);
    const double *poles = J->poles + q * (2 * m + r);
    Py_ssize_t i = 0;
    for (Py_ssize_t g = 0; g < m; ++g)
        for (Py_ssize_t j = 0; j < nu; ++j, ++i) {
            S->c1[i] = poles[2 * g];
            S->c2[i] = poles[2 * g + 1];
            S->x1[i] = S->x2[i] = 0.0;
        }
    for (Py_ssize_t g = 0; g < m && fr; ++g)
        for (int b = 0; b < 2; ++b, ++i) {
            S->c1[i] = poles[2 * g];
            S->c2[i] = poles[2 * g + 1];
            S->x1[i] = b == 0 ? 1.0 : 0.0; /* [x(-1), x(-2)] = e1, e2 */
            S->x2[i] = b == 0 ? 0.0 : 1.0;
        }
    i = 0;
    for (Py_ssize_t g = 0; g < r; ++g)
        for (Py_ssize_t j = 0; j < nu; ++j, ++i) {
            S->p1[i] = poles[2 * m + g];
            S->y1[i] = 0.0;
        }
    for (Py_ssize_t g = 0; g < r && fr; ++g, ++i) {
        S->p1[i] = poles[2 * m + g];
        S->y1[i] = 1.0;
    }
}

/* Row t of the regressors into row, and every recursion one step on. */
static inline void modal_row(const modal_job *J, modal_state *S, const double *ut,
                             double *restrict row)
{
    const Py_ssize_t nu = J->nu, d2 = S->driven2, d1 = S->driven1;
    double *restrict x1 = S->x1, *restrict x2 = S->x2, *restrict y1 = S->y1;
    const double *restrict c1 = S->c1, *restrict c2 = S->c2, *restrict p1 = S->p1;
    /* recursion g is driven by input g mod nu: the groups' recursions in input order */
    for (Py_ssize_t g0 = 0; g0 < d2; g0 += nu)
        for (Py_ssize_t j = 0, g = g0; j < nu; ++j, ++g) {
            row[2 * g] = x1[g];
            row[2 * g + 1] = x2[g];
            const double x = ut[j] - (c1[g] * x1[g] + c2[g] * x2[g]);
            x2[g] = x1[g];
            x1[g] = x;
        }
    for (Py_ssize_t g0 = 0; g0 < d1; g0 += nu)
        for (Py_ssize_t j = 0, g = g0; j < nu; ++j, ++g) {
            row[2 * d2 + g] = y1[g];
            y1[g] = ut[j] + p1[g] * y1[g];
        }
    if (J->feedthrough)
        for (Py_ssize_t j = 0; j < nu; ++j) row[S->feed + j] = ut[j];
    double *restrict free = row + S->free0;
    for (Py_ssize_t g = d2; g < S->n2; ++g) {
        free[g - d2] = x1[g];
        const double x = -(c1[g] * x1[g] + c2[g] * x2[g]);
        x2[g] = x1[g];
        x1[g] = x;
    }
    free += S->n2 - d2;
    for (Py_ssize_t g = d1; g < S->n1; ++g) {
        free[g - d1] = y1[g];
        y1[g] *= p1[g];
    }
}

static int modal_unit(const void *ctx, Py_ssize_t q, void **scratch)
{
    const modal_job *J = (const modal_job *)ctx;
    if (*scratch == NULL && (*scratch = malloc(sizeof(double) * modal_scratch(J))) == NULL)
        return -1;
    modal_state S;
    modal_begin(J, q, (double *)*scratch, &S);
    const Py_ssize_t N = J->N, nu = J->nu, ny = J->ny, k = J->k;
    double *gram = J->gram ? J->gram + q * k * k : NULL;
    double *rhs = J->rhs ? J->rhs + q * k * ny : NULL;
    const double *coef = J->coef ? J->coef + q * k * ny : NULL;
    double *res = J->residual ? J->residual + q * N * ny : NULL;
    double sse = 0.0;
    if (gram) memset(gram, 0, sizeof(double) * (size_t)(k * k));
    if (rhs) memset(rhs, 0, sizeof(double) * (size_t)(k * ny));
    FLUSH_SUBNORMALS_BEGIN;
    Py_ssize_t held = 0; /* rows of the current block */
    for (Py_ssize_t t = 0; t < N; ++t) {
        double *restrict row = J->phi ? J->phi + (q * N + t) * k : S.row;
        modal_row(J, &S, J->u + t * nu, row);
        const double *yt = J->target ? J->target + t * ny : NULL;
        if (gram) {
            for (Py_ssize_t i = 0; i < k; ++i) S.rows[i * MODAL_BLOCK + held] = row[i];
            for (Py_ssize_t o = 0; o < ny; ++o) S.ys[o * MODAL_BLOCK + held] = yt[o];
            if (++held == MODAL_BLOCK || t == N - 1) {
                const Py_ssize_t b = (held + 3) / 4 * 4; /* zero-padded to whole vectors */
                for (Py_ssize_t i = 0; i < k; ++i)
                    for (Py_ssize_t h = held; h < b; ++h) S.rows[i * MODAL_BLOCK + h] = 0.0;
                for (Py_ssize_t o = 0; o < ny; ++o)
                    for (Py_ssize_t h = held; h < b; ++h) S.ys[o * MODAL_BLOCK + h] = 0.0;
                modal_block(S.rows, S.ys, b, k, ny, gram, rhs);
                held = 0;
            }
        }
        if (coef)
            for (Py_ssize_t o = 0; o < ny; ++o) {
                double fit = 0.0;
                for (Py_ssize_t i = 0; i < k; ++i) fit += row[i] * coef[i * ny + o];
                const double e = yt[o] - fit;
                if (res) res[t * ny + o] = e;
                sse += e * e;
            }
    }
    FLUSH_SUBNORMALS_END;
    if (gram)
        for (Py_ssize_t i = 0; i < k; ++i)
            for (Py_ssize_t j = 0; j < i; ++j) gram[i * k + j] = gram[j * k + i];
    if (J->sse) J->sse[q] = sse;
    return 0;
}

int flexid_modal_run(const modal_job *J, int n_threads)
{
    return flexid_run_units(J, modal_unit, J->P, n_threads < 1 ? 1 : n_threads);
}
