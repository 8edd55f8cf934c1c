/*
 * flagged.c: the fitted numerator in the orthogonal numerators' basis, and nothing else.
 *
 *   flagged_fit(a, lead, sig, target, targets, state, free, restart, tol, coef_out,
 *               sse_out, ok_out[, threads])
 *       The least-squares problem of flexid.costs.polynomial.PolynomialCost.b_regressors for
 *       one input, solved as _least_squares_rows solves it (flexid.kernels.flagged_fit): for
 *       each candidate, a (P, n) the a_1 .. a_n of its den (1 <= n <= 24, stable), lead
 *       (P, nl) a numerator on the input (D of a one-step predictor; None: 1), sig (N,) the
 *       input delayed by nk, target (K,) shared or targets (P, K) per candidate (the other
 *       None), state (n,) past outputs whose free response the shared target loses (or
 *       None), free 1 for the rule "estimate" (the n free responses are unknowns too),
 *       restart 1 for the rule "measured".  Writes coef_out (P, nb), 1 <= nb <= 16, the
 *       fitted B in powers of q^-1, sse_out (P,) and ok_out (P,) uint8, 0 where the
 *       Cholesky factorisation broke down, the refinement still moved after two steps, or a
 *       result is not finite (the caller solves those rows another way).
 *
 * The regressors are those of the NumPy route, formed in fewer operations.  With w = lead u
 * (t - nk) and start = N - K, regressor m is, over t = start .. N - 1,
 *
 *   restart 0:  g_m = P_m(q) x, x = w / den from rest at t = 0: one recursion of 1/den and
 *               the P_m(q) x of it, where the route of one recursion per coefficient runs
 *               nb recursions of P_m w / den (the same signals: 1/den and P_m commute);
 *   restart 1:  the response of 1/den to P_m(q) w from rest at t = start (each regressor's
 *               own recursion: their transients differ, so they are no filters of one
 *               signal);
 *
 * and with free the free responses from t = start are n more, the Q_k(q) h of the impulse
 * response h of 1/den from t = start (where the route of one recursion per coefficient runs
 * n recursions of Q_k(q) delta / den).  The P_m and Q_k are den's reversed step-down
 * polynomials, so all of them are formed by one lattice (Levinson's step-up, fl_lattice:
 * two multiply-adds a regressor and sample, where the FIR filters of their coefficients
 * take m + 1); the reflection coefficients come from den's step-down here, as
 * orthogonal_numerators computes them (all zero, the plain shifts, where it breaks down),
 * and B = sum_m c_m P_m from their step-up, the polynomials the lattice applied.  Both
 * ways of forming a regressor carry rounding errors of the same size, a few eps times the
 * gain of 1/den (measured against long double: 1e-10 relative, either way, next to the
 * poles of benchmarks/bench_structures.py).  With state (restart, shared target) the
 * target is less the free response of 1/den from those past outputs, formed here.
 *
 * Then, per block of candidates (one per SIMD lane; one copy per instruction set, simd.h)
 * with subnormals flushed to zero: the Gram matrix of the regressors and their products with
 * the target (one sum per entry, in the order of t, in register tiles over chunks of the
 * record), the normal equations of the column-scaled regressors by Cholesky, and up to two
 * steps of iterative refinement with the residual formed from the regressors, a lane
 * stopping where its step is below tol relative (_least_squares_rows' criterion; a lane that
 * still moves after two steps is flagged, as _least_squares_rows solves such a row again by
 * SVD); the sum of squares is that of the last residual formed, corrected for the last step
 * (see fl_quad_impl).  Blocks of 4 candidates, or 8 with AVX-512 (see
 * flexid_flagged_fit); the results of a candidate depend on neither (each lane computes
 * alone) nor on the thread count.  The blocks are split between `threads` threads.
 */
#include "flagged.h"
#include "polynomial.h"
#include "pool.h"

#if defined(__GNUC__)
#define FL_PAD 32 /* zeros stored before each signal (>= nb - 1 + nl - 1 and >= n - 1) */
#define FL_MAXR (FL_MAXNB + FL_MAXN) /* regressors nb + n */
#define FL_CHUNK 64                  /* samples of a chunk of the Gram matrix (fl_products) */
#define FL_SPAN 256 /* samples of the regressors formed at a time (a multiple of FL_CHUNK; at
                     * order 16 and 8 lanes 33 rows of it are 0.5 MB, in the second-level
                     * cache) */

/* The kernel in blocks of 4 (the baseline and AVX2 copies) and of 8 (AVX-512) */
#define FLV v4d
#define FLW 4
#define FLN(x) x##_4
#include "flagged_lanes.h"
#undef FLV
#undef FLW
#undef FLN
#if defined(SIMD_X86)
typedef double v8d __attribute__((vector_size(64), aligned(8)));
#define FLV v8d
#define FLW 8
#define FLN(x) x##_8
#include "flagged_lanes.h"
#undef FLV
#undef FLW
#undef FLN
#endif

/* DEF(n, isa, TGT, ...) for the orders 1 .. 24 */
#define FL_ORDERS24(DEF, ...)                                                                 \
    DEF(1, __VA_ARGS__) DEF(2, __VA_ARGS__) DEF(3, __VA_ARGS__) DEF(4, __VA_ARGS__)           \
    DEF(5, __VA_ARGS__) DEF(6, __VA_ARGS__) DEF(7, __VA_ARGS__) DEF(8, __VA_ARGS__)           \
    DEF(9, __VA_ARGS__) DEF(10, __VA_ARGS__) DEF(11, __VA_ARGS__) DEF(12, __VA_ARGS__)        \
    DEF(13, __VA_ARGS__) DEF(14, __VA_ARGS__) DEF(15, __VA_ARGS__) DEF(16, __VA_ARGS__)       \
    DEF(17, __VA_ARGS__) DEF(18, __VA_ARGS__) DEF(19, __VA_ARGS__) DEF(20, __VA_ARGS__)       \
    DEF(21, __VA_ARGS__) DEF(22, __VA_ARGS__) DEF(23, __VA_ARGS__) DEF(24, __VA_ARGS__)
/* the recursion of order n in a copy of width W and instruction set isa */
#define FL_REC(n, isa, TGT, W, V)                                                             \
    TGT static void fl_rec_##isa##n(const V *A, const V *f, V *y, Py_ssize_t len, V *Z0)     \
    {                                                                                         \
        fl_rec_impl_##W(A, f, y, len, Z0, n);                                                 \
    }
/* the block of a copy, with its table of recursions */
#define FL_QUAD(isa, TGT, W, V, wide)                                                         \
    FL_ORDERS24(FL_REC, isa, TGT, W, V)                                                       \
    static const fl_rec_fn_##W fl_recs_##isa[FL_MAXN + 1] = SIMD_TABLE24(fl_rec_##isa);      \
    TGT static void fl_quad_##isa(const fl_ctx *c, Py_ssize_t q, void *buf)                  \
    {                                                                                         \
        fl_quad_impl_##W(c, q, (V *)buf, wide, fl_recs_##isa[c->n]);                          \
    }
FL_QUAD(g, SIMD_G, 4, v4d, 0)
#if defined(SIMD_X86)
FL_QUAD(v3_, SIMD_V3, 4, v4d, 0)
FL_QUAD(v4_, SIMD_V4, 8, v8d, 1)
#endif

typedef void (*fl_quad_fn)(const fl_ctx *, Py_ssize_t, void *);
typedef struct {
    fl_ctx c;
    fl_quad_fn fn;
    int width; /* candidates per block */
} fl_job;

/* Block u; the scratch (zeros first: the padding before each signal) holds its signals, in
 * vectors of the block's width */
static int fl_unit(const void *ctx, Py_ssize_t u, void **scratch)
{
    const fl_job *j = (const fl_job *)ctx;
    const fl_ctx *c = &j->c;
    const Py_ssize_t nr = c->nb + (c->free_state ? c->n : 0);
    if (!*scratch) {
        const size_t count = (size_t)(2 * (FL_PAD + c->N) + FL_PAD + c->K + (nr + 1) * c->K +
                                      c->K + (nr + 1) * (nr + 1) + nr * nr + FL_PAD +
                                      c->N + 2 * FL_SPAN);
        *scratch = calloc(count, (size_t)j->width * sizeof(double));
        if (!*scratch) return -1;
    }
    FLUSH_SUBNORMALS_BEGIN;
    j->fn(c, j->width * u, *scratch);
    FLUSH_SUBNORMALS_END;
    return 0;
}

int flexid_flagged_fit(const fl_ctx *problem, int n_threads)
{
    fl_job job;
    job.c = *problem;
    /* AVX-512: blocks of 8.  The regressors are formed and their Gram matrix summed chunk
     * by chunk, and the residual's products are added while its rows are in the cache, so a
     * block's regressors (3 MB at order 16, K = 1,500, with 8 lanes) are written once and read
     * once from further out; the rule "measured"'s nb recursions are chains of dependent steps,
     * which 8 lanes run at the cost of 4 (measured, AMD Zen 4, OE(16,16,1) next to the poles:
     * 8 lanes about 10 % faster than 4 under "estimate", level under "zero") */
    job.fn = SIMD_PICK(fl_quad_g, fl_quad_v3_, fl_quad_v4_);
    job.width = SIMD_PICK(4, 4, 8);
    return flexid_run_units(&job, fl_unit, (job.c.P + job.width - 1) / job.width, n_threads);
}
#endif
