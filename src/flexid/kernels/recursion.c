/*
 * recursion.c: the autoregressive recursion of a population, and nothing else.
 *
 *   ar_run(a, forced, state, target, y_out, sse_out[, threads])
 *       The autoregressive recursion y(t) = f(t) - sum_i a_i y(t - i), t = 0..K-1, for
 *       every candidate: a (P, na), forced (P, K), state (P, na) holding
 *       [y(-1), ..., y(-na)] (or (na,) shared by all candidates), target (K,) or None,
 *       y_out (P, K) or None, sse_out (P,) or None (sum over t of (target - y)^2).
 *
 *   arx_run(a, b, reg, state, target, y_out, sse_out[, threads[, first]])
 *       The same with the input part computed in the kernel, f(t) = sum_j b_j reg[t, j]:
 *       b (P, nb), reg (K, nb) the input regressors of every step (shared by all
 *       candidates), so that no (P, K) array of forced terms is formed.  a and b may be
 *       column blocks of one population array (rows of contiguous values some stride
 *       apart).  With first > 0 (default 0) the recursion still runs from t = 0 but sse_out
 *       sums t >= first only, target then being (K - first,) and compared with y(first ..):
 *       a recursion started at rest before the samples that count.
 *
 * The recursion runs on blocks of 4 candidates, one per lane of a SIMD vector, in the
 * transposed direct form with its state in registers (see ar_quad_impl), the summation order
 * of the direct form; one copy per order 1 .. AR_MAXREC and instruction set (simd.h), the
 * portable one-candidate loop (ar_one) above that.  The population is split between
 * `threads` threads in blocks of 4 (pool.c), each computed as one thread would.
 */
#include "recursion.h"
#include "pool.h"

/* One candidate at a time, the direct form y(t) = f(t) - a_na y(t - na) - ... - a_1 y(t - 1)
 * summed in that order, the history in hist (na + K doubles).  The portable path, and the one
 * for orders above AR_MAXREC. */
static void ar_one(const ar_job *J, Py_ssize_t p, double *hist)
{
    const Py_ssize_t na = J->na, nb = J->nb, K = J->K;
    const double *ap = J->a + p * J->a_stride, *sp = J->state + p * J->state_stride;
    for (Py_ssize_t i = 0; i < na; ++i) hist[na - 1 - i] = sp[i];
    double s = 0.0;
    for (Py_ssize_t t = 0; t < K; ++t) {
        double acc;
        if (J->forced) {
            acc = J->forced[p * K + t];
        } else {
            const double *bp = J->b + p * J->b_stride, *rt = J->reg + t * nb;
            acc = nb ? bp[0] * rt[0] : 0.0;
            for (Py_ssize_t j = 1; j < nb; ++j) acc += bp[j] * rt[j];
        }
        for (Py_ssize_t k = na; k >= 1; --k) acc -= ap[k - 1] * hist[na + t - k];
        hist[na + t] = acc;
        if (J->target && t >= J->first) {
            const double e = J->target[t - J->first] - acc;
            s += e * e;
        }
    }
    if (J->y) memcpy(J->y + p * K, hist + na, (size_t)K * sizeof(double));
    if (J->sse) J->sse[p] = s;
}

#if defined(__GNUC__)
#define AR_CHUNK 128 /* forced terms computed per pass (4 KB: they stay in L1) */

/* Candidates q, ..., q + 3 (those below P; the other lanes run a zero model), one per lane of
 * a 4-double vector, by the transposed direct form: after step t, S[k - 1] holds f(t + k) -
 * sum_{i >= k} a_i y(t + k - i), the part of y(t + k) known so far, so that
 *
 *     y(t) = S[0],   S[k - 1] <- S[k] - a_k y(t)  (k < na),   S[na - 1] <- f(t + na) - a_na y(t).
 *
 * Each y(t) is then f(t) - a_na y(t - na) - ... - a_1 y(t - 1) summed in that order, the order
 * of ar_one (and of this kernel's earlier direct form, so its results are unchanged), but the
 * state lives in registers and a step waits for one multiply-add only (the na updates are
 * independent): the recursion runs at the machine's multiply-add throughput, not at the
 * latency of a chain of na of them.  The forced terms are computed AR_CHUNK steps at a time
 * into a small buffer (a separate pass, so that the coefficients of both passes have the
 * registers to themselves).  na is a constant in every caller; a_in_mem keeps the a_k in
 * memory (read as operands of the multiply-adds) where the vector registers cannot hold them
 * beside the state (16 registers, or orders above 16), and rounds unrolls the steps by na
 * (where 32 registers hold the state unspilled). */
/* In AR_BLOCK_IMPL: f(c0), ..., f(c1 - 1) into fbuf[0 .. c1 - c0); each f(t) = b_1 r_1 + ... +
 * b_nb r_nb in that order, 8 steps at a time so that each b_j is loaded once for 8 products */
#define AR_FILL(c0, c1)                                                                       \
    do {                                                                                      \
        if (forced) {                                                                         \
            for (Py_ssize_t t_ = (c0); t_ < (c1); ++t_) {                                     \
                __typeof__(zero) v_ = zero;                                                   \
                for (Py_ssize_t l_ = 0; l_ < w; ++l_) v_[l_] = forced[l_ * K + t_];           \
                fbuf[t_ - (c0)] = v_;                                                         \
            }                                                                                 \
        } else if (nb == 0) {                                                                 \
            for (Py_ssize_t t_ = (c0); t_ < (c1); ++t_) fbuf[t_ - (c0)] = zero;               \
        } else {                                                                              \
            Py_ssize_t t_ = (c0);                                                             \
            for (; t_ + 8 <= (c1); t_ += 8) {                                                 \
                const double *r_ = reg + t_ * nb;                                             \
                __typeof__(zero) o_[8];                                                       \
                for (int i_ = 0; i_ < 8; ++i_) o_[i_] = Bv[0] * r_[i_ * nb];                  \
                for (Py_ssize_t j_ = 1; j_ < nb; ++j_) {                                      \
                    const __typeof__(zero) bj_ = Bv[j_];                                      \
                    for (int i_ = 0; i_ < 8; ++i_) o_[i_] += bj_ * r_[i_ * nb + j_];          \
                }                                                                             \
                for (int i_ = 0; i_ < 8; ++i_) fbuf[t_ - (c0) + i_] = o_[i_];                 \
            }                                                                                 \
            for (; t_ < (c1); ++t_) {                                                         \
                const double *r_ = reg + t_ * nb;                                             \
                __typeof__(zero) o_ = Bv[0] * r_[0];                                          \
                for (Py_ssize_t j_ = 1; j_ < nb; ++j_) o_ += Bv[j_] * r_[j_];                 \
                fbuf[t_ - (c0)] = o_;                                                         \
            }                                                                                 \
        }                                                                                     \
    } while (0)

#define AR_BLOCK_IMPL(NAME, VEC, NL)                                                          \
static inline __attribute__((always_inline)) void                                              \
NAME(const ar_job *J, Py_ssize_t q, const int na, const int a_in_mem, const int rounds)        \
{                                                                                              \
    const Py_ssize_t K = J->K, nb = J->nb, w = (J->P - q < NL) ? J->P - q : NL;                \
    const double *forced = J->forced ? J->forced + q * K : NULL, *reg = J->reg;                \
    const double *target = J->target;                                                          \
    const Py_ssize_t first = J->first;                                                         \
    double *y = J->y ? J->y + q * K : NULL;                                                    \
    VEC A[AR_MAXREC], S[AR_MAXREC], Y[AR_MAXREC], Bv[AR_MAXNB];                                \
    VEC fbuf[AR_CHUNK];                                                                        \
    VEC zero = {0};                                                                            \
    for (int i = 0; i < na; ++i) A[i] = Y[i] = zero;                                           \
    for (Py_ssize_t j = 0; j < nb && !forced; ++j) Bv[j] = zero;                               \
    for (Py_ssize_t l = 0; l < w; ++l) {                                                       \
        const double *ap = J->a + (q + l) * J->a_stride, *sp = J->state + (q + l) * J->state_stride; \
        for (int i = 0; i < na; ++i) {                                                         \
            A[i][l] = ap[i];                                                                   \
            Y[i][l] = sp[i]; /* y(-1 - i) */                                                   \
        }                                                                                      \
        for (Py_ssize_t j = 0; j < nb && !forced; ++j) Bv[j][l] = J->b[(q + l) * J->b_stride + j]; \
    }                                                                                          \
    /* the state before t = 0: S[k - 1] = f(k - 1) - sum_{i = na..k} a_i y(k - 1 - i) */       \
    const Py_ssize_t n0 = na < K ? na : K;                                                     \
    AR_FILL(0, n0);                                                                            \
    for (int k = 1; k <= na; ++k) {                                                            \
        VEC acc = k - 1 < K ? fbuf[k - 1] : zero;                                              \
        for (int i = na; i >= k; --i) acc -= A[i - 1] * Y[i - k]; /* y(k - 1 - i) */           \
        S[k - 1] = acc;                                                                        \
    }                                                                                          \
    VEC s = zero;                                                                              \
    /* steps t = c0 - na .. c1 - na - 1 take f(t + na) from the chunk [c0, c1); the last na    \
     * steps feed no forced term */                                                            \
    for (Py_ssize_t c0 = na; c0 < K + na; c0 += AR_CHUNK) {                                    \
        const Py_ssize_t c1 = c0 + AR_CHUNK < K + na ? c0 + AR_CHUNK : K + na;                 \
        const Py_ssize_t cf = c1 < K ? c1 : K;                                                 \
        if (cf > c0) AR_FILL(c0, cf);                                                          \
        for (Py_ssize_t c = cf; c < c1; ++c) fbuf[c - c0] = zero;                              \
        const VEC *Am = A;                                                                     \
        if (a_in_mem) __asm__("" : "+r"(Am)); /* the a_k read from memory in the loop */       \
        Py_ssize_t c = c0;                                                                     \
        /* with 32 registers, na steps at a time with the state's registers renamed            \
         * rather than moved: in step r of a round, the S[k] above is S[(k + r) % na], so      \
         * each update accumulates in place and the slot of y(t) takes the new last entry      \
         * (the same operations; with 16 registers the unrolled rounds spill) */               \
        for (; rounds && c + na <= c1; c += na) {                                              \
            _Pragma("GCC unroll 24") for (int r = 0; r < na; ++r) {                            \
                const Py_ssize_t t = c + r - na;                                               \
                const VEC yt = S[r];                                                           \
                if (target && t >= first) {                                                    \
                    const VEC e = target[t - first] - yt;                                      \
                    s += e * e;                                                                \
                }                                                                              \
                if (y)                                                                         \
                    for (Py_ssize_t l = 0; l < w; ++l) y[l * K + t] = yt[l];                   \
                _Pragma("GCC unroll 24") for (int k = 0; k < na - 1; ++k)                      \
                    S[(k + 1 + r) % na] -= Am[k] * yt;                                         \
                S[r] = fbuf[c + r - c0] - Am[na - 1] * yt;                                     \
            }                                                                                  \
        }                                                                                      \
        for (; c < c1; ++c) {                                                                  \
            const Py_ssize_t t = c - na;                                                       \
            const VEC yt = S[0];                                                               \
            if (target && t >= first) {                                                        \
                const VEC e = target[t - first] - yt;                                          \
                s += e * e;                                                                    \
            }                                                                                  \
            if (y)                                                                             \
                for (Py_ssize_t l = 0; l < w; ++l) y[l * K + t] = yt[l];                       \
            for (int k = 0; k < na - 1; ++k) S[k] = S[k + 1] - Am[k] * yt;                     \
            S[na - 1] = fbuf[c - c0] - Am[na - 1] * yt;                                        \
        }                                                                                      \
    }                                                                                          \
    if (J->sse)                                                                                \
        for (Py_ssize_t l = 0; l < w; ++l) J->sse[q + l] = s[l];                               \
}
AR_BLOCK_IMPL(ar_quad_impl, v4d, 4)
/* the baseline: 2-lane vectors (SSE2 has 16 registers of 2 doubles: 4-lane states spill) */
AR_BLOCK_IMPL(ar_pair_impl, v2d, 2)

/* One function per order and instruction set, chosen at run time (flexid_ar_quad): on x86-64
 * with GCC, AVX-512 (32 vector registers: the a_k stay in registers), AVX2/FMA, and the
 * baseline (2-lane vectors, two per block); elsewhere the compiler's generic vectors. */
#define AR_BODY_g(n)                                                                          \
    ar_pair_impl(J, q, n, 1, 0);                                                              \
    if (q + 2 < J->P) ar_pair_impl(J, q + 2, n, 1, 0)
#define AR_BODY_v3_(n) ar_quad_impl(J, q, n, 1, 0)
#define AR_BODY_v4_(n) ar_quad_impl(J, q, n, n > AR_MAXNA, 1)
#define AR_QUAD(n, isa, TGT, wide)                                                            \
    TGT static void ar_quad_##isa##n(const ar_job *J, Py_ssize_t q) { AR_BODY_##isa(n); }
SIMD_ORDERS24(AR_QUAD)
static const ar_quad_fn ar_quads_generic[AR_MAXREC + 1] = SIMD_TABLE24(ar_quad_g);
#if defined(SIMD_X86)
static const ar_quad_fn ar_quads_v3[AR_MAXREC + 1] = SIMD_TABLE24(ar_quad_v3_);
static const ar_quad_fn ar_quads_v4[AR_MAXREC + 1] = SIMD_TABLE24(ar_quad_v4_);
#endif

ar_quad_fn flexid_ar_quad(Py_ssize_t na)
{
    return SIMD_PICK(ar_quads_generic, ar_quads_v3, ar_quads_v4)[na];
}
#endif

/* Runs units [lo, hi) of the job: blocks of 4 candidates on the vector path, single
 * candidates otherwise; hist (na + K doubles) for the latter. */
static void ar_units(const ar_job *J, Py_ssize_t lo, Py_ssize_t hi, double *hist)
{
#if defined(__GNUC__)
    if (J->na >= 1 && J->na <= AR_MAXREC) {
        const ar_quad_fn quad = flexid_ar_quad(J->na);
        for (Py_ssize_t u = lo; u < hi; ++u) quad(J, u * AR_UNIT);
        return;
    }
#endif
    for (Py_ssize_t u = lo; u < hi; ++u)
        for (Py_ssize_t p = u * AR_UNIT; p < (u + 1) * AR_UNIT && p < J->P; ++p)
            ar_one(J, p, hist);
}

/* One unit of a recursion job; the scratch is the history of the one-candidate path. */
static int ar_unit(const void *ctx, Py_ssize_t u, void **scratch)
{
    const ar_job *J = (const ar_job *)ctx;
    if (!(J->na >= 1 && J->na <= AR_MAXREC) && !*scratch) {
        *scratch = malloc((size_t)(J->na + J->K + 1) * sizeof(double));
        if (!*scratch) return -1;
    }
    ar_units(J, u, u + 1, (double *)*scratch);
    return 0;
}

int flexid_ar_run(const ar_job *J, int n_threads)
{
    return flexid_run_units(J, ar_unit, (J->P + AR_UNIT - 1) / AR_UNIT, n_threads);
}
