/*
 * flexid._kernels: compiled inner loops of the batched ARX costs.
 *
 * Optional: the package works without it (flexid.kernels falls back to the NumPy/SciPy
 * reference path, which the tests compare against this code).  Two kernels:
 *
 *   schur_cohn(a, out)
 *       Strict stability of monic denominators z^n + a_1 z^(n-1) + ... + a_n, one row of
 *       the C-contiguous float64 array a (P, n) per candidate, by the Schur-Cohn step-down
 *       recursion; writes 1/0 into the uint8 array out (P,).
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
 *       candidates), so that no (P, K) array of forced terms is formed.  With first > 0
 *       (default 0) the recursion still runs from t = 0 but sse_out sums t >= first only,
 *       target then being (K - first,) and compared with y(first ..): a recursion started
 *       at rest before the samples that count.
 *
 *   poly_mul(p, q, out)
 *       Row-wise polynomial products out[r] = p[r] * q[r]: p (P, a) and q (P, b) with rows
 *       some stride apart, out (P, a + b - 1) C-contiguous; each coefficient summed over the
 *       shorter factor's coefficients in order, as flexid.costs.polynomial.poly_mul_rows's
 *       NumPy route does (without contracted multiply-adds on x86-64: bit for bit).
 *
 *   twin_rotor_run(params, x, u, out, n_sub, h, lock_yaw, square_law[, threads])
 *       The twin rotor's RK4 (flexid.envs.twin_rotor_physics: the equations of its batched
 *       ``derivatives`` and ``_rk4``, with the constants divided out once and sin, cos and
 *       tanh as inline polynomials, 4 rotors per SIMD vector): x (B, 7) states, updated in
 *       place; u (S, B, 2) voltages held over each of S samples; out (S, B, 7) or None, the
 *       states after each sample; params (22,) in the order of TRS_PARAMS below, shared by
 *       every rotor, or (B, 22), one row per rotor (a population of parameter sets); n_sub
 *       substeps of length h per sample.
 *
 * The recursion runs on blocks of 4 candidates, one per lane of a SIMD vector, in the
 * transposed direct form with its state in registers (see ar_quad_impl), the summation order
 * of the direct form; on x86-64 with GCC an AVX2/FMA clone is chosen at load time when the
 * CPU has it.  The GIL is released while the kernels run, and ar_run/arx_run split the
 * population between `threads` threads (POSIX threads; one where there are none).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdlib.h>
#include <stdint.h>
#include <string.h>

/* The least-squares fits (arx_fit, the lag sums of arx_fit_shifted, the estimated initial
 * state of free_fit) run with subnormal results flushed to zero and subnormal operands read
 * as zero (x86-64's FTZ and DAZ, restored after each block): the impulse and free responses
 * of a fast denominator decay through the subnormal range, where each operation costs about
 * a hundred cycles (a fit from poles of radius 0.5 took 2 to 20 times as long as one from
 * radius 0.9).  Only values below 2.3e-308 in absolute value are changed.  The plain
 * recursions (ar_run, arx_run: the costs themselves) keep IEEE arithmetic. */
#if defined(__x86_64__)
#include <xmmintrin.h>
#define FLUSH_SUBNORMALS_BEGIN const unsigned int flush_csr_ = _mm_getcsr(); _mm_setcsr(flush_csr_ | 0x8040u)
#define FLUSH_SUBNORMALS_END _mm_setcsr(flush_csr_)
#else
#define FLUSH_SUBNORMALS_BEGIN (void)0
#define FLUSH_SUBNORMALS_END (void)0
#endif

#if defined(_MSC_VER)
#define restrict __restrict
#endif

/* Helper threads for one call (the population split between them): POSIX threads */
#if defined(__GNUC__) && !defined(_WIN32) && (defined(__unix__) || defined(__APPLE__))
#define FLEXID_THREADS 1
#endif

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define FLEXID_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define FLEXID_CLONES
#endif

/* ------------------------------------------------------------------ Schur-Cohn */

static void schur_cohn_rows(const double *a, Py_ssize_t stride, Py_ssize_t P, Py_ssize_t n,
                            unsigned char *out,
                            double *c)
{
    for (Py_ssize_t p = 0; p < P; ++p) {
        const double *row = a + p * stride;
        int ok = 1;
        for (Py_ssize_t j = 0; j < n; ++j) {
            if (!isfinite(row[j])) ok = 0;
            c[j] = row[j];
        }
        for (Py_ssize_t m = n; ok && m > 0; --m) {
            const double k = c[m - 1];
            if (!(fabs(k) < 1.0)) {
                ok = 0;
                break;
            }
            const double d = 1.0 - k * k;
            Py_ssize_t i = 0, j = m - 2;
            for (; i < j; ++i, --j) {
                const double lo = c[i], hi = c[j];
                c[i] = (lo - k * hi) / d;
                c[j] = (hi - k * lo) / d;
            }
            if (i == j) c[i] = (c[i] - k * c[i]) / d;
        }
        out[p] = (unsigned char)ok;
    }
}

/* ------------------------------------------------------------------ AR recursion */

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
typedef double v4d __attribute__((vector_size(32), aligned(8)));
#define AR_MAXNA 16  /* orders whose state is held in registers (the numerator fits) */
#define AR_MAXREC 24 /* orders of ar_run/arx_run's block path (above 16: BJ's C F) */
#define AR_MAXNB 64  /* input terms computed in the kernel (more: the caller's GEMM) */
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
typedef double v2d __attribute__((vector_size(16), aligned(8)));
AR_BLOCK_IMPL(ar_quad_impl, v4d, 4)
/* the baseline: 2-lane vectors (SSE2 has 16 registers of 2 doubles: 4-lane states spill) */
AR_BLOCK_IMPL(ar_pair_impl, v2d, 2)

/* One function per order and instruction set, chosen at run time (ar_simd): on x86-64 with
 * GCC, AVX-512 (32 vector registers: the a_k stay in registers), AVX2/FMA, and the baseline;
 * elsewhere the compiler's generic vectors. */
#if defined(__x86_64__) && !defined(__clang__)
#define AR_X86 1
#define AR_TGT_V4 __attribute__((target("avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")))
#define AR_TGT_V3 __attribute__((target("avx2,fma")))
/* The baseline copies of the kernels run only on x86-64 CPUs without AVX2/FMA (pre-2013):
 * compiled at -O2 they lose little there, and the build takes a third of the time. */
#define AR_TGT_G __attribute__((optimize("O2")))
#else
#define AR_TGT_G
#endif
#define AR_QUAD(n)                                                                            \
    AR_TGT_G static void ar_quad_g##n(const ar_job *J, Py_ssize_t q)                          \
    {                                                                                         \
        ar_pair_impl(J, q, n, 1, 0);                                                          \
        if (q + 2 < J->P) ar_pair_impl(J, q + 2, n, 1, 0);                                    \
    }                                                                                         \
    AR_QUAD_X86(n)
#if defined(AR_X86)
#define AR_QUAD_X86(n)                                                                        \
    AR_TGT_V3 static void ar_quad_v3_##n(const ar_job *J, Py_ssize_t q)                       \
    {                                                                                         \
        ar_quad_impl(J, q, n, 1, 0);                                                          \
    }                                                                                         \
    AR_TGT_V4 static void ar_quad_v4_##n(const ar_job *J, Py_ssize_t q)                       \
    {                                                                                         \
        ar_quad_impl(J, q, n, n > AR_MAXNA, 1);                                               \
    }
#else
#define AR_QUAD_X86(n)
#endif
AR_QUAD(1)
AR_QUAD(2)
AR_QUAD(3)
AR_QUAD(4)
AR_QUAD(5)
AR_QUAD(6)
AR_QUAD(7)
AR_QUAD(8)
AR_QUAD(9)
AR_QUAD(10)
AR_QUAD(11)
AR_QUAD(12)
AR_QUAD(13)
AR_QUAD(14)
AR_QUAD(15)
AR_QUAD(16)
AR_QUAD(17)
AR_QUAD(18)
AR_QUAD(19)
AR_QUAD(20)
AR_QUAD(21)
AR_QUAD(22)
AR_QUAD(23)
AR_QUAD(24)
typedef void (*ar_quad_fn)(const ar_job *, Py_ssize_t);
#define AR_TABLE(p)                                                                           \
    {                                                                                         \
        NULL, p##1, p##2, p##3, p##4, p##5, p##6, p##7, p##8, p##9, p##10, p##11, p##12,      \
            p##13, p##14, p##15, p##16                                                        \
    }
#define AR_TABLE24(p)                                                                         \
    {                                                                                         \
        NULL, p##1, p##2, p##3, p##4, p##5, p##6, p##7, p##8, p##9, p##10, p##11, p##12,      \
            p##13, p##14, p##15, p##16, p##17, p##18, p##19, p##20, p##21, p##22, p##23, p##24 \
    }
static const ar_quad_fn ar_quads_generic[AR_MAXREC + 1] = AR_TABLE24(ar_quad_g);
#if defined(AR_X86)
static const ar_quad_fn ar_quads_v3[AR_MAXREC + 1] = AR_TABLE24(ar_quad_v3_);
static const ar_quad_fn ar_quads_v4[AR_MAXREC + 1] = AR_TABLE24(ar_quad_v4_);
#endif
static const char *const ar_simd_names[3] = {"generic", "avx2", "avx512"};
static int ar_simd_best = 0; /* the best the CPU runs */
static int ar_simd = 0;      /* the one in use */
static const ar_quad_fn *ar_quads = ar_quads_generic;

static void ar_simd_detect(void)
{
#if defined(AR_X86)
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
        ar_simd_best = 1;
        if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
            __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw"))
            ar_simd_best = 2;
    }
#endif
}

static void ar_simd_select(int level)
{
    ar_simd = level;
#if defined(AR_X86)
    ar_quads = level == 2 ? ar_quads_v4 : level == 1 ? ar_quads_v3 : ar_quads_generic;
#else
    ar_quads = ar_quads_generic;
#endif
}
#define AR_UNIT 4 /* candidates per unit of work */
#else
#define AR_MAXNA 0
#define AR_MAXREC 0
#define AR_MAXNB 0
#define AR_UNIT 1
static const char *const ar_simd_names[1] = {"scalar"};
static int ar_simd_best = 0, ar_simd = 0;
static void ar_simd_detect(void) {}
static void ar_simd_select(int level) { (void)level; }
#endif

/* Runs units [lo, hi) of the job: blocks of 4 candidates on the vector path, single
 * candidates otherwise; hist (na + K doubles) for the latter. */
static void ar_units(const ar_job *J, Py_ssize_t lo, Py_ssize_t hi, double *hist)
{
#if defined(__GNUC__)
    if (J->na >= 1 && J->na <= AR_MAXREC) {
        for (Py_ssize_t u = lo; u < hi; ++u) ar_quads[J->na](J, u * AR_UNIT);
        return;
    }
#endif
    for (Py_ssize_t u = lo; u < hi; ++u)
        for (Py_ssize_t p = u * AR_UNIT; p < (u + 1) * AR_UNIT && p < J->P; ++p)
            ar_one(J, p, hist);
}

/* ------------------------------------------------------------------ threads */
/* A job's units (blocks of candidates) are claimed one at a time, by the calling thread and
 * by up to n - 1 helper threads woken for the call.  The caller waits only for units a
 * helper has claimed, never for a helper to wake or to finish: on a busy machine a helper the
 * scheduler runs late finds nothing left (the shared record is freed by whichever of them
 * lets go of it last), so threads cost at most their wake-up when they do not help.  A unit function gets a scratch pointer of its thread (allocated by it on
 * first use, freed with free() at the end) and returns -1 when out of memory.  The GIL is
 * released around all of it. */
typedef int (*unit_fn)(const void *ctx, Py_ssize_t unit, void **scratch);

static int run_units_serial(const void *ctx, unit_fn fn, Py_ssize_t n_units)
{
    void *scratch = NULL;
    int rc = 0;
    for (Py_ssize_t u = 0; u < n_units && rc == 0; ++u) rc = fn(ctx, u, &scratch);
    free(scratch);
    return rc;
}

#if defined(FLEXID_THREADS)
#include <pthread.h>
#include <time.h>
typedef struct {
    const void *ctx;    /* read only while a claimed unit runs: the caller is waiting then */
    unit_fn fn;
    Py_ssize_t n_units;
    Py_ssize_t next;    /* next unclaimed unit (atomic) */
    Py_ssize_t done;    /* units finished (atomic) */
    int failed;         /* a unit ran out of memory (atomic) */
    int refs;           /* the caller and every helper started (atomic) */
    int waiting;        /* the caller sleeps on cond (under lock) */
    int joined;         /* helpers that took the job (atomic) */
    int max_helpers;    /* how many may work on it */
    pthread_mutex_t lock;
    pthread_cond_t cond;
} pool_shared;

static void pool_release(pool_shared *sh)
{
    if (__atomic_sub_fetch(&sh->refs, 1, __ATOMIC_ACQ_REL) == 0) {
        pthread_mutex_destroy(&sh->lock);
        pthread_cond_destroy(&sh->cond);
        free(sh);
    }
}

static void pool_claim(pool_shared *sh)
{
    void *scratch = NULL;
    for (;;) {
        const Py_ssize_t u = __atomic_fetch_add(&sh->next, 1, __ATOMIC_RELAXED);
        if (u >= sh->n_units) break;
        if (sh->fn(sh->ctx, u, &scratch) < 0) __atomic_store_n(&sh->failed, 1, __ATOMIC_RELAXED);
        if (__atomic_add_fetch(&sh->done, 1, __ATOMIC_ACQ_REL) == sh->n_units) {
            pthread_mutex_lock(&sh->lock);
            if (sh->waiting) pthread_cond_signal(&sh->cond);
            pthread_mutex_unlock(&sh->lock);
        }
    }
    free(scratch);
}

/* The helper threads: started on first use and then kept, waiting for the next job (starting
 * a thread costs tens of microseconds, as much as a whole small population).  One caller at a
 * time posts a job to them (pool_busy); another one meanwhile runs its job alone. */
static pthread_mutex_t pool_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t pool_wake = PTHREAD_COND_INITIALIZER;
static pool_shared *pool_job = NULL; /* the posted job (under pool_lock) */
static unsigned long pool_gen = 0;   /* jobs posted so far (under pool_lock) */
static int pool_helpers = 0;         /* helper threads started (under pool_lock) */
static int pool_busy = 0;            /* a caller owns the helpers (atomic) */
static int pool_sleepers = 0;        /* helpers blocked on pool_wake (under pool_lock) */

/* Waking a sleeping thread costs the caller a system call and the helper tens of
 * microseconds, as much as the whole job of one call of an optimiser's generation; the
 * calls of a run come back after the optimiser's own work (about 0.2 ms a generation in
 * Python), so a helper first spins this long on the word it waits for, and the caller on
 * the units a helper still runs. */
#define POOL_SPIN_HELPER 1e-3 /* seconds: between the calls of a run */
#define POOL_SPIN_CALLER 2e-5 /* seconds: for the last units a helper runs */
static double pool_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}
static inline void pool_pause(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}
/* Spins until *word differs from value (1) or the time is up (0). */
static int pool_spin_ul(const unsigned long *word, unsigned long value, double seconds)
{
    const double end = pool_now() + seconds;
    for (;;) {
        for (int i = 0; i < 64; ++i) {
            if (__atomic_load_n(word, __ATOMIC_ACQUIRE) != value) return 1;
            pool_pause();
        }
        if (pool_now() > end) return 0;
    }
}

static void *pool_helper(void *arg)
{
    (void)arg;
    unsigned long seen = 0;
    for (;;) {
        pool_spin_ul(&pool_gen, seen, POOL_SPIN_HELPER);
        pthread_mutex_lock(&pool_lock);
        while (!(pool_job && pool_gen != seen)) {
            if (!pool_job) seen = pool_gen; /* a job posted meanwhile is over */
            ++pool_sleepers;
            pthread_cond_wait(&pool_wake, &pool_lock);
            --pool_sleepers;
        }
        pool_shared *sh = pool_job;
        seen = pool_gen;
        __atomic_add_fetch(&sh->refs, 1, __ATOMIC_ACQ_REL);
        pthread_mutex_unlock(&pool_lock);
        /* no more helpers on a job than its caller asked for */
        if (__atomic_add_fetch(&sh->joined, 1, __ATOMIC_ACQ_REL) <= sh->max_helpers)
            pool_claim(sh);
        pool_release(sh);
    }
    return NULL;
}

/* In a child process made by fork the helpers do not exist: start afresh. */
static void pool_after_fork(void)
{
    pthread_mutex_init(&pool_lock, NULL);
    pthread_cond_init(&pool_wake, NULL);
    pool_job = NULL;
    pool_helpers = 0;
    pool_busy = 0;
    pool_sleepers = 0;
}
#endif

/* Runs units 0 .. n_units - 1 of fn on up to n_threads threads; 0, or -1 out of memory. */
static int run_units(const void *ctx, unit_fn fn, Py_ssize_t n_units, int n_threads)
{
#if defined(FLEXID_THREADS)
    if (n_threads > n_units) n_threads = (int)n_units;
    if (n_threads > 64) n_threads = 64;
    pool_shared *sh = NULL;
    if (n_threads > 1 && !__atomic_exchange_n(&pool_busy, 1, __ATOMIC_ACQUIRE)) {
        sh = (pool_shared *)calloc(1, sizeof(pool_shared));
        if (!sh) __atomic_store_n(&pool_busy, 0, __ATOMIC_RELEASE);
    }
    if (sh) {
        sh->ctx = ctx;
        sh->fn = fn;
        sh->n_units = n_units;
        sh->refs = 1;
        sh->max_helpers = n_threads - 1;
        pthread_mutex_init(&sh->lock, NULL);
        pthread_cond_init(&sh->cond, NULL);
        pthread_mutex_lock(&pool_lock);
        if (pool_helpers < n_threads - 1) {
            pthread_attr_t attr;
            pthread_attr_init(&attr);
            pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
            while (pool_helpers < n_threads - 1) {
                pthread_t tid;
                if (pthread_create(&tid, &attr, pool_helper, NULL) != 0) break;
                ++pool_helpers;
            }
            pthread_attr_destroy(&attr);
        }
        pool_job = sh;
        __atomic_store_n(&pool_gen, pool_gen + 1, __ATOMIC_RELEASE);
        if (pool_sleepers) pthread_cond_broadcast(&pool_wake);
        pthread_mutex_unlock(&pool_lock);
        pool_claim(sh);
        if (__atomic_load_n(&sh->done, __ATOMIC_ACQUIRE) < n_units) {
            const double end = pool_now() + POOL_SPIN_CALLER;
            while (__atomic_load_n(&sh->done, __ATOMIC_ACQUIRE) < n_units && pool_now() < end)
                for (int i = 0; i < 64; ++i) pool_pause();
        }
        if (__atomic_load_n(&sh->done, __ATOMIC_ACQUIRE) < n_units) {
            pthread_mutex_lock(&sh->lock);
            sh->waiting = 1;
            while (__atomic_load_n(&sh->done, __ATOMIC_ACQUIRE) < n_units)
                pthread_cond_wait(&sh->cond, &sh->lock);
            pthread_mutex_unlock(&sh->lock);
        }
        pthread_mutex_lock(&pool_lock);
        pool_job = NULL;
        pthread_mutex_unlock(&pool_lock);
        __atomic_store_n(&pool_busy, 0, __ATOMIC_RELEASE);
        const int failed = __atomic_load_n(&sh->failed, __ATOMIC_ACQUIRE);
        pool_release(sh);
        return failed ? -1 : 0;
    }
#else
    (void)n_threads;
#endif
    return run_units_serial(ctx, fn, n_units);
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

/* Runs the whole job on up to n_threads threads; 0 on success, -1 when out of memory. */
static int ar_run_job(const ar_job *J, int n_threads)
{
    return run_units(J, ar_unit, (J->P + AR_UNIT - 1) / AR_UNIT, n_threads);
}

/* ------------------------------------------------------------------ Python glue */

static int get_buffer(PyObject *obj, Py_buffer *view, int writable, const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) < 0) {
        PyErr_Format(PyExc_TypeError, "%s: expected a C-contiguous%s buffer", name,
                     writable ? " writable" : "");
        return -1;
    }
    return 0;
}

static int check_format(Py_buffer *view, const char *want, const char *name)
{
    const char *fmt = view->format ? view->format : "B";
    if (fmt[0] == '<' || fmt[0] == '=' || fmt[0] == '@') ++fmt;
    if (strcmp(fmt, want) != 0) {
        PyErr_Format(PyExc_TypeError, "%s: expected format '%s', got '%s'", name, want, fmt);
        return -1;
    }
    return 0;
}

/* A (P, n) float64 array whose rows are contiguous, some (non-negative) number of doubles
 * apart, e.g. a column block of a population array; its row stride in doubles, or -1 with an
 * exception set. */
static Py_ssize_t get_rows(PyObject *obj, Py_buffer *view, const char *fn, const char *name)
{
    if (PyObject_GetBuffer(obj, view, PyBUF_STRIDES | PyBUF_FORMAT) < 0) {
        PyErr_Format(PyExc_TypeError, "%s: %s: expected a buffer", fn, name);
        return -1;
    }
    if (check_format(view, "d", name) < 0) goto fail;
    if (view->ndim != 2) {
        PyErr_Format(PyExc_ValueError, "%s: %s must be 2-D", fn, name);
        goto fail;
    }
    const Py_ssize_t d = (Py_ssize_t)sizeof(double);
    if ((view->shape[1] > 1 && view->strides[1] != d) || view->strides[0] % d != 0 ||
        (view->shape[0] > 1 && view->strides[0] < 0)) {
        PyErr_Format(PyExc_TypeError, "%s: %s: rows must be contiguous", fn, name);
        goto fail;
    }
    return view->shape[0] > 1 ? view->strides[0] / d : view->shape[1];
fail:
    PyBuffer_Release(view);
    return -1;
}

/* Compiled for the baseline (no target clones): on x86-64 that has no fused multiply-add,
 * so every product is rounded before it is added, as in NumPy. */
static void poly_mul_rows_c(const double *p, Py_ssize_t ps, Py_ssize_t a, const double *q,
                            Py_ssize_t qs, Py_ssize_t b, Py_ssize_t P, double *out)
{
    const int swap = b > a; /* the loop runs over the shorter factor's coefficients */
    if (swap) {
        const double *t = p;
        p = q;
        q = t;
        Py_ssize_t u = ps;
        ps = qs;
        qs = u;
        u = a;
        a = b;
        b = u;
    }
    const Py_ssize_t w = a + b - 1;
    for (Py_ssize_t r = 0; r < P; ++r) {
        const double *pr = p + r * ps, *qr = q + r * qs;
        double *o = out + r * w;
        for (Py_ssize_t k = 0; k < w; ++k) o[k] = 0.0;
        for (Py_ssize_t i = 0; i < b; ++i) {
            const double qi = qr[i];
            for (Py_ssize_t j = 0; j < a; ++j) o[i + j] += qi * pr[j];
        }
    }
}

static PyObject *py_poly_mul(PyObject *self, PyObject *args)
{
    PyObject *p_obj, *q_obj, *out_obj;
    Py_buffer p, q, out;
    if (!PyArg_ParseTuple(args, "OOO", &p_obj, &q_obj, &out_obj)) return NULL;
    const Py_ssize_t ps = get_rows(p_obj, &p, "poly_mul", "p");
    if (ps < 0) return NULL;
    const Py_ssize_t qs = get_rows(q_obj, &q, "poly_mul", "q");
    if (qs < 0) {
        PyBuffer_Release(&p);
        return NULL;
    }
    if (get_buffer(out_obj, &out, 1, "out") < 0) {
        PyBuffer_Release(&p);
        PyBuffer_Release(&q);
        return NULL;
    }
    PyObject *result = NULL;
    if (check_format(&out, "d", "out") < 0) goto done;
    if (q.shape[0] != p.shape[0] || p.shape[1] < 1 || q.shape[1] < 1 || out.ndim != 2 ||
        out.shape[0] != p.shape[0] || out.shape[1] != p.shape[1] + q.shape[1] - 1) {
        PyErr_SetString(PyExc_ValueError,
                        "poly_mul: p (P, a) and q (P, b) with a, b >= 1, out (P, a + b - 1)");
        goto done;
    }
    poly_mul_rows_c((const double *)p.buf, ps, p.shape[1], (const double *)q.buf, qs,
                    q.shape[1], p.shape[0], (double *)out.buf);
    result = Py_None;
    Py_INCREF(result);
done:
    PyBuffer_Release(&p);
    PyBuffer_Release(&q);
    PyBuffer_Release(&out);
    return result;
}

static PyObject *py_schur_cohn(PyObject *self, PyObject *args)
{
    PyObject *a_obj, *out_obj;
    Py_buffer a, out;
    if (!PyArg_ParseTuple(args, "OO", &a_obj, &out_obj)) return NULL;
    const Py_ssize_t stride = get_rows(a_obj, &a, "schur_cohn", "a");
    if (stride < 0) return NULL;
    if (get_buffer(out_obj, &out, 1, "out") < 0) {
        PyBuffer_Release(&a);
        return NULL;
    }
    PyObject *result = NULL;
    if (check_format(&out, "B", "out") < 0) goto done;
    if (out.ndim != 1 || out.shape[0] != a.shape[0]) {
        PyErr_SetString(PyExc_ValueError, "schur_cohn: a must be (P, n) and out (P,)");
        goto done;
    }
    Py_ssize_t P = a.shape[0], n = a.shape[1];
    double *c = (double *)malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
    if (!c) {
        PyErr_NoMemory();
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    schur_cohn_rows((const double *)a.buf, stride, P, n, (unsigned char *)out.buf, c);
    Py_END_ALLOW_THREADS
    free(c);
    result = Py_None;
    Py_INCREF(result);
done:
    PyBuffer_Release(&a);
    PyBuffer_Release(&out);
    return result;
}

/* Parses the common tail (state, target, y_out, sse_out) of ar_run and arx_run into J, given
 * P, na, K and first; bufs[0..3] and have[0..3] are theirs.  -1 with an exception set on
 * error. */
static int ar_parse_tail(const char *fn, PyObject *objs[4], Py_buffer bufs[4], int have[4],
                         ar_job *J)
{
    static const char *names[4] = {"state", "target", "y_out", "sse_out"};
    const Py_ssize_t P = J->P, na = J->na, K = J->K;
    for (int i = 0; i < 4; ++i) {
        if (objs[i] == Py_None) {
            if (i == 0) {
                PyErr_Format(PyExc_TypeError, "%s: state is required", fn);
                return -1;
            }
            continue;
        }
        if (get_buffer(objs[i], &bufs[i], i >= 2, names[i]) < 0) return -1;
        have[i] = 1;
        if (check_format(&bufs[i], "d", names[i]) < 0) return -1;
    }
    if (bufs[0].ndim == 1 && bufs[0].shape[0] == na) {
        J->state_stride = 0;
    } else if (bufs[0].ndim == 2 && bufs[0].shape[0] == P && bufs[0].shape[1] == na) {
        J->state_stride = na;
    } else {
        PyErr_Format(PyExc_ValueError, "%s: state must be (na,) or (P, na)", fn);
        return -1;
    }
    if (have[1] && (bufs[1].ndim != 1 || bufs[1].shape[0] != K - J->first)) {
        PyErr_Format(PyExc_ValueError, "%s: target must be (K - first,)", fn);
        return -1;
    }
    if (have[2] && (bufs[2].ndim != 2 || bufs[2].shape[0] != P || bufs[2].shape[1] != K)) {
        PyErr_Format(PyExc_ValueError, "%s: y_out must be (P, K)", fn);
        return -1;
    }
    if (have[3] && (bufs[3].ndim != 1 || bufs[3].shape[0] != P)) {
        PyErr_Format(PyExc_ValueError, "%s: sse_out must be (P,)", fn);
        return -1;
    }
    J->state = (const double *)bufs[0].buf;
    J->target = have[1] ? (const double *)bufs[1].buf : NULL;
    J->y = have[2] ? (double *)bufs[2].buf : NULL;
    J->sse = have[3] ? (double *)bufs[3].buf : NULL;
    return 0;
}

/* Runs J without the GIL; None, or NULL with MemoryError. */
static PyObject *ar_execute(const ar_job *J, int n_threads)
{
    int rc;
    Py_BEGIN_ALLOW_THREADS
    rc = ar_run_job(J, n_threads);
    Py_END_ALLOW_THREADS
    if (rc < 0) return PyErr_NoMemory();
    Py_RETURN_NONE;
}

static PyObject *py_ar_run(PyObject *self, PyObject *args)
{
    PyObject *objs[6];
    Py_buffer bufs[6];
    int have[6] = {0}, n_threads = 1;
    if (!PyArg_ParseTuple(args, "OOOOOO|i", &objs[0], &objs[1], &objs[2], &objs[3], &objs[4],
                          &objs[5], &n_threads))
        return NULL;
    PyObject *result = NULL;
    static const char *names[2] = {"a", "forced"};
    for (int i = 0; i < 2; ++i) {
        if (objs[i] == Py_None) {
            PyErr_Format(PyExc_TypeError, "ar_run: %s is required", names[i]);
            goto done;
        }
        if (get_buffer(objs[i], &bufs[i], 0, names[i]) < 0) goto done;
        have[i] = 1;
        if (check_format(&bufs[i], "d", names[i]) < 0) goto done;
    }
    if (bufs[0].ndim != 2 || bufs[1].ndim != 2) {
        PyErr_SetString(PyExc_ValueError, "ar_run: a must be (P, na) and forced (P, K)");
        goto done;
    }
    ar_job J = {0};
    J.P = bufs[0].shape[0];
    J.na = bufs[0].shape[1];
    J.K = bufs[1].shape[1];
    if (bufs[1].shape[0] != J.P) {
        PyErr_SetString(PyExc_ValueError, "ar_run: a and forced differ in P");
        goto done;
    }
    J.a = (const double *)bufs[0].buf;
    J.a_stride = J.na;
    J.forced = (const double *)bufs[1].buf;
    if (ar_parse_tail("ar_run", objs + 2, bufs + 2, have + 2, &J) < 0) goto done;
    result = ar_execute(&J, n_threads);
done:
    for (int i = 0; i < 6; ++i)
        if (have[i]) PyBuffer_Release(&bufs[i]);
    return result;
}

static PyObject *py_arx_run(PyObject *self, PyObject *args)
{
    PyObject *objs[7];
    Py_buffer bufs[7];
    int have[7] = {0}, n_threads = 1;
    Py_ssize_t strides[2] = {0, 0}, first = 0;
    if (!PyArg_ParseTuple(args, "OOOOOOO|in", &objs[0], &objs[1], &objs[2], &objs[3], &objs[4],
                          &objs[5], &objs[6], &n_threads, &first))
        return NULL;
    PyObject *result = NULL;
    static const char *names[3] = {"a", "b", "reg"};
    for (int i = 0; i < 3; ++i) {
        if (objs[i] == Py_None) {
            PyErr_Format(PyExc_TypeError, "arx_run: %s is required", names[i]);
            goto done;
        }
        /* a and b may be column blocks of one population array (rows of contiguous values
         * some stride apart), reg must be C-contiguous */
        if (i < 2) {
            strides[i] = get_rows(objs[i], &bufs[i], "arx_run", names[i]);
            if (strides[i] < 0) goto done;
            have[i] = 1;
            continue;
        }
        if (get_buffer(objs[i], &bufs[i], 0, names[i]) < 0) goto done;
        have[i] = 1;
        if (check_format(&bufs[i], "d", names[i]) < 0) goto done;
    }
    if (bufs[0].ndim != 2 || bufs[1].ndim != 2 || bufs[2].ndim != 2 ||
        bufs[1].shape[0] != bufs[0].shape[0] || bufs[2].shape[1] != bufs[1].shape[1]) {
        PyErr_SetString(PyExc_ValueError,
                        "arx_run: a must be (P, na), b (P, nb) and reg (K, nb)");
        goto done;
    }
    ar_job J = {0};
    J.P = bufs[0].shape[0];
    J.na = bufs[0].shape[1];
    J.nb = bufs[1].shape[1];
    J.K = bufs[2].shape[0];
    if (J.nb > AR_MAXNB && AR_MAXNB > 0) {
        PyErr_Format(PyExc_ValueError, "arx_run: at most %d input terms (nb)", AR_MAXNB);
        goto done;
    }
    J.a = (const double *)bufs[0].buf;
    J.b = (const double *)bufs[1].buf;
    J.a_stride = strides[0];
    J.b_stride = strides[1];
    J.reg = (const double *)bufs[2].buf;
    if (first < 0 || first > J.K) {
        PyErr_SetString(PyExc_ValueError, "arx_run: first must be in [0, K]");
        goto done;
    }
    J.first = first;
    if (ar_parse_tail("arx_run", objs + 3, bufs + 3, have + 3, &J) < 0) goto done;
    result = ar_execute(&J, n_threads);
done:
    for (int i = 0; i < 7; ++i)
        if (have[i]) PyBuffer_Release(&bufs[i]);
    return result;
}

/* ------------------------------------------------------------------ twin rotor RK4 */
/* params order: I1 I2 a1 b1 a2 b2 Mg B1psi B2psi B1phi B2phi Kgy k1 k2 T11 T10 T21 T20 Tp T0
 * kc eps (eps: the Coulomb smoothing velocity) */
#define TRS_PARAMS 22

#if defined(__GNUC__)
/* The derivative of the model spends its time in sin(psi), cos(psi) and two tanh.  Here they
 * are inline polynomials on vectors of 4 twin rotors (one rotor per lane), so that one
 * instruction steps 4 rotors and the four functions of a stage overlap instead of waiting
 * for four library calls.  Each is within a few eps of the exact value (absolute error),
 * which is what the model's terms need: sin, cos and tanh enter multiplied by a coefficient,
 * and the rounding of that term is already a few eps of the coefficient.
 *
 * sin and cos: reduction by n pi/2 with pi/2 split in three parts (the first two of 33 bits,
 * so n * part is exact for |n| < 2^20) and the fdlibm kernels on [-pi/4, pi/4]; beyond
 * |psi| = TRS_TRIG_MAX (a rotor that has spun over thousands of times) or for a non-finite
 * psi the library's sin and cos take that lane.
 * tanh(x) = 2 / (1 + exp(-2x)) - 1, with x clamped to +-20 (tanh(20) is 1 in doubles) and
 * exp on [-40, 40] as 2^n times the degree-13 Taylor polynomial on |r| <= ln2 / 2, whose
 * truncation error is below 5e-18. */
typedef long long v4i __attribute__((vector_size(32), aligned(8)));
/* the vector helpers are always inlined, so no vector crosses a call boundary */
#pragma GCC diagnostic ignored "-Wpsabi"

#define TRS_TRIG_MAX 1e5
#define TRS_ROUND 6755399441055744.0 /* 1.5 * 2^52: x + it rounds x to an integer */

static inline __attribute__((always_inline)) v4d trs_select(v4i mask, v4d a, v4d b)
{
    return (v4d)((mask & (v4i)a) | (~mask & (v4i)b));
}

static inline __attribute__((always_inline)) v4d trs_splat(double a)
{
    return (v4d){a, a, a, a};
}

static inline __attribute__((always_inline)) void trs_sincos(v4d x, v4d *s_out, v4d *c_out)
{
    const v4d rnd = trs_splat(TRS_ROUND);
    const v4d t = x * 6.36619772367581382433e-01 + rnd; /* 2 / pi */
    const v4d n = t - rnd;
    v4d r = x - n * 1.57079632673412561417e+00;
    r = r - n * 6.07710050630396597660e-11;
    r = r - n * 2.02226624879595063154e-21;
    const v4i q = (v4i)t - (v4i)rnd; /* n as an integer */
    const v4d z = r * r, z2 = z * z;
    /* fdlibm __kernel_sin and __kernel_cos coefficients, Estrin's scheme */
    const v4d ps = (-1.66666666666666324348e-01 + z * 8.33333333332248946124e-03) +
                   z2 * ((-1.98412698298579493134e-04 + z * 2.75573137070700676789e-06) +
                         z2 * (-2.50507602534068634195e-08 + z * 1.58969099521155010221e-10));
    const v4d pc = (4.16666666666666019037e-02 + z * -1.38888888888741095749e-03) +
                   z2 * ((2.48015872894767294178e-05 + z * -2.75573143513906633035e-07) +
                         z2 * (2.08757232129817482790e-09 + z * -1.13596475577881948265e-11));
    const v4d sr = r + (r * z) * ps;
    const v4d cr = (1.0 - 0.5 * z) + z2 * pc;
    /* quadrant n mod 4: sin = (s, c, -s, -c), cos = (c, -s, -c, s) */
    const v4i odd = -(q & 1);
    const v4d sv = trs_select(odd, cr, sr), cv = trs_select(odd, sr, cr);
    const v4i sin_sign = (q & 2) << 62, cos_sign = ((q + 1) & 2) << 62;
    *s_out = (v4d)((v4i)sv ^ sin_sign);
    *c_out = (v4d)((v4i)cv ^ cos_sign);
    const v4i fine = (v4d)((v4i)x & ~((v4i){0, 0, 0, 0} + (1LL << 63))) <= TRS_TRIG_MAX;
    if (!(fine[0] & fine[1] & fine[2] & fine[3])) {
        for (int j = 0; j < 4; ++j)
            if (!fine[j]) {
                (*s_out)[j] = sin(x[j]);
                (*c_out)[j] = cos(x[j]);
            }
    }
}

static inline __attribute__((always_inline)) v4d trs_tanh(v4d x)
{
    x = trs_select(x > 20.0, trs_splat(20.0), x);
    x = trs_select(x < -20.0, trs_splat(-20.0), x);
    const v4d y = -2.0 * x;
    const v4d rnd = trs_splat(TRS_ROUND);
    const v4d t = y * 1.44269504088896338700e+00 + rnd; /* 1 / ln 2 */
    const v4d n = t - rnd;
    v4d r = y - n * 6.93147180369123816490e-01; /* ln 2, high part: n * it is exact */
    r = r - n * 1.90821492927058770002e-10;
    const v4d r2 = r * r, r4 = r2 * r2, r8 = r4 * r4;
    const v4d p = ((1.0 + r) + r2 * (1.0 / 2 + r * (1.0 / 6))) +
                  r4 * ((1.0 / 24 + r * (1.0 / 120)) + r2 * (1.0 / 720 + r * (1.0 / 5040))) +
                  r8 * (((1.0 / 40320 + r * (1.0 / 362880)) +
                         r2 * (1.0 / 3628800 + r * (1.0 / 39916800))) +
                        r4 * (1.0 / 479001600 + r * (1.0 / 6227020800.0)));
    const v4i q = (v4i)t - (v4i)rnd;
    const v4d scale = (v4d)((q + 1023) << 52);
    return 2.0 / (1.0 + p * scale) - 1.0;
}

/* The model's constants folded as the derivative uses them (divisions done once), one lane
 * per rotor, so that rotors with their own parameters share a vector. */
typedef struct {
    v4d a1, b1, a2, b2;           /* thrust coefficients over I1 and I2 */
    v4d mg, c1psi, c2psi;         /* Mg, B1psi, B2psi over I1 */
    v4d c1phi, c2phi, inv_i2;     /* B1phi, B2phi over I2; 1 / I2 */
    v4d kgy, inv_eps;
    v4d ku1, ku2, g1, g2;         /* k1 / T11, k2 / T21, T10 / T11, T20 / T21 */
    v4d r_dt1, r_t1, inv_tp;      /* kc T0 / Tp, kc / Tp, 1 / Tp */
} trs_consts;

/* Lane j of c from the parameter vector lanes[j] (TRS_PARAMS values). */
static void trs_fold(const double *const lanes[4], trs_consts *c)
{
    for (int j = 0; j < 4; ++j) {
        const double *p = lanes[j];
        c->a1[j] = p[2] / p[0];
        c->b1[j] = p[3] / p[0];
        c->a2[j] = p[4] / p[1];
        c->b2[j] = p[5] / p[1];
        c->mg[j] = p[6] / p[0];
        c->c1psi[j] = p[7] / p[0];
        c->c2psi[j] = p[8] / p[0];
        c->c1phi[j] = p[9] / p[1];
        c->c2phi[j] = p[10] / p[1];
        c->inv_i2[j] = 1.0 / p[1];
        c->kgy[j] = p[11];
        c->inv_eps[j] = 1.0 / p[21];
        c->ku1[j] = p[12] / p[14];
        c->ku2[j] = p[13] / p[16];
        c->g1[j] = p[15] / p[14];
        c->g2[j] = p[17] / p[16];
        c->r_dt1[j] = p[20] * p[19] / p[18];
        c->r_t1[j] = p[20] / p[18];
        c->inv_tp[j] = 1.0 / p[18];
    }
}

/* Derivatives of 4 rotors, one per lane: x[i] is state i; f1, f2 the rotor forcing k u / T
 * of the sample (held).  Writes d[i]; with lock the yaw rows are 0. */
static inline __attribute__((always_inline)) void
trs_deriv(const trs_consts *c, const v4d x[7], v4d f1, v4d f2, v4d d[7], const int lock,
          const int square)
{
    const v4i sign = (v4i){0, 0, 0, 0} + (1LL << 63);
    const v4d psi = x[0], dpsi = x[1], dphi = x[3], t1 = x[4], t2 = x[5], mr = x[6];
    v4d s, co;
    trs_sincos(psi, &s, &co);
    const v4d m1 = t1 * (c->a1 * (square ? t1 : (v4d)((v4i)t1 & ~sign)) + c->b1); /* M1 / I1 */
    const v4d dt1 = f1 - c->g1 * t1;
    d[0] = dpsi;
    d[4] = dt1;
    d[5] = f2 - c->g2 * t2;
    d[6] = c->r_dt1 * dt1 + c->r_t1 * t1 - c->inv_tp * mr;
    if (lock) {
        d[1] = m1 - c->mg * s - c->c1psi * dpsi - c->c2psi * trs_tanh(dpsi * c->inv_eps);
        d[2] = trs_splat(0.0);
        d[3] = trs_splat(0.0);
    } else {
        const v4d m2 = t2 * (c->a2 * (square ? t2 : (v4d)((v4i)t2 & ~sign)) + c->b2); /* M2 / I2 */
        d[1] = m1 * (1.0 - c->kgy * dphi * co) - c->mg * s - c->c1psi * dpsi -
               c->c2psi * trs_tanh(dpsi * c->inv_eps);
        d[2] = dphi;
        d[3] = m2 - c->c1phi * dphi - c->c2phi * trs_tanh(dphi * c->inv_eps) - c->inv_i2 * mr;
    }
}

/* Rotors g .. g + 3 (those below B; the other lanes run rotors at rest), all S samples.  One
 * vector at a time: a second one interleaved runs out of registers and is slower. */
static inline __attribute__((always_inline)) void
trs_block_impl(const trs_consts *c, double *x, const double *u, double *out, Py_ssize_t S,
               Py_ssize_t B, Py_ssize_t g, long n_sub, double h, const int lock,
               const int square)
{
    v4d xs[7], y[7], k[7], acc[7], f1 = trs_splat(0.0), f2 = trs_splat(0.0);
    const double hh = 0.5 * h, h6 = h / 6.0;
    const Py_ssize_t w = (B - g < 4) ? B - g : 4;
    for (int i = 0; i < 7; ++i) xs[i] = trs_splat(0.0);
    for (Py_ssize_t j = 0; j < w; ++j)
        for (int i = 0; i < 7; ++i) xs[i][j] = x[7 * (g + j) + i];
    for (Py_ssize_t s = 0; s < S; ++s) {
        const double *us = u + 2 * (s * B + g);
        for (Py_ssize_t j = 0; j < w; ++j) {
            f1[j] = c->ku1[j] * us[2 * j];
            f2[j] = c->ku2[j] * us[2 * j + 1];
        }
        for (long sub = 0; sub < n_sub; ++sub) {
            trs_deriv(c, xs, f1, f2, k, lock, square);
            for (int i = 0; i < 7; ++i) {
                acc[i] = k[i];
                y[i] = xs[i] + hh * k[i];
            }
            trs_deriv(c, y, f1, f2, k, lock, square);
            for (int i = 0; i < 7; ++i) {
                acc[i] += 2.0 * k[i];
                y[i] = xs[i] + hh * k[i];
            }
            trs_deriv(c, y, f1, f2, k, lock, square);
            for (int i = 0; i < 7; ++i) {
                acc[i] += 2.0 * k[i];
                y[i] = xs[i] + h * k[i];
            }
            trs_deriv(c, y, f1, f2, k, lock, square);
            for (int i = 0; i < 7; ++i) xs[i] += h6 * (acc[i] + k[i]);
        }
        if (out) {
            double *os = out + 7 * (s * B + g);
            for (Py_ssize_t j = 0; j < w; ++j)
                for (int i = 0; i < 7; ++i) os[7 * j + i] = xs[i][j];
        }
    }
    for (Py_ssize_t j = 0; j < w; ++j)
        for (int i = 0; i < 7; ++i) x[7 * (g + j) + i] = xs[i][j];
}

/* One function per (lock, thrust law), so that every branch on them is resolved at compile
 * time. */
#define TRS_BLOCK(name, lock, square)                                                         \
    FLEXID_CLONES                                                                             \
    static void name(const trs_consts *c, double *x, const double *u, double *out,           \
                     Py_ssize_t S, Py_ssize_t B, Py_ssize_t g, long n_sub, double h)          \
    {                                                                                         \
        trs_block_impl(c, x, u, out, S, B, g, n_sub, h, lock, square);                        \
    }
TRS_BLOCK(trs_block, 0, 0)
TRS_BLOCK(trs_block_lock, 1, 0)
TRS_BLOCK(trs_block_sq, 0, 1)
TRS_BLOCK(trs_block_lock_sq, 1, 1)

typedef void (*trs_block_fn)(const trs_consts *, double *, const double *, double *,
                             Py_ssize_t, Py_ssize_t, Py_ssize_t, long, double);

/* Rotors g .. g + 3 of a run, all its samples. */
static void trs_group(const double *p, Py_ssize_t p_stride, double *x, const double *u,
                      double *out, Py_ssize_t S, Py_ssize_t B, Py_ssize_t g, long n_sub,
                      double h, int lock, int square)
{
    static const trs_block_fn blocks[2][2] = {
        {trs_block, trs_block_sq},
        {trs_block_lock, trs_block_lock_sq},
    };
    trs_consts c;
    /* lanes past the last rotor take the block's first parameters (they run at rest) */
    const double *lanes[4];
    for (Py_ssize_t j = 0; j < 4; ++j) lanes[j] = p + p_stride * (g + j < B ? g + j : g);
    trs_fold(lanes, &c);
    blocks[lock != 0][square != 0](&c, x, u, out, S, B, g, n_sub, h);
}
#else
/* Without GCC's vector extensions: the equations as written in the reference route. */
static inline double trs_thrust(double tau, double a, double b, int square)
{
    return tau * (a * (square ? tau : fabs(tau)) + b);
}

static void trs_derivatives(const double *p, const double *x, double u1, double u2,
                            int lock, int square, double *d)
{
    const double psi = x[0], dpsi = x[1], dphi = x[3], t1 = x[4], t2 = x[5], mr = x[6];
    const double m1 = trs_thrust(t1, p[2], p[3], square);
    const double m2 = trs_thrust(t2, p[4], p[5], square);
    const double dt1 = (p[12] * u1 - p[15] * t1) / p[14];
    const double dt2 = (p[13] * u2 - p[17] * t2) / p[16];
    const double dmr = (-mr + p[20] * (p[19] * dt1 + t1)) / p[18];
    d[0] = dpsi;
    d[1] = (m1 - p[6] * sin(psi) - p[7] * dpsi - p[8] * tanh(dpsi / p[21])
            - p[11] * m1 * dphi * cos(psi)) / p[0];
    if (lock) {
        d[2] = 0.0;
        d[3] = 0.0;
    } else {
        d[2] = dphi;
        d[3] = (m2 - p[9] * dphi - p[10] * tanh(dphi / p[21]) - mr) / p[1];
    }
    d[4] = dt1;
    d[5] = dt2;
    d[6] = dmr;
}

/* Rotors g .. g + 3 of a run (each rotor's samples in turn: rotors are independent). */
static void trs_group(const double *params, Py_ssize_t p_stride, double *x, const double *u,
                      double *out, Py_ssize_t S, Py_ssize_t B, Py_ssize_t g, long n_sub,
                      double h, int lock, int square)
{
    double k1[7], k2[7], k3[7], k4[7], y[7];
    const double hh = 0.5 * h, h6 = h / 6.0;
    const Py_ssize_t end = (g + 4 < B) ? g + 4 : B;
    for (Py_ssize_t b = g; b < end; ++b) {
        for (Py_ssize_t s = 0; s < S; ++s) {
            const double *p = params + p_stride * b;
            double *xb = x + 7 * b;
            const double u1 = u[2 * (s * B + b)], u2 = u[2 * (s * B + b) + 1];
            for (long k = 0; k < n_sub; ++k) {
                trs_derivatives(p, xb, u1, u2, lock, square, k1);
                for (int i = 0; i < 7; ++i) y[i] = xb[i] + hh * k1[i];
                trs_derivatives(p, y, u1, u2, lock, square, k2);
                for (int i = 0; i < 7; ++i) y[i] = xb[i] + hh * k2[i];
                trs_derivatives(p, y, u1, u2, lock, square, k3);
                for (int i = 0; i < 7; ++i) y[i] = xb[i] + h * k3[i];
                trs_derivatives(p, y, u1, u2, lock, square, k4);
                for (int i = 0; i < 7; ++i)
                    xb[i] = xb[i] + h6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
            }
            if (out) memcpy(out + 7 * (s * B + b), xb, 7 * sizeof(double));
        }
    }
}
#endif

/* A twin rotor run as a job of units of 4 rotors (one SIMD vector each). */
typedef struct {
    const double *p;
    Py_ssize_t p_stride;
    double *x;
    const double *u;
    double *out;
    Py_ssize_t S, B;
    long n_sub;
    double h;
    int lock, square;
} trs_job;

static int trs_unit(const void *ctx, Py_ssize_t unit, void **scratch)
{
    const trs_job *J = (const trs_job *)ctx;
    (void)scratch;
    trs_group(J->p, J->p_stride, J->x, J->u, J->out, J->S, J->B, 4 * unit, J->n_sub, J->h,
              J->lock, J->square);
    return 0;
}

static PyObject *py_twin_rotor_run(PyObject *self, PyObject *args)
{
    PyObject *objs[4];
    Py_buffer bufs[4];
    int have[4] = {0};
    static const char *names[4] = {"params", "x", "u", "out"};
    long n_sub;
    double h;
    int lock, square, n_threads = 1;
    if (!PyArg_ParseTuple(args, "OOOOldpp|i", &objs[0], &objs[1], &objs[2], &objs[3], &n_sub, &h,
                          &lock, &square, &n_threads))
        return NULL;
    PyObject *result = NULL;
    for (int i = 0; i < 4; ++i) {
        if (objs[i] == Py_None) {
            if (i < 3) {
                PyErr_Format(PyExc_TypeError, "twin_rotor_run: %s is required", names[i]);
                goto done;
            }
            continue;
        }
        if (get_buffer(objs[i], &bufs[i], i == 1 || i == 3, names[i]) < 0) goto done;
        have[i] = 1;
        if (check_format(&bufs[i], "d", names[i]) < 0) goto done;
    }
    /* params (22,) shared by every rotor, or (B, 22): one row per rotor */
    const int rows = bufs[0].ndim == 2;
    if (!(bufs[0].ndim == 1 || rows) || bufs[0].shape[bufs[0].ndim - 1] != TRS_PARAMS ||
        bufs[1].ndim != 2 || (rows && bufs[0].shape[0] != bufs[1].shape[0]) ||
        bufs[1].shape[1] != 7 || bufs[2].ndim != 3 || bufs[2].shape[1] != bufs[1].shape[0] ||
        bufs[2].shape[2] != 2 || n_sub < 1) {
        PyErr_SetString(PyExc_ValueError, "twin_rotor_run: params (22,) or (B, 22), x (B, 7), "
                                          "u (S, B, 2), n_sub >= 1");
        goto done;
    }
    Py_ssize_t S = bufs[2].shape[0], B = bufs[1].shape[0];
    if (have[3] && (bufs[3].ndim != 3 || bufs[3].shape[0] != S || bufs[3].shape[1] != B ||
                    bufs[3].shape[2] != 7)) {
        PyErr_SetString(PyExc_ValueError, "twin_rotor_run: out must be (S, B, 7)");
        goto done;
    }
    const trs_job job = {
        (const double *)bufs[0].buf, rows ? TRS_PARAMS : 0, (double *)bufs[1].buf,
        (const double *)bufs[2].buf, have[3] ? (double *)bufs[3].buf : NULL, S, B, n_sub, h,
        lock, square,
    };
    Py_BEGIN_ALLOW_THREADS
    run_units(&job, trs_unit, (B + 3) / 4, n_threads < 1 ? 1 : n_threads);
    Py_END_ALLOW_THREADS
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < 4; ++i)
        if (have[i]) PyBuffer_Release(&bufs[i]);
    return result;
}

/* ------------------------------------------------------------------ numerator fit */
/* Variable projection of the simulation cost (flexid.costs.arx.ARXCost.fit_numerator): for
 * each denominator a (P, na), the b (P, nb) minimising sum_{t >= offset} (target(t - offset)
 * - y(t))^2 where y = g_0 + sum_j b_j g_j, g_0 the free response from state0 and g_j the
 * response to the regressor column reg[:, j - 1] from rest (all signals over t = 0..T-1).
 *
 * Per block of 4 candidates (one per lane): the nb + 1 recursions run together, each step
 * summed f(t) - a_na y(t - na) - ... - a_1 y(t - 1) in that order like ar_run (the nb + 1
 * independent chains hide the latency of each); then, in passes over the stored outputs,
 * the column norms s_j, the Gram matrix and right-hand side of the column-scaled regressors,
 * a Cholesky solve, and one step of iterative refinement with the residual recomputed from
 * the regressors: the normal equations of ARXCost._least_squares_rows, solved without
 * forming a (P, nb + 1, T) array.  ok[p] = 0 where the Cholesky factorisation breaks down
 * or the result is not finite (the caller solves those rows another way). */
#if defined(__GNUC__)
#define FIT_MAXNB 16

static inline __attribute__((always_inline)) void
fit_quad_impl(const double *a, Py_ssize_t a_stride, Py_ssize_t P, Py_ssize_t na,
              const double *reg, Py_ssize_t T, const double *state0, const double *target,
              Py_ssize_t offset, double *b_out, unsigned char *ok, Py_ssize_t q, v4d *hist,
              const int nb)
{
    const Py_ssize_t w = (P - q < 4) ? P - q : 4, K = T - offset, H = na + T;
    const int R = nb + 1;
    v4d A[AR_MAXNA];
    const v4d zero = {0, 0, 0, 0};
    for (Py_ssize_t i = 0; i < na; ++i) A[i] = zero;
    for (Py_ssize_t l = 0; l < 4; ++l)
        for (Py_ssize_t i = 0; i < na; ++i) A[i][l] = a[(q + (l < w ? l : 0)) * a_stride + i];
    /* hist[r * H + na + t] = g_r(t); the na rows before are the initial state */
    for (Py_ssize_t r = 0; r < R; ++r)
        for (Py_ssize_t i = 0; i < na; ++i) {
            const double s = r == 0 ? state0[i] : 0.0; /* y(-1 - i) */
            hist[r * H + na - 1 - i] = (v4d){s, s, s, s};
        }
    v4d acc[FIT_MAXNB + 1];
    for (Py_ssize_t t = 0; t < T; ++t) {
        const double *rt = reg + t * nb;
        acc[0] = zero;
        for (int r = 1; r < R; ++r) acc[r] = zero + rt[r - 1];
        for (Py_ssize_t k = na; k >= 1; --k) {
            const v4d ak = A[k - 1];
            const v4d *past = hist + na + t - k;
            for (int r = 0; r < R; ++r) acc[r] -= ak * past[r * H];
        }
        for (int r = 0; r < R; ++r) hist[r * H + na + t] = acc[r];
    }
    const v4d *g0 = hist + na + offset;
#define FIT_G(j) (hist + (j) * H + na + offset) /* column j (1..nb) over t >= offset */
    /* column norms; Gram matrix and right-hand side of the scaled columns */
    v4d sc[FIT_MAXNB], G[FIT_MAXNB][FIT_MAXNB], c[FIT_MAXNB], rhs[FIT_MAXNB];
    for (int i = 0; i < nb; ++i) {
        /* row i of the Gram matrix and rhs[i] in one pass, the sums in registers */
        const v4d *gi = FIT_G(i + 1);
        v4d s[FIT_MAXNB], sr = zero;
        for (int j = i; j < nb; ++j) s[j] = zero;
        for (Py_ssize_t t = 0; t < K; ++t) {
            const v4d v = gi[t];
            for (int j = i; j < nb; ++j) s[j] += v * FIT_G(j + 1)[t];
            sr += v * (target[t] - g0[t]);
        }
        for (int j = i; j < nb; ++j) G[i][j] = s[j];
        rhs[i] = sr;
    }
    for (Py_ssize_t i = 0; i < nb; ++i)
        for (int l = 0; l < 4; ++l) {
            const double d = sqrt(G[i][i][l]);
            sc[i][l] = d > 0 ? d : 1.0;
        }
    for (Py_ssize_t i = 0; i < nb; ++i) {
        rhs[i] /= sc[i];
        for (Py_ssize_t j = i; j < nb; ++j) G[i][j] /= sc[i] * sc[j];
    }
    /* Cholesky G = L L^T per lane, in place in the lower triangle (G[j][i], j >= i) */
    unsigned char good[4] = {1, 1, 1, 1};
    for (int l = 0; l < 4; ++l) {
        double L[FIT_MAXNB][FIT_MAXNB];
        for (Py_ssize_t i = 0; i < nb; ++i)
            for (Py_ssize_t j = 0; j <= i; ++j) L[i][j] = G[j][i][l];
        for (Py_ssize_t j = 0; j < nb && good[l]; ++j) {
            double d = L[j][j];
            for (Py_ssize_t k = 0; k < j; ++k) d -= L[j][k] * L[j][k];
            if (!(d > 0) || !isfinite(d)) {
                good[l] = 0;
                break;
            }
            d = sqrt(d);
            L[j][j] = d;
            for (Py_ssize_t i = j + 1; i < nb; ++i) {
                double v = L[i][j];
                for (Py_ssize_t k = 0; k < j; ++k) v -= L[i][k] * L[j][k];
                L[i][j] = v / d;
            }
        }
        for (Py_ssize_t i = 0; i < nb; ++i)
            for (Py_ssize_t j = 0; j <= i; ++j) G[i][j][l] = good[l] ? L[i][j] : (i == j);
    }
    /* solve L L^T x = v in place, every lane */
#define FIT_SOLVE(v)                                                                          \
    do {                                                                                      \
        for (Py_ssize_t i_ = 0; i_ < nb; ++i_) {                                              \
            v4d s_ = (v)[i_];                                                                 \
            for (Py_ssize_t k_ = 0; k_ < i_; ++k_) s_ -= G[i_][k_] * (v)[k_];                 \
            (v)[i_] = s_ / G[i_][i_];                                                         \
        }                                                                                     \
        for (Py_ssize_t i_ = nb - 1; i_ >= 0; --i_) {                                         \
            v4d s_ = (v)[i_];                                                                 \
            for (Py_ssize_t k_ = i_ + 1; k_ < nb; ++k_) s_ -= G[k_][i_] * (v)[k_];            \
            (v)[i_] = s_ / G[i_][i_];                                                         \
        }                                                                                     \
    } while (0)
    for (Py_ssize_t i = 0; i < nb; ++i) c[i] = rhs[i];
    FIT_SOLVE(c);
    /* refinement: the residual of the scaled problem, from the columns themselves */
    v4d cs[FIT_MAXNB], corr[FIT_MAXNB];
    for (Py_ssize_t i = 0; i < nb; ++i) {
        cs[i] = c[i] / sc[i];
        corr[i] = zero;
    }
    for (Py_ssize_t t = 0; t < K; ++t) {
        v4d e = target[t] - g0[t];
        for (Py_ssize_t j = 0; j < nb; ++j) e -= FIT_G(j + 1)[t] * cs[j];
        for (Py_ssize_t j = 0; j < nb; ++j) corr[j] += FIT_G(j + 1)[t] * e;
    }
    for (Py_ssize_t i = 0; i < nb; ++i) corr[i] /= sc[i];
    FIT_SOLVE(corr);
#undef FIT_SOLVE
#undef FIT_G
    for (Py_ssize_t l = 0; l < w; ++l) {
        int fine = good[l];
        for (Py_ssize_t i = 0; i < nb; ++i) {
            const double v = (c[i][l] + corr[i][l]) / sc[i][l];
            b_out[(q + l) * nb + i] = v;
            fine = fine && isfinite(v);
        }
        ok[q + l] = (unsigned char)fine;
    }
}

#define FIT_ARGS                                                                              \
    const double *a, Py_ssize_t a_stride, Py_ssize_t P, Py_ssize_t na, const double *reg,     \
        Py_ssize_t T, const double *state0, const double *target, Py_ssize_t offset,          \
        double *b_out, unsigned char *ok, Py_ssize_t q, v4d *hist
#define FIT_PASS a, a_stride, P, na, reg, T, state0, target, offset, b_out, ok, q, hist
typedef void (*fit_quad_fn)(FIT_ARGS);
/* one function per nb and instruction set (nb a constant: the sums stay in registers) */
#if defined(AR_X86)
#define FIT_QUAD(n)                                                                           \
    AR_TGT_G static void fit_quad_g##n(FIT_ARGS) { fit_quad_impl(FIT_PASS, n); }              \
    AR_TGT_V3 static void fit_quad_v3_##n(FIT_ARGS) { fit_quad_impl(FIT_PASS, n); }           \
    AR_TGT_V4 static void fit_quad_v4_##n(FIT_ARGS) { fit_quad_impl(FIT_PASS, n); }
#else
#define FIT_QUAD(n)                                                                           \
    static void fit_quad_g##n(FIT_ARGS) { fit_quad_impl(FIT_PASS, n); }
#endif
FIT_QUAD(1)
FIT_QUAD(2)
FIT_QUAD(3)
FIT_QUAD(4)
FIT_QUAD(5)
FIT_QUAD(6)
FIT_QUAD(7)
FIT_QUAD(8)
FIT_QUAD(9)
FIT_QUAD(10)
FIT_QUAD(11)
FIT_QUAD(12)
FIT_QUAD(13)
FIT_QUAD(14)
FIT_QUAD(15)
FIT_QUAD(16)
static const fit_quad_fn fit_quads_generic[FIT_MAXNB + 1] = AR_TABLE(fit_quad_g);
#if defined(AR_X86)
static const fit_quad_fn fit_quads_v3[FIT_MAXNB + 1] = AR_TABLE(fit_quad_v3_);
static const fit_quad_fn fit_quads_v4[FIT_MAXNB + 1] = AR_TABLE(fit_quad_v4_);
#endif

static fit_quad_fn fit_quad_for(int level, Py_ssize_t nb)
{
#if defined(AR_X86)
    if (level == 2) return fit_quads_v4[nb];
    if (level == 1) return fit_quads_v3[nb];
#endif
    (void)level;
    return fit_quads_generic[nb];
}

/* The arguments of fit_quad_fn for the blocks of one call. */
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

/* Block u of a numerator fit; the scratch holds its nb + 1 recursions. */
static int fit_unit(const void *ctx, Py_ssize_t u, void **scratch)
{
    const fit_ctx *c = (const fit_ctx *)ctx;
    if (!*scratch) {
        *scratch = malloc((size_t)((c->nb + 1) * (c->na + c->T)) * sizeof(v4d));
        if (!*scratch) return -1;
    }
    FLUSH_SUBNORMALS_BEGIN;
    c->fn(c->a, c->a_stride, c->P, c->na, c->reg, c->T, c->state0, c->target, c->offset,
          c->b_out, c->ok, 4 * u, (v4d *)*scratch);
    FLUSH_SUBNORMALS_END;
    return 0;
}

static PyObject *py_arx_fit(PyObject *self, PyObject *args)
{
    PyObject *objs[6];
    Py_buffer bufs[6];
    int have[6] = {0}, n_threads = 1;
    Py_ssize_t offset;
    if (!PyArg_ParseTuple(args, "OOOOnOO|i", &objs[0], &objs[1], &objs[2], &objs[3], &offset,
                          &objs[4], &objs[5], &n_threads))
        return NULL;
    static const char *names[6] = {"a", "reg", "state0", "target", "b_out", "ok_out"};
    PyObject *result = NULL;
    Py_ssize_t a_stride = get_rows(objs[0], &bufs[0], "arx_fit", "a");
    if (a_stride < 0) return NULL;
    have[0] = 1;
    for (int i = 1; i < 6; ++i) {
        if (get_buffer(objs[i], &bufs[i], i >= 4, names[i]) < 0) goto done;
        have[i] = 1;
        if (check_format(&bufs[i], i == 5 ? "B" : "d", names[i]) < 0) goto done;
    }
    const Py_ssize_t P = bufs[0].shape[0], na = bufs[0].shape[1];
    if (bufs[1].ndim != 2 || bufs[2].ndim != 1 || bufs[3].ndim != 1 || bufs[4].ndim != 2 ||
        bufs[5].ndim != 1) {
        PyErr_SetString(PyExc_ValueError, "arx_fit: wrong number of dimensions");
        goto done;
    }
    const Py_ssize_t T = bufs[1].shape[0], nb = bufs[1].shape[1], K = bufs[3].shape[0];
    if (na < 1 || na > AR_MAXNA || nb < 1 || nb > FIT_MAXNB || bufs[2].shape[0] != na ||
        offset < 0 || K != T - offset || K < 1 || bufs[4].shape[0] != P ||
        bufs[4].shape[1] != nb || bufs[5].shape[0] != P) {
        PyErr_SetString(PyExc_ValueError,
                        "arx_fit: a (P, na) with 1 <= na <= 16, reg (T, nb) with 1 <= nb <= "
                        "16, state0 (na,), target (T - offset,), b_out (P, nb), ok_out (P,)");
        goto done;
    }
    fit_ctx ctx = {(const double *)bufs[0].buf, a_stride, P, na, nb,
                   (const double *)bufs[1].buf, T, (const double *)bufs[2].buf,
                   (const double *)bufs[3].buf, offset, (double *)bufs[4].buf,
                   (unsigned char *)bufs[5].buf, fit_quad_for(ar_simd, nb)};
    int rc;
    Py_BEGIN_ALLOW_THREADS
    rc = run_units(&ctx, fit_unit, (P + 3) / 4, n_threads);
    Py_END_ALLOW_THREADS
    if (rc < 0) {
        PyErr_NoMemory();
        goto done;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < 6; ++i)
        if (have[i]) PyBuffer_Release(&bufs[i]);
    return result;
}

/* ------------------------------------------------------------------ numerator fit by shifts */
/* The least-squares problem of arx_fit when the regressor columns are one signal and its
 * delays, reg[t, j] = x(t - j) (one input; x(-1), ..., x(-(nb - 1)) are reg[0, 1 ..]), solved
 * from two recursions instead of nb + 1.  With v the response of 1/A to x and h its impulse
 * response, both from rest at t = 0 and zero before it, and S the delay by one sample:
 *
 *     g_j = S^j v + sum_{i = 1..j} x(-i) S^(j - i) h,     g_0(free) = sum_{l < na} c_l S^l h,
 *
 * the response to column j from rest (1/A is time-invariant: delaying v by j samples drops
 * the inputs x(-j), ..., x(-1), whose responses are delayed impulse responses) and the free
 * response from state0 (which is the response to the inputs c_l = -sum_{i > l} a_i y(l - i)
 * at t = l < na).  So every regressor is a fixed combination F = M E of the basis M = [S^j v
 * (j < nb), S^l h (l < L)], L = max(na, nb - 1) (0, and h not run, when the initial state and
 * x(-i) are all zero), whose Gram matrix and products with the target are sliding sums of
 * products: sum_{t >= offset} p(t - j) q(t - k) is the lag-(k - j) sum of p and q over the
 * window plus at most j terms at each end, so the (m + L)^2 products cost 3 (m + L) - 1 lag
 * sums per sample (m - 1 fewer over the whole window, see vp_solve_impl) instead of
 * (nb + 1)(na + nb) multiply-adds.  The normal equations of the
 * column-scaled regressors are then solved once by Cholesky (no refinement: the accuracy is
 * that of the normal equations, kappa(F)^2 times the rounding of the sums; a row is flagged
 * (ok = 0) where the bound kappa(Gs) T eps that bounds it exceeds tol, or the factorisation
 * breaks down), and when sse is given the plain recursion of ar_run runs at the solution
 * (AR_BLOCK_IMPL itself, so the sums of squares are those of arx_run for the same b).
 * With free_state the initial state is not given but fitted with b (MATLAB's estimated
 * initial condition): the coefficients c_l of S^l h, l < na, are unknowns beside b, which
 * makes the system m + na, and state0 is not used.  With d (P, nd + 1) the signal of each
 * candidate is D x (a Box-Jenkins or ARMAX predictor's regressors), and with targets each
 * has its own target; the pre-sample inputs of D x are not formed, so d needs them out of
 * the basis (L = 0, or free_state with nb - 1 <= na). */
#define VP_PAD 32                          /* zeros stored before each signal */
#define VP_TAIL 16                         /* samples of h run past T (>= nb - 1) */
#define VP_MAXNA 24 /* orders of A (BJ's C F reaches 18 at BJ(16, 2, 2, 16, 1)) */
#define VP_MAXB (FIT_MAXNB + VP_MAXNA) /* basis size m + L */

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

/* v and h of candidates q .. q + 3 (lanes past P repeat candidate q), by the transposed form
 * of ar_quad_impl (each y(t) summed f(t) - a_na y(t - na) - ... - a_1 y(t - 1)); the two
 * recursions are independent chains, so each hides the other's latency. */
static inline __attribute__((always_inline)) void
vp_rec_impl(const vp_ctx *c, Py_ssize_t q, v4d *v, v4d *h, const int na)
{
    const Py_ssize_t T = c->T, nb = c->nb, w = (c->P - q < 4) ? c->P - q : 4;
    const double *reg = c->reg;
    v4d A[VP_MAXNA], S[VP_MAXNA], R[VP_MAXNA], D[FIT_MAXNB];
    const v4d zero = {0, 0, 0, 0};
    const Py_ssize_t nd = c->d ? c->nd : 0;
    for (int i = 0; i < na; ++i) A[i] = zero;
    for (Py_ssize_t l = 0; l < 4; ++l)
        for (int i = 0; i < na; ++i) A[i][l] = c->a[(q + (l < w ? l : 0)) * c->a_stride + i];
    for (Py_ssize_t k = 0; k <= nd && c->d; ++k)
        for (Py_ssize_t l = 0; l < 4; ++l) D[k][l] = c->d[(q + (l < w ? l : 0)) * c->d_stride + k];
    /* the input of sample t: x(t), or sum_k d_k x(t - k) with x(-i) = reg[0, i] (nd < nb) */
#define VP_X(t) ((t) >= 0 ? reg[(t) * nb] : reg[-(t)])
#define VP_IN(t, out)                                                                         \
    do {                                                                                      \
        if (c->d) {                                                                           \
            v4d s_ = zero;                                                                    \
            for (Py_ssize_t k_ = 0; k_ <= nd; ++k_) s_ += D[k_] * VP_X((t) - k_);             \
            out = s_;                                                                         \
        } else {                                                                              \
            out = zero + VP_X(t);                                                             \
        }                                                                                     \
    } while (0)
    for (int k = 0; k < na; ++k) {
        if (k < T) VP_IN(k, S[k]); else S[k] = zero;
        R[k] = zero + (k == 0 ? 1.0 : 0.0);
    }
    if (c->L) {
        for (Py_ssize_t t = 0; t < T; ++t) {
            const v4d ys = S[0], yr = R[0];
            v[t] = ys;
            h[t] = yr;
            for (int k = 0; k < na - 1; ++k) {
                S[k] = S[k + 1] - A[k] * ys;
                R[k] = R[k + 1] - A[k] * yr;
            }
            v4d f = zero;
            if (t + na < T) VP_IN(t + na, f);
            S[na - 1] = f - A[na - 1] * ys;
            R[na - 1] = zero - A[na - 1] * yr;
        }
        for (Py_ssize_t t = T; t < T + VP_TAIL; ++t) { /* h past the window: end terms */
            const v4d yr = R[0];
            h[t] = yr;
            for (int k = 0; k < na - 1; ++k) R[k] = R[k + 1] - A[k] * yr;
            R[na - 1] = zero - A[na - 1] * yr;
        }
        return;
    }
    for (Py_ssize_t t = 0; t < T; ++t) { /* no delays of h in the basis: v alone */
        const v4d ys = S[0];
        v[t] = ys;
        for (int k = 0; k < na - 1; ++k) S[k] = S[k + 1] - A[k] * ys;
        v4d f = zero;
        if (t + na < T) VP_IN(t + na, f);
        S[na - 1] = f - A[na - 1] * ys;
    }
#undef VP_IN
#undef VP_X
}

/* acc[d] = sum_{s0 <= s < s1} lead(s) other(s - d), d < ND, in 4 lanes (lead a vector
 * signal, or a scalar one shared by the lanes); even and odd s in separate sums, so that
 * 2 ND independent chains hide the latency of each multiply-add */
#define VP_CORR(ND, LEAD)                                                                     \
    do {                                                                                      \
        v4d s_[ND], r_[ND];                                                                   \
        for (int d_ = 0; d_ < (ND); ++d_) s_[d_] = r_[d_] = zero;                             \
        Py_ssize_t t_ = s0;                                                                   \
        for (; t_ + 2 <= s1; t_ += 2) {                                                       \
            const v4d l_ = LEAD;                                                              \
            const v4d *o_ = other + t_;                                                       \
            ++t_;                                                                             \
            const v4d m_ = LEAD;                                                              \
            --t_;                                                                             \
            for (int d_ = 0; d_ < (ND); ++d_) {                                               \
                s_[d_] += l_ * o_[-d_];                                                       \
                r_[d_] += m_ * o_[1 - d_];                                                    \
            }                                                                                 \
        }                                                                                     \
        if (t_ < s1) {                                                                        \
            const v4d l_ = LEAD;                                                              \
            const v4d *o_ = other + t_;                                                       \
            for (int d_ = 0; d_ < (ND); ++d_) s_[d_] += l_ * o_[-d_];                         \
        }                                                                                     \
        for (int d_ = 0; d_ < (ND); ++d_) acc[d_] = s_[d_] + r_[d_];                          \
    } while (0)

static inline __attribute__((always_inline)) void
vp_lags(const v4d *lead, const double *slead, Py_ssize_t lead_off, const v4d *other,
        Py_ssize_t s0, Py_ssize_t s1, Py_ssize_t n, v4d *out)
{
    const v4d zero = {0, 0, 0, 0};
    /* at most 8 sums at a time: with the lead and an operand they fit 16 registers */
    for (Py_ssize_t g = 0; g < n; g += 8, other -= 8) {
        v4d *acc = out + g;
        const Py_ssize_t k = n - g < 8 ? n - g : 8;
#define VP_CASE(ND)                                                                           \
    case ND:                                                                                  \
        if (lead)                                                                             \
            VP_CORR(ND, lead[t_]);                                                            \
        else                                                                                  \
            VP_CORR(ND, zero + slead[t_ - lead_off]);                                         \
        break;
        switch (k) {
            VP_CASE(1)
            VP_CASE(2)
            VP_CASE(3)
            VP_CASE(4)
            VP_CASE(5)
            VP_CASE(6)
            VP_CASE(7)
            VP_CASE(8)
        }
#undef VP_CASE
    }
}

/* The lag sums, the normal equations in the basis M, their Cholesky solve and the flag.
 * work holds G_M (VP_MAXB^2) and G_M E (VP_MAXB x FIT_MAXNB) */
static inline __attribute__((always_inline)) void
vp_solve_impl(const vp_ctx *c, Py_ssize_t q, const v4d *v, const v4d *h, v4d *work)
{
    const Py_ssize_t T = c->T, o = c->offset, m = c->nb, L = c->L, na = c->na, n = m + L;
    const Py_ssize_t w = (c->P - q < 4) ? c->P - q : 4;
    const double *pre = c->reg; /* pre[i] = x(-i), 1 <= i < m */
    const v4d zero = {0, 0, 0, 0};
    v4d Rvv[FIT_MAXNB], Rhv[FIT_MAXNB], Rtv[FIT_MAXNB], Rvh[VP_MAXNA + FIT_MAXNB],
        Rhh[VP_MAXNA + FIT_MAXNB], Rth[VP_MAXNA + FIT_MAXNB];
    v4d *tv = NULL; /* per-candidate targets, lane by lane, at their times o .. T - 1 */
    if (c->targets) {
        tv = work + VP_MAXB * (VP_MAXB + FIT_MAXNB);
        for (Py_ssize_t t = o; t < T; ++t)
            for (Py_ssize_t l = 0; l < 4; ++l)
                tv[t][l] = c->targets[(q + (l < w ? l : 0)) * c->t_stride + t - o];
    }
    vp_lags(v, NULL, 0, v, o, T, m, Rvv);
    vp_lags(tv, c->target, o, v, o, T, m, Rtv);
    /* Over the whole window (o = 0), A h = delta gives the sums of h with delays of v past
     * it without lag sums: with c(k) = sum_s h(s) v(s + k) (c(k) = Rvh[k] for k >= 0, Rhv[-k]
     * for k < 0) and X(k) = sum_{T <= s < T - k} h(s) v(s + k) (the terms past the window),
     *     c(k) = -X(k) - sum_{i = 1..na} a_i (c(k + i) + X(k + i)),   k = -1, -2, ...,
     * the recursion of 1/A itself, run from Rvh[0 .. na - 1] (L >= na).  (The sums of h with
     * itself follow from Yule-Walker equations too, but those lose accuracy as the poles near
     * the unit circle: their matrix's inverse grows like sum h^2.) */
    const int cont = L && o == 0;
    if (L) {
        if (!cont) vp_lags(h, NULL, 0, v - 1, o, T, m - 1, Rhv + 1); /* lags 1 .. m - 1 */
        vp_lags(v, NULL, 0, h, o, T, L, Rvh);
        vp_lags(h, NULL, 0, h, o, T, L, Rhh);
        vp_lags(tv, c->target, o, h, o, T, L, Rth);
    }
    if (cont) {
        v4d Av[VP_MAXNA];
        for (Py_ssize_t i = 0; i < na; ++i)
            for (Py_ssize_t e = 0; e < 4; ++e)
                Av[i][e] = c->a[(q + (e < w ? e : 0)) * c->a_stride + i];
        /* index k + m - 1 holds lag k, k = -(m - 1) .. na - 1 */
        v4d C[VP_MAXNA + FIT_MAXNB], X[VP_MAXNA + FIT_MAXNB];
        const Py_ssize_t z = m - 1;
        for (Py_ssize_t k = -z; k < na; ++k) {
            v4d sx = zero;
            for (Py_ssize_t s = T; s < T - k; ++s) sx += h[s] * v[s + k];
            X[k + z] = sx;
            if (k >= 0) C[k + z] = Rvh[k];
        }
        for (Py_ssize_t k = -1; k >= -z; --k) {
            v4d acc = zero - X[k + z];
            for (Py_ssize_t i = 1; i <= na; ++i)
                acc -= Av[i - 1] * (C[k + i + z] + X[k + i + z]);
            C[k + z] = acc;
            Rhv[-k] = acc;
        }
    }
    v4d(*GM)[VP_MAXB] = (v4d(*)[VP_MAXB])work;
    v4d(*GE)[FIT_MAXNB] = (v4d(*)[FIT_MAXNB])(work + VP_MAXB * VP_MAXB);
    /* G_M: basis b < m is S^b v, b >= m is S^(b - m) h.  The entry of (p, j) and (q, j + d)
     * is the lag-d sum over the window [o - j, T - j) in the time of p: the sum over [o, T)
     * plus the terms before o and minus those from T - j on, which grow by one at each end
     * from j to j + 1 along a diagonal. */
    for (int pq = 0; pq < 4; ++pq) {
        const int p = pq & 1, r = pq >> 1; /* (v,v) (h,v) (v,h) (h,h) */
        const Py_ssize_t np = p ? L : m, nq = r ? L : m;
        const v4d *ps = p ? h : v, *qs = r ? h : v;
        for (Py_ssize_t d = (p && !r) ? 1 : 0; d < nq; ++d) {
            const v4d base = p == r ? (p ? Rhh[d] : Rvv[d]) : p ? Rhv[d] : Rvh[d];
            v4d corr = zero;
            for (Py_ssize_t j = 0; j < np && j + d < nq; ++j) {
                if (j) corr += ps[o - j] * qs[o - j - d] - ps[T - j] * qs[T - j - d];
                const Py_ssize_t b1 = p * m + j, b2 = r * m + j + d;
                GM[b1][b2] = GM[b2][b1] = base + corr;
            }
        }
    }
    /* Unknowns: b, then (nfree > 0) the coefficients of S^l h, l < na, which span the free
     * responses from any initial state; the pre-sample inputs' S^l h with l < na are then in
     * that span, so E keeps only those with l >= nfree. */
    const Py_ssize_t nfree = c->nfree, nn = m + nfree;
    /* F = M E: E = identity on the v part, E[m + l][j] = x(-(j - l)) for nfree <= l < j */
    for (Py_ssize_t b = 0; b < n; ++b)
        for (Py_ssize_t k = 0; k < m; ++k) {
            v4d s = GM[b][k];
            for (Py_ssize_t l = nfree; l < k && L; ++l) s += GM[b][m + l] * pre[k - l];
            GE[b][k] = s;
        }
    /* free response coefficients c_l (per lane) and u = M^T target - G_M c */
    v4d cl[VP_MAXNA], u[VP_MAXB];
    for (Py_ssize_t l = 0; l < na && L && !nfree; ++l) {
        v4d s = zero;
        for (Py_ssize_t i = l + 1; i <= na; ++i) {
            v4d ai = zero;
            for (Py_ssize_t e = 0; e < 4; ++e)
                ai[e] = c->a[(q + (e < w ? e : 0)) * c->a_stride + i - 1];
            s -= ai * c->state0[i - l - 1];
        }
        cl[l] = s;
    }
    for (Py_ssize_t b = 0; b < n; ++b) {
        v4d s = b < m ? Rtv[b] : Rth[b - m];
        for (Py_ssize_t l = 0; l < na && L && !nfree; ++l) s -= GM[b][m + l] * cl[l];
        u[b] = s;
    }
    v4d G[VP_MAXB][VP_MAXB], rhs[VP_MAXB], sc[VP_MAXB], cf[VP_MAXB];
    for (Py_ssize_t j = 0; j < m; ++j) {
        v4d r = u[j];
        for (Py_ssize_t l = nfree; l < j && L; ++l) r += u[m + l] * pre[j - l];
        rhs[j] = r;
        for (Py_ssize_t k = j; k < m; ++k) {
            v4d s = GE[j][k];
            for (Py_ssize_t l = nfree; l < j && L; ++l) s += GE[m + l][k] * pre[j - l];
            G[j][k] = s;
        }
    }
    for (Py_ssize_t i = 0; i < nfree; ++i) { /* rows of the free coefficients: (E^T G_M)[m + i] */
        rhs[m + i] = u[m + i];
        for (Py_ssize_t k = 0; k < m; ++k) G[k][m + i] = GE[m + i][k];
        for (Py_ssize_t k = i; k < nfree; ++k) G[m + i][m + k] = GM[m + i][m + k];
    }
    for (Py_ssize_t i = 0; i < nn; ++i)
        for (int l = 0; l < 4; ++l) {
            const double d = G[i][i][l] > 0 ? sqrt(G[i][i][l]) : 0.0;
            sc[i][l] = d > 0 ? d : 1.0;
        }
    for (Py_ssize_t i = 0; i < nn; ++i) {
        rhs[i] /= sc[i];
        for (Py_ssize_t j = i; j < nn; ++j) G[i][j] /= sc[i] * sc[j];
    }
    /* Cholesky in every lane at once (a lane whose pivot is not positive is marked and goes
     * on with 1); kappa(Gs) <= ||Gs||_F ||L^-1||_F^2 */
    v4d Lc[VP_MAXB][VP_MAXB], gf = zero, inv2 = zero;
    int bad[4] = {0, 0, 0, 0};
    for (Py_ssize_t i = 0; i < nn; ++i)
        for (Py_ssize_t j = 0; j <= i; ++j) {
            Lc[i][j] = G[j][i];
            gf += (i == j ? 1.0 : 2.0) * Lc[i][j] * Lc[i][j];
        }
    for (Py_ssize_t j = 0; j < nn; ++j) {
        v4d d = Lc[j][j];
        for (Py_ssize_t k = 0; k < j; ++k) d -= Lc[j][k] * Lc[j][k];
        for (int l = 0; l < 4; ++l) {
            if (!(d[l] > 0) || !isfinite(d[l])) {
                bad[l] = 1;
                d[l] = 1.0;
            } else {
                d[l] = sqrt(d[l]);
            }
        }
        Lc[j][j] = d;
        for (Py_ssize_t i = j + 1; i < nn; ++i) {
            v4d t = Lc[i][j];
            for (Py_ssize_t k = 0; k < j; ++k) t -= Lc[i][k] * Lc[j][k];
            Lc[i][j] = t / d;
        }
    }
    for (Py_ssize_t i = 0; i < nn; ++i) {
        v4d t = rhs[i];
        for (Py_ssize_t k = 0; k < i; ++k) t -= Lc[i][k] * cf[k];
        cf[i] = t / Lc[i][i];
    }
    for (Py_ssize_t i = nn - 1; i >= 0; --i) {
        v4d t = cf[i];
        for (Py_ssize_t k = i + 1; k < nn; ++k) t -= Lc[k][i] * cf[k];
        cf[i] = t / Lc[i][i];
    }
    for (Py_ssize_t col = 0; col < nn; ++col) { /* ||L^-1||_F^2, column by column */
        v4d zc[VP_MAXB];
        for (Py_ssize_t i = col; i < nn; ++i) {
            v4d t = zero + (i == col ? 1.0 : 0.0);
            for (Py_ssize_t k = col; k < i; ++k) t -= Lc[i][k] * zc[k];
            zc[i] = t / Lc[i][i];
            inv2 += zc[i] * zc[i];
        }
    }
    for (int l = 0; l < w; ++l) {
        int good = !bad[l] && sqrt(gf[l]) * inv2[l] * (double)T * 2.220446049250313e-16 <= c->tol;
        for (Py_ssize_t i = 0; i < m; ++i) {
            const double b = good ? cf[i][l] / sc[i][l] : 0.0;
            c->b_out[(q + l) * m + i] = b;
            good = good && isfinite(b);
        }
        c->ok[q + l] = (unsigned char)good;
    }
}

#if defined(AR_X86)
#define VP_REC(n)                                                                             \
    AR_TGT_G static void vp_rec_g##n(const vp_ctx *c, Py_ssize_t q, v4d *v, v4d *h)           \
    {                                                                                         \
        vp_rec_impl(c, q, v, h, n);                                                           \
    }                                                                                         \
    AR_TGT_V3 static void vp_rec_v3_##n(const vp_ctx *c, Py_ssize_t q, v4d *v, v4d *h)        \
    {                                                                                         \
        vp_rec_impl(c, q, v, h, n);                                                           \
    }                                                                                         \
    AR_TGT_V4 static void vp_rec_v4_##n(const vp_ctx *c, Py_ssize_t q, v4d *v, v4d *h)        \
    {                                                                                         \
        vp_rec_impl(c, q, v, h, n);                                                           \
    }
AR_TGT_G static void vp_solve_g(const vp_ctx *c, Py_ssize_t q, const v4d *v, const v4d *h, v4d *w)
{
    vp_solve_impl(c, q, v, h, w);
}
AR_TGT_V3 static void vp_solve_v3(const vp_ctx *c, Py_ssize_t q, const v4d *v, const v4d *h,
                                  v4d *w)
{
    vp_solve_impl(c, q, v, h, w);
}
AR_TGT_V4 static void vp_solve_v4(const vp_ctx *c, Py_ssize_t q, const v4d *v, const v4d *h,
                                  v4d *w)
{
    vp_solve_impl(c, q, v, h, w);
}
#else
#define VP_REC(n)                                                                             \
    static void vp_rec_g##n(const vp_ctx *c, Py_ssize_t q, v4d *v, v4d *h)                    \
    {                                                                                         \
        vp_rec_impl(c, q, v, h, n);                                                           \
    }
static void vp_solve_g(const vp_ctx *c, Py_ssize_t q, const v4d *v, const v4d *h, v4d *w)
{
    vp_solve_impl(c, q, v, h, w);
}
#endif
VP_REC(1)
VP_REC(2)
VP_REC(3)
VP_REC(4)
VP_REC(5)
VP_REC(6)
VP_REC(7)
VP_REC(8)
VP_REC(9)
VP_REC(10)
VP_REC(11)
VP_REC(12)
VP_REC(13)
VP_REC(14)
VP_REC(15)
VP_REC(16)
VP_REC(17)
VP_REC(18)
VP_REC(19)
VP_REC(20)
VP_REC(21)
VP_REC(22)
VP_REC(23)
VP_REC(24)
static const vp_rec_fn vp_recs_generic[VP_MAXNA + 1] = AR_TABLE24(vp_rec_g);
#if defined(AR_X86)
static const vp_rec_fn vp_recs_v3[VP_MAXNA + 1] = AR_TABLE24(vp_rec_v3_);
static const vp_rec_fn vp_recs_v4[VP_MAXNA + 1] = AR_TABLE24(vp_rec_v4_);
#endif

/* Block u: the two recursions into the scratch (2 (VP_PAD + T + VP_TAIL) vectors, zeros first, then
 * the work of vp_solve_impl), the solve, and the plain recursion at the solution. */
static int vp_unit(const void *ctx, Py_ssize_t u, void **scratch)
{
    const vp_ctx *c = (const vp_ctx *)ctx;
    const Py_ssize_t span = VP_PAD + c->T + VP_TAIL;
    if (!*scratch) {
        const size_t nv = (size_t)(2 * span + VP_MAXB * (VP_MAXB + FIT_MAXNB) + c->T);
        *scratch = calloc(nv, sizeof(v4d)); /* the leading zeros stay zero */
        if (!*scratch) return -1;
    }
    v4d *base = (v4d *)*scratch, *v = base + VP_PAD, *h = base + span + VP_PAD;
    const Py_ssize_t q = 4 * u;
    {
        FLUSH_SUBNORMALS_BEGIN;
        c->rec(c, q, v, h);
        c->solve(c, q, v, h, base + 2 * span);
        FLUSH_SUBNORMALS_END;
    }
    if (c->sse) {
        ar_job J = {0};
        J.a = c->a;
        J.a_stride = c->a_stride;
        J.b = c->b_out;
        J.b_stride = c->nb;
        J.reg = c->reg;
        J.state = c->state0;
        J.target = c->target;
        J.sse = c->sse;
        J.P = c->P;
        J.na = c->na;
        J.nb = c->nb;
        J.K = c->T;
        ar_quads[c->na](&J, q);
    }
    return 0;
}

static PyObject *py_arx_fit_shifted(PyObject *self, PyObject *args)
{
    PyObject *objs[9] = {NULL};
    Py_buffer bufs[9];
    int have[9] = {0}, n_threads = 1, free_state = 0;
    Py_ssize_t offset, L;
    double tol;
    objs[7] = objs[8] = Py_None;
    if (!PyArg_ParseTuple(args, "OOOOnndOOO|iiOO", &objs[0], &objs[1], &objs[2], &objs[3],
                          &offset, &L, &tol, &objs[4], &objs[5], &objs[6], &n_threads,
                          &free_state, &objs[7], &objs[8]))
        return NULL;
    static const char *names[9] = {"a",     "reg",    "state0",  "target", "b_out",
                                   "ok_out", "sse_out", "d", "targets"};
    PyObject *result = NULL;
    Py_ssize_t a_stride = get_rows(objs[0], &bufs[0], "arx_fit_shifted", "a");
    if (a_stride < 0) return NULL;
    have[0] = 1;
    for (int i = 1; i < 9; ++i) {
        if (i >= 6 && objs[i] == Py_None) continue;
        if (get_buffer(objs[i], &bufs[i], i >= 4 && i <= 6, names[i]) < 0) goto done;
        have[i] = 1;
        if (check_format(&bufs[i], i == 5 ? "B" : "d", names[i]) < 0) goto done;
    }
    const Py_ssize_t P = bufs[0].shape[0], na = bufs[0].shape[1];
    if (bufs[1].ndim != 2 || bufs[2].ndim != 1 || bufs[3].ndim != 1 || bufs[4].ndim != 2 ||
        bufs[5].ndim != 1 || (have[6] && bufs[6].ndim != 1)) {
        PyErr_SetString(PyExc_ValueError, "arx_fit_shifted: wrong number of dimensions");
        goto done;
    }
    const Py_ssize_t T = bufs[1].shape[0], nb = bufs[1].shape[1], K = bufs[3].shape[0];
    const Py_ssize_t Lmin = na > nb - 1 ? na : nb - 1;
    if (na < 1 || na > VP_MAXNA || nb < 1 || nb > FIT_MAXNB || bufs[2].shape[0] != na ||
        offset < 0 || K != T - offset || K < 1 || bufs[4].shape[0] != P ||
        bufs[4].shape[1] != nb || bufs[5].shape[0] != P || (L != 0 && L != Lmin) ||
        (have[6] && (bufs[6].shape[0] != P || offset != 0)) ||
        (free_state && (L != Lmin || have[6])) ||
        (have[7] && (bufs[7].ndim != 2 || bufs[7].shape[0] != P || bufs[7].shape[1] < 1 ||
                     bufs[7].shape[1] > nb || have[6] || (L && !(free_state && nb - 1 <= na)) ||
                     bufs[7].strides[1] != sizeof(double))) ||
        (have[8] && (bufs[8].ndim != 2 || bufs[8].shape[0] != P || bufs[8].shape[1] != K ||
                     have[6] || bufs[8].strides[1] != sizeof(double)))) {
        PyErr_SetString(PyExc_ValueError,
                        "arx_fit_shifted: a (P, na) with 1 <= na <= 24, reg (T, nb) with 1 <= "
                        "nb <= 16, state0 (na,), target (T - offset,), L 0 or max(na, nb - 1) "
                        "(the latter with free_state), b_out (P, nb), ok_out (P,), sse_out "
                        "(P,) with offset 0 and without free_state, or None; d (P, nd + 1) "
                        "with nd < nb, with L 0 or free_state and nb - 1 <= na; targets (P, "
                        "T - offset); neither with sse_out");
        goto done;
    }
    vp_ctx ctx = {(const double *)bufs[0].buf, a_stride, P, na, nb, L,
                  (const double *)bufs[1].buf, T, (const double *)bufs[2].buf,
                  (const double *)bufs[3].buf, offset, (double *)bufs[4].buf,
                  (unsigned char *)bufs[5].buf, have[6] ? (double *)bufs[6].buf : NULL, tol,
                  free_state ? na : 0,
                  have[7] ? (const double *)bufs[7].buf : NULL,
                  have[8] ? (const double *)bufs[8].buf : NULL,
                  have[7] ? bufs[7].strides[0] / (Py_ssize_t)sizeof(double) : 0,
                  have[7] ? bufs[7].shape[1] - 1 : 0,
                  have[8] ? bufs[8].strides[0] / (Py_ssize_t)sizeof(double) : 0,
                  vp_recs_generic[na], vp_solve_g};
#if defined(AR_X86)
    if (ar_simd == 2) ctx.rec = vp_recs_v4[na], ctx.solve = vp_solve_v4;
    if (ar_simd == 1) ctx.rec = vp_recs_v3[na], ctx.solve = vp_solve_v3;
#endif
    int rc;
    Py_BEGIN_ALLOW_THREADS
    rc = run_units(&ctx, vp_unit, (P + 3) / 4, n_threads);
    Py_END_ALLOW_THREADS
    if (rc < 0) {
        PyErr_NoMemory();
        goto done;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < 9; ++i)
        if (have[i]) PyBuffer_Release(&bufs[i]);
    return result;
}
#endif

static PyObject *py_simd(PyObject *self, PyObject *args)
{
    const char *name = NULL;
    if (!PyArg_ParseTuple(args, "|z", &name)) return NULL;
    if (name) {
        int level = -1;
        for (int i = 0; i <= ar_simd_best; ++i)
            if (strcmp(name, ar_simd_names[i]) == 0) level = i;
        if (level < 0) {
            PyErr_Format(PyExc_ValueError, "simd: %s is not one this CPU runs (best: %s)",
                         name, ar_simd_names[ar_simd_best]);
            return NULL;
        }
        ar_simd_select(level);
    }
    return Py_BuildValue("(ss)", ar_simd_names[ar_simd], ar_simd_names[ar_simd_best]);
}

#if defined(__GNUC__)
static PyObject *py_free_fit(PyObject *self, PyObject *args); /* defined at the end */
#endif

static PyMethodDef methods[] = {
    {"poly_mul", py_poly_mul, METH_VARARGS,
     "poly_mul(p, q, out): row-wise polynomial products of p (P, a) and q (P, b) into out."},
    {"schur_cohn", py_schur_cohn, METH_VARARGS,
     "schur_cohn(a, out): strict stability of monic denominators a (P, n) into out (P,) uint8."},
    {"ar_run", py_ar_run, METH_VARARGS,
     "ar_run(a, forced, state, target, y_out, sse_out[, threads]): batched AR recursion "
     "(see module)."},
    {"arx_run", py_arx_run, METH_VARARGS,
     "arx_run(a, b, reg, state, target, y_out, sse_out[, threads[, first]]): batched ARX "
     "recursion, the input part computed from the regressor rows reg, sse over t >= first "
     "(see module)."},
    {"twin_rotor_run", py_twin_rotor_run, METH_VARARGS,
     "twin_rotor_run(params, x, u, out, n_sub, h, lock_yaw, square_law[, threads]): twin rotor RK4; "
     "params (22,) shared or (B, 22) per rotor."},
#if defined(__GNUC__)
    {"arx_fit", py_arx_fit, METH_VARARGS,
     "arx_fit(a, reg, state0, target, offset, b_out, ok_out[, threads]): least-squares "
     "numerators of the simulation cost for denominators a (see the module)."},
    {"arx_fit_shifted", py_arx_fit_shifted, METH_VARARGS,
     "arx_fit_shifted(a, reg, state0, target, offset, L, tol, b_out, ok_out, sse_out"
     "[, threads[, free_state[, d, targets]]]): arx_fit for regressor columns that are delays of one signal, from two "
     "recursions and lag sums (see the module)."},
#endif
#if defined(__GNUC__)
    {"free_fit", py_free_fit, METH_VARARGS,
     "free_fit(a, num, reg, target, basis, energies, window, cancel, errors_out, sse_out, "
     "coef_out"
     "[, threads]): errors of 1/den filters with the initial state fitted (see the end of "
     "the module)."},
#endif
    {"simd", py_simd, METH_VARARGS,
     "simd([name]): (in use, best) instruction sets of ar_run/arx_run; with a name ('generic', "
     "'avx2', 'avx512'), run that one from now on (tests, benchmarks)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_kernels",
    "Compiled inner loops of flexid's batched ARX costs (optional; see flexid.kernels).", -1,
    methods,
};

PyMODINIT_FUNC PyInit__kernels(void)
{
#if defined(FLEXID_THREADS)
    pthread_atfork(NULL, NULL, pool_after_fork);
#endif
    ar_simd_detect();
    ar_simd_select(ar_simd_best);
    return PyModule_Create(&module);
}

/* ------------------------------------------------------------------ estimated initial state */
/* free_fit(a, num, reg, target, basis, energies, window, cancel, errors_out, sse_out,
 * coef_out[, threads]): the error of 1/den filters with the initial state fitted by least squares
 * (flexid.kernels.initial_state_fit, whose docstring gives the method).  a (P, n) the
 * a_1..a_n of each den, num (P, nb) rows some stride apart, reg (K, nb), target (K,),
 * basis (P, n, n) the numerators P_m, energies (P, n) the energies of P_m/den over t >= 0
 * (both None: computed here by the step-down of each den, free_stepdown), window the
 * samples L of the basis windows, errors_out (P, K) or None, sse_out (P,), coef_out (P, n).
 * sse_out is NaN where a Cholesky factorisation or the step-down breaks down.  Without
 * errors_out, a block whose fits all leave at least cancel |e|^2 takes the sums of squares
 * as |e|^2 - c.r (the normal equations' identity, flexid.kernels.FREE_CANCEL) instead of
 * running the fitted free response.  With first (P, n) and noise (P, 4), the error from rest
 * is a cascade: e = (D / C)(target - f / F), F = 1 + first_1 q^-1 + ... (zeros past its
 * order), D / C of order 2 at most (noise: c_1, c_2, d_1, d_2), and a = C F: fewer
 * multiply-adds than the one filter (D F y - D B u) / (C F) of Box-Jenkins, whose free
 * responses it spans (so the fitted errors are the same).
 *
 * Per block of 4 candidates (one per lane), four recursions of 1/den in the transposed
 * direct form with the state in registers: the error from rest e (input part computed here
 * from reg), the impulse response h over K + L samples (or until what is left of it
 * cannot matter), the anti-causal recursion over e
 * (the right-hand side), and the fitted free response, removed from e; then the small
 * algebra of the normalised basis on 4 lanes at once. */
/* The estimated initial state is compiled at -O2 on every instruction set: -O3 makes it no
 * faster (measured, OE and BJ of order 16 at K = 1,500) and doubles the build's time. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC push_options
#pragma GCC optimize("O2")
#endif
#if defined(__GNUC__)
#define FREE_MAXN 24
/* |S_K|_F^2 (the basis normalised to unit energy, over the window after the record) below
 * which the kernel takes the record's Gram matrix as I, leaving out the tail Q Q^T:
 * |Q Q^T| <= |S_K|_F^2 / lambda_min(S_0 S_0^T), and lambda_min >= 0.45 where the basis has
 * decayed that far (measured, and checked by the tests: the window of FREE_WINDOW n samples
 * then holds nearly all of the unit energy), so |Q Q^T| < 2.3e-17, a tenth of eps */
#define FREE_TAIL 1e-17

/* y(t) = f(t) + z_0, z_k <- z_(k+1) - a_(k+1) y(t), z_(n-1) <- -a_n y(t): one step of the
 * recursion with the state Z in registers */
#define FREE_STEP(Z, A, f, yt, n)                                                             \
    do {                                                                                      \
        (yt) = (f) + (Z)[0];                                                                  \
        _Pragma("GCC unroll 24") for (int k_ = 0; k_ < (n) - 1; ++k_)                         \
            (Z)[k_] = (Z)[k_ + 1] - (A)[k_] * (yt);                                           \
        (Z)[(n) - 1] = -(A)[(n) - 1] * (yt);                                                  \
    } while (0)

/* G[m] = sum_(i <= m) T[m, i] h(t - i) for every m, H pointing at h(t) and h(t - i) taken as 0
 * for i > t: the sum of each m in the order of i, the n sums side by side in registers
 * (independent chains; n is a constant, so the loops unroll) */
#define FREE_WINDOW_SAMPLE(G, H, t, n)                                                        \
    do {                                                                                      \
        _Pragma("GCC unroll 24") for (int m_ = 0; m_ < (n); ++m_) (G)[m_] = zero;             \
        _Pragma("GCC unroll 24") for (int i_ = 0; i_ < (n); ++i_) {                           \
            const v4d h_ = i_ <= (t) ? (H)[-i_] : zero;                                       \
            _Pragma("GCC unroll 24") for (int m_ = i_; m_ < (n); ++m_)                        \
                (G)[m_] += T[m_ * (n) + i_] * h_;                                             \
        }                                                                                     \
    } while (0)

/* Steps s = S0 .. S1 - 1 of the recursion FREE_STEP(Z, A, F(s), yt, n), each followed by
 * BODY(s, yt) (F and BODY function-like macros).  With rounds (32 registers), n steps at a
 * time with the state's registers renamed rather than moved: in step r of a round the Z[k]
 * of FREE_STEP is Z[(k + r) % n], so each update subtracts in place and the slot of Z[0]
 * takes the new last entry (the same operations); after a whole round the names are back. */
#define FREE_REC(Z, A, n, rounds, S0, S1, F, BODY)                                            \
    do {                                                                                      \
        Py_ssize_t s_ = (S0);                                                                 \
        for (; (rounds) && s_ + (n) <= (S1); s_ += (n)) {                                     \
            _Pragma("GCC unroll 24") for (int r_ = 0; r_ < (n); ++r_) {                       \
                const v4d yr_ = F(s_ + r_) + (Z)[r_];                                         \
                _Pragma("GCC unroll 24") for (int k_ = 0; k_ < (n) - 1; ++k_)                 \
                    (Z)[(k_ + 1 + r_) % (n)] -= (A)[k_] * yr_;                                \
                (Z)[r_] = zero - (A)[(n) - 1] * yr_; /* a multiply-add: not fused onward */  \
                BODY(s_ + r_, yr_);                                                           \
            }                                                                                 \
        }                                                                                     \
        for (; s_ < (S1); ++s_) {                                                             \
            v4d yr_;                                                                          \
            FREE_STEP(Z, A, F(s_), yr_, n);                                                   \
            BODY(s_, yr_);                                                                    \
        }                                                                                     \
    } while (0)

typedef struct {
    const double *a, *num, *reg, *target, *basis, *energies;
    Py_ssize_t P, n, nb, K, L, num_stride;
    double *errors, *sse, *coef;
    double cancel;      /* see the head of this section */
    const double *first, *noise; /* the cascade (see the head of this section), or NULL */
    const Py_ssize_t *order;     /* the rows in the order of the blocks, or NULL: 0 .. P-1 */
} free_job;

/* row[l] <- the population row of lane l of the block at q (lanes past the population's end
 * take the block's first row; their results are not written) */
static inline __attribute__((always_inline)) void free_rows(const free_job *J, Py_ssize_t q,
                                                            Py_ssize_t w, Py_ssize_t row[4])
{
    for (int l = 0; l < 4; ++l) {
        const Py_ssize_t i = q + (l < w ? l : 0);
        row[l] = J->order ? J->order[i] : i;
    }
}

/* Cholesky of the symmetric positive definite G (n x n, lower triangle read and written) on
 * the 4 lanes at once, the reciprocals of the pivots into R (the solves multiply by them);
 * good[l] = 0 where a pivot is not positive and finite (that lane's pivots are then taken
 * as 1, so the other lanes go on, and its results are discarded).  Right-looking: each
 * column updates the trailing matrix, whose updates are independent (no chain of
 * dependent multiply-adds), and every entry still subtracts its products in the order of
 * k, as the dot-product form does. */
static inline __attribute__((always_inline)) void
free_cholesky(v4d *G, v4d *R, const int n, int good[4])
{
    const v4d one = {1, 1, 1, 1};
    for (int j = 0; j < n; ++j) {
        v4d d = G[j * n + j];
        for (int l = 0; l < 4; ++l)
            if (!(d[l] > 0) || !isfinite(d[l])) {
                good[l] = 0;
                d[l] = 1.0;
            }
        for (int l = 0; l < 4; ++l) d[l] = sqrt(d[l]);
        const v4d r = one / d;
        G[j * n + j] = d;
        R[j] = r;
        for (int i = j + 1; i < n; ++i) G[i * n + j] *= r;
        for (int i = j + 1; i < n; ++i) {
            const v4d gij = G[i * n + j];
            for (int k = j + 1; k <= i; ++k) G[i * n + k] -= gij * G[k * n + j];
        }
    }
}

/* Rows j0 .. j0 + R - 1 of X (rows of n) <- L^-T L^-1 X: each entry subtracts its products
 * in the order of k, as free_lower_solve and free_upper_solve do, the R rows side by side
 * (independent chains, the partial sums in registers) */
static inline __attribute__((always_inline)) void
free_solve_group(const v4d *Lm, const v4d *R, v4d *X, const int n, const int j0, const int rows)
{
    v4d *Xr = X + j0 * n;
    for (int i = 0; i < n; ++i) {
        v4d s[8];
        _Pragma("GCC unroll 8") for (int r = 0; r < rows; ++r) s[r] = Xr[r * n + i];
        for (int k = 0; k < i; ++k) {
            const v4d lik = Lm[i * n + k];
            _Pragma("GCC unroll 8") for (int r = 0; r < rows; ++r) s[r] -= lik * Xr[r * n + k];
        }
        _Pragma("GCC unroll 8") for (int r = 0; r < rows; ++r) Xr[r * n + i] = s[r] * R[i];
    }
    for (int i = n - 1; i >= 0; --i) {
        v4d s[8];
        _Pragma("GCC unroll 8") for (int r = 0; r < rows; ++r) s[r] = Xr[r * n + i];
        for (int k = i + 1; k < n; ++k) {
            const v4d lki = Lm[k * n + i];
            _Pragma("GCC unroll 8") for (int r = 0; r < rows; ++r) s[r] -= lki * Xr[r * n + k];
        }
        _Pragma("GCC unroll 8") for (int r = 0; r < rows; ++r) Xr[r * n + i] = s[r] * R[i];
    }
}

/* out[i * ros + j * cos] = sum_k X[i * len + k] Y[j * len + k], k = 0 .. len - 1 in order
 * (one sum per entry, in registers), for rows i0 .. i0 + tr - 1 of X and j0 .. j0 + tc - 1 of
 * Y: a tile of tr x tc sums in registers, each X and Y value loaded once for the tile */
static inline __attribute__((always_inline)) void
free_tile(const v4d *X, const v4d *Y, const Py_ssize_t len, const int i0, const int j0,
          const int tr, const int tc, v4d *out, const Py_ssize_t ros, const Py_ssize_t cos)
{
    const v4d zero = {0, 0, 0, 0};
    v4d s[4][4];
    _Pragma("GCC unroll 4") for (int a = 0; a < tr; ++a)
        _Pragma("GCC unroll 4") for (int b = 0; b < tc; ++b) s[a][b] = zero;
    for (Py_ssize_t k = 0; k < len; ++k) {
        v4d x[4], y[4];
        _Pragma("GCC unroll 4") for (int a = 0; a < tr; ++a) x[a] = X[(i0 + a) * len + k];
        _Pragma("GCC unroll 4") for (int b = 0; b < tc; ++b) y[b] = Y[(j0 + b) * len + k];
        _Pragma("GCC unroll 4") for (int a = 0; a < tr; ++a)
            _Pragma("GCC unroll 4") for (int b = 0; b < tc; ++b) s[a][b] += x[a] * y[b];
    }
    _Pragma("GCC unroll 4") for (int a = 0; a < tr; ++a)
        _Pragma("GCC unroll 4") for (int b = 0; b < tc; ++b)
            out[(i0 + a) * ros + (j0 + b) * cos] = s[a][b];
}

/* free_tile over the nx x ny products (only the tiles that reach j <= i where lower), in
 * tiles of t x t (t = 4 with 32 registers, 3 with 16), the edges in 1 x t, t x 1 and 1 x 1 */
static inline __attribute__((always_inline)) void
free_products(const v4d *X, const int nx, const v4d *Y, const int ny, const Py_ssize_t len,
              v4d *out, const Py_ssize_t ros, const Py_ssize_t cos, const int lower,
              const int t)
{
    const int mx = nx - nx % t, my = ny - ny % t;
    for (int i = 0; i < mx; i += t)
        for (int j = 0; j < my && (!lower || j <= i + t - 1); j += t)
            free_tile(X, Y, len, i, j, t, t, out, ros, cos);
    for (int i = mx; i < nx; ++i)
        for (int j = 0; j < my && (!lower || j <= i); j += t)
            free_tile(X, Y, len, i, j, 1, t, out, ros, cos);
    for (int j = my; j < ny; ++j)
        for (int i = lower ? j - j % t : 0; i < mx; i += t)
            free_tile(X, Y, len, i, j, t, 1, out, ros, cos);
    for (int i = mx; i < nx; ++i)
        for (int j = my; j < ny && (!lower || j <= i); ++j)
            free_tile(X, Y, len, i, j, 1, 1, out, ros, cos);
}

/* The m right-hand sides X (rows of n) <- L^-T L^-1 X, L and R from free_cholesky: 8 (then 4,
 * then 1) rows at a time */
static inline __attribute__((always_inline)) void
free_solve_rows(const v4d *Lm, const v4d *R, v4d *X, const int n, const int m)
{
    int j = 0;
    for (; j + 8 <= m; j += 8) free_solve_group(Lm, R, X, n, j, 8);
    for (; j + 4 <= m; j += 4) free_solve_group(Lm, R, X, n, j, 4);
    for (; j < m; ++j) free_solve_group(Lm, R, X, n, j, 1);
}

/* v <- L^-1 v (lower) or L^-T v (upper: the transpose), L and R from free_cholesky */
static inline __attribute__((always_inline)) void
free_lower_solve(const v4d *Lm, const v4d *R, v4d *v, const int n)
{
    for (int i = 0; i < n; ++i) {
        v4d s = v[i];
        for (int k = 0; k < i; ++k) s -= Lm[i * n + k] * v[k];
        v[i] = s * R[i];
    }
}
static inline __attribute__((always_inline)) void
free_upper_solve(const v4d *Lm, const v4d *R, v4d *v, const int n)
{
    for (int i = n - 1; i >= 0; --i) {
        v4d s = v[i];
        for (int k = i + 1; k < n; ++k) s -= Lm[k * n + i] * v[k];
        v[i] = s * R[i];
    }
}

/* T (n x n, the numerators P_m by rows) and sc (1 / sqrt of their energies) of the 4 lanes
 * from the step-down of each lane's den = 1 + a_1 q^-1 + ... + a_n q^-n (rows a, a + stride,
 * ...; a_l of lane l), as flexid.costs.polynomial.orthogonal_numerators and _energies
 * compute them: row m - 1 the reversed A_(m-1) = (A_m - k_m A_m reversed) / (1 - k_m^2), k_m
 * the last coefficient of A_m, and E_m = 1 / prod_(j > m) (1 - k_j^2).  good[l] = 0 where a
 * lane breaks down (some |k_m| >= 1 in rounding, or energies not finite and positive): its
 * T = I and sc = 1.  Not inlined into the clones: compiled for the baseline, without
 * contracted multiply-adds, it rounds every operation as NumPy does (each lane on its own,
 * in the same order), so on x86-64 the basis is the reference's. */
static __attribute__((noinline)) void free_stepdown(const double *const al[4], const int n, v4d *T,
                                                    v4d *sc, int good[4])
{
    const v4d zero = {0, 0, 0, 0}, one = {1, 1, 1, 1};
    v4d cur[FREE_MAXN + 1], nxt[FREE_MAXN + 1], k[FREE_MAXN + 1];
    v4d bad = zero; /* nonzero in a lane that broke down */
    cur[0] = one;
    for (int i = 0; i < n; ++i)
        for (int l = 0; l < 4; ++l) cur[i + 1][l] = al[l][i];
    for (int i = 0; i < n * n; ++i) T[i] = zero;
    for (int m = n; m >= 1; --m) {
        const v4d km = cur[m], d = one - km * km;
        k[m] = km;
        for (int l = 0; l < 4; ++l)
            if (!(fabs(km[l]) < 1.0)) bad[l] = 1;
        for (int i = 0; i < m; ++i) nxt[i] = (cur[i] - km * cur[m - i]) / d;
        for (int i = 0; i < m; ++i) cur[i] = nxt[i];
        for (int i = 0; i < m; ++i) T[(m - 1) * n + i] = cur[m - 1 - i];
    }
    v4d prod = one;
    for (int m = n - 1; m >= 0; --m) {
        prod = m == n - 1 ? one - k[n] * k[n] : prod * (one - k[m + 1] * k[m + 1]);
        const v4d e = one / prod;
        for (int l = 0; l < 4; ++l) {
            if (!(e[l] > 0) || !isfinite(e[l])) bad[l] = 1;
            sc[m][l] = 1.0 / sqrt(e[l]);
        }
    }
    /* T - T is NaN in a lane where some T is not finite: four sums, short chains */
    v4d nonfinite[4] = {zero, zero, zero, zero};
    for (int i = 0; i < n * n; ++i) nonfinite[i & 3] += T[i] - T[i];
    for (int l = 0; l < 4; ++l)
        if ((nonfinite[0][l] + nonfinite[1][l]) + (nonfinite[2][l] + nonfinite[3][l]) != 0)
            bad[l] = 1;
    for (int l = 0; l < 4; ++l) {
        good[l] = bad[l] == 0;
        if (!good[l])
            for (int i = 0; i < n; ++i) {
                sc[i][l] = 1.0;
                for (int j = 0; j < n; ++j) T[i * n + j][l] = i == j;
            }
    }
}

/* Steps 4 to 6 of free_quad_impl (the basis, the Gram matrix over the record and the solve)
 * for the block at q of w candidates, from the impulse response in hbuf and the anti-causal
 * sums wv; into o the coefficients c (also written to coef_out), the fitted response's
 * forcing Nc, the sums of squares left and whether the fitted response must be run.  A
 * function of its own (not inlined into free_quad_impl), so that the registers of the
 * recursions are allocated without this code's. */
typedef struct {
    v4d T[FREE_MAXN * FREE_MAXN], sc[FREE_MAXN], cb, Nc[FREE_MAXN], left;
    int good[4], run, early;
    Py_ssize_t row[4]; /* the population rows of the lanes (free_rows) */
} free_alg;

static inline __attribute__((always_inline)) void
free_algebra_impl(const free_job *J, Py_ssize_t q, v4d *buf, const v4d *wv, const v4d *eep,
                  free_alg *o, const int n, const int wide)
{
    const Py_ssize_t K = J->K, L = J->L, w = (J->P - q < 4) ? J->P - q : 4;
    const v4d zero = {0, 0, 0, 0}, ee = *eep;
    v4d *hbuf = buf + K, *S0 = hbuf + K + L, *SK = S0 + n * L;
    int *good = o->good;
    v4d *T = o->T, *sc = o->sc, R[FREE_MAXN];
    if (!wv) {
        /* the basis: T and sc from the step-down (or from basis and energies), and cb */
        for (int l = 0; l < 4; ++l) good[l] = 1;
        if (!J->basis) {
            const double *al[4];
            for (int l = 0; l < 4; ++l) al[l] = J->a + o->row[l] * n;
            free_stepdown(al, n, T, sc, good);
        }
        for (int l = 0; l < 4 && J->basis; ++l) {
            const Py_ssize_t p = o->row[l];
            for (int m = 0; m < n; ++m) {
                sc[m][l] = 1.0 / sqrt(J->energies[p * n + m]);
                for (int i = 0; i < n; ++i) T[m * n + i][l] = J->basis[(p * n + m) * n + i];
            }
        }
        v4d cb = zero;
        for (int m = 0; m < n; ++m) {
            v4d r = zero;
            for (int i = 0; i <= m; ++i) r += T[m * n + i] * T[m * n + i];
            cb += sc[m] * sc[m] * r;
        }
        o->cb = cb;
        return;
    }
    /* 4. the basis windows S0 = g(0 .. L-1), SK = g(K .. K+L-1), normalised to unit energy */
    /* per sample, g_m = sum_(i <= m) T[m, i] h(. - i) for every m (independent chains, the
     * h values in registers); SK first, with its squares.  Where the impulse response has
     * decayed far enough by K in every lane that the tail is below FREE_TAIL whatever its
     * signs, SK is not formed (it would only show that): by Cauchy-Schwarz, tail <= L n
     * max|h|^2 sum_m sc_m^2 sum_i T[m, i]^2 over the h(K - n + 1 .. K + L - 1) it reads (the
     * factor 1.01 covers the rounding of this bound and of the tail's own sum). */
    v4d tail = zero, hmax = zero;
    const v4d cb = o->cb;
    for (Py_ssize_t t = K - n + 1 > 0 ? K - n + 1 : 0; t < K + L && !o->early; ++t)
        for (int l = 0; l < 4; ++l) {
            const double ah = fabs(hbuf[t][l]);
            if (!(ah <= hmax[l])) hmax[l] = ah; /* a NaN stays: not decayed */
        }
    int decayed = 1;
    for (int l = 0; l < w && !o->early; ++l)
        if (!(hmax[l] < sqrt(FREE_TAIL / (1.01 * (double)L * n * cb[l])))) decayed = 0;
    if (!decayed) {
        v4d tails[4] = {zero, zero, zero, zero}; /* four partial sums: shorter chains */
        for (Py_ssize_t tau = 0; tau < L; ++tau) {
            v4d g[FREE_MAXN];
            FREE_WINDOW_SAMPLE(g, hbuf + K + tau, tau + K, n);
            _Pragma("GCC unroll 24") for (int m = 0; m < n; ++m) {
                const v4d s = g[m] * sc[m];
                SK[m * L + tau] = s;
                tails[m & 3] += s * s;
            }
        }
        tail = (tails[0] + tails[1]) + (tails[2] + tails[3]);
    }
    /* 5. Q^T = (S0 S0^T)^-1 S0 SK^T, the Gram matrix over the record I - Q Q^T; where the
     * basis has decayed below FREE_TAIL by the end of the record in every lane, I */
    v4d M0[FREE_MAXN * FREE_MAXN], QT[FREE_MAXN * FREE_MAXN], G[FREE_MAXN * FREE_MAXN];
    int full = 0;
    for (Py_ssize_t l = 0; l < w; ++l)
        if (good[l] && !(tail[l] < FREE_TAIL)) full = 1;
    for (Py_ssize_t tau = 0; tau < L && full; ++tau) {
        v4d g[FREE_MAXN];
        FREE_WINDOW_SAMPLE(g, hbuf + tau, tau, n);
        for (int m = 0; m < n; ++m) S0[m * L + tau] = g[m] * sc[m];
    }
    if (full) {
        /* S0 S0^T (its lower triangle and some entries above it) and SK S0^T (column j of
         * S0 SK^T as row j of QT), in tiles of 4 x 4 sums where 32 registers hold them,
         * else (and for orders that 3 divides: no edge tiles) of 3 x 3 */
        const int tile = wide && n % 3 != 0 ? 4 : 3;
        free_products(S0, n, S0, n, L, M0, n, 1, 1, tile);
        free_products(S0, n, SK, n, L, QT, 1, n, 0, tile);
        free_cholesky(M0, R, n, good);
        free_solve_rows(M0, R, QT, n, n); /* row j of QT now column j of Q^T */
        free_products(QT, n, QT, n, n, G, n, 1, 1, tile); /* Q Q^T, its lower triangle */
        for (int i = 0; i < n; ++i)
            for (int j = 0; j <= i; ++j) G[i * n + j] = (i == j ? zero + 1.0 : zero) - G[i * n + j];
    }
    /* 6. the right-hand side and the normalised solve */
    v4d c[FREE_MAXN], rn[FREE_MAXN], *Nc = o->Nc;
    for (int m = 0; m < n; ++m) {
        v4d s = zero;
        for (int i = 0; i <= m; ++i) s += T[m * n + i] * wv[i];
        c[m] = rn[m] = s * sc[m];
    }
    if (full) { /* else G is I: c = rn */
        free_cholesky(G, R, n, good);
        free_lower_solve(G, R, c, n);
        free_upper_solve(G, R, c, n);
    }
    /* the sum of squares the fit leaves, |e|^2 - c.r at the solution of the normal equations
     * (normalised); where it is at least cancel |e|^2 its cancellation is harmless and the
     * fitted response need not be run (see initial_state_fit) */
    v4d fit = zero;
    for (int m = 0; m < n; ++m) fit += c[m] * rn[m];
    const v4d left = ee - fit;
    o->left = left;
    int run = J->errors != NULL;
    for (Py_ssize_t l = 0; l < w; ++l)
        if (good[l] && !(left[l] >= J->cancel * ee[l])) run = 1;
    for (int m = 0; m < n; ++m) c[m] *= sc[m];
    for (int i = 0; i < n; ++i) {
        v4d s = zero;
        for (int m = i; m < n; ++m) s += T[m * n + i] * c[m];
        Nc[i] = s;
    }
    o->run = run;
    for (Py_ssize_t l = 0; l < w; ++l)
        for (int m = 0; m < n; ++m) J->coef[o->row[l] * n + m] = c[m][l];
}

static inline __attribute__((always_inline)) void
free_quad_impl(const free_job *J, Py_ssize_t q, v4d *buf, const int n, const int wide,
               void (*alg)(const free_job *, Py_ssize_t, v4d *, const v4d *, const v4d *, free_alg *))
{
    const Py_ssize_t K = J->K, L = J->L, nb = J->nb, w = (J->P - q < 4) ? J->P - q : 4;
    const double *reg = J->reg, *target = J->target;
    const v4d zero = {0, 0, 0, 0};
    v4d *ebuf = buf, *hbuf = buf + K;
    v4d A[FREE_MAXN], Z[FREE_MAXN], Bv[64];
    /* lanes past P run lane 0's candidate; their results are not written */
    free_alg o;
    free_rows(J, q, w, o.row);
    const Py_ssize_t *row = o.row;
    for (int i = 0; i < n; ++i)
        for (int l = 0; l < 4; ++l) A[i][l] = J->a[row[l] * n + i];
    for (Py_ssize_t j = 0; j < nb; ++j)
        for (int l = 0; l < 4; ++l) Bv[j][l] = J->num[row[l] * J->num_stride + j];
    /* the cascade: the first recursion's denominator (order n, padded with zeros) and the
     * c_1, c_2, d_1, d_2 of D / C */
    const int cascade = J->first != NULL;
    v4d A1[FREE_MAXN], CD[4];
    for (int i = 0; i < n && cascade; ++i)
        for (int l = 0; l < 4; ++l) A1[i][l] = J->first[row[l] * n + i];
    for (int i = 0; i < 4 && cascade; ++i)
        for (int l = 0; l < 4; ++l) CD[i][l] = J->noise[row[l] * 4 + i];
    v4d s0 = zero, s1 = zero; /* the state of D / C */
    /* 1. the error from rest, and its sum of squares */
    v4d ee = zero;
    for (int i = 0; i < n; ++i) Z[i] = zero;
    /* the input part first, into ebuf, 8 samples at a time: 8 independent sums in registers
     * (a pass of its own, so that the recursion has the registers to itself) */
    Py_ssize_t t0 = 0;
    for (; t0 + 8 <= K; t0 += 8) {
        v4d f[8];
        _Pragma("GCC unroll 8") for (int i = 0; i < 8; ++i) f[i] = zero;
        for (Py_ssize_t j = 0; j < nb; ++j) {
            const v4d bj = Bv[j];
            _Pragma("GCC unroll 8") for (int i = 0; i < 8; ++i) f[i] += bj * reg[(t0 + i) * nb + j];
        }
        _Pragma("GCC unroll 8") for (int i = 0; i < 8; ++i) ebuf[t0 + i] = f[i];
    }
    for (; t0 < K; ++t0) {
        v4d f = zero;
        for (Py_ssize_t j = 0; j < nb; ++j) f += Bv[j] * reg[t0 * nb + j];
        ebuf[t0] = f;
    }
    /* the basis, from each den's step-down */
    o.early = 0;
    alg(J, q, buf, NULL, &ee, &o);
    /* 2. the impulse response over K + L samples: with 32 registers (wide) and an order whose
     * two states fit them, in the same loop as the error (two independent recursions side by
     * side); else after it, in rounds where wide */
    const int fuse = wide && n <= 14, rounds = wide;
    v4d Zh[FREE_MAXN];
    for (int i = 0; i < n; ++i) Zh[i] = zero;
    {
        v4d ht, f = zero + 1.0;
        FREE_STEP(Zh, A, f, ht, n);
        hbuf[0] = ht;
    }
#define FREE_F_ERR(t) ebuf[t]
#define FREE_B_ERR(t, yt)                                                                     \
    do {                                                                                      \
        const v4d e_ = target[t] - (yt);                                                      \
        ebuf[t] = e_;                                                                         \
        ee += e_ * e_;                                                                        \
    } while (0)
/* the cascade: v = target - the first recursion's output, e = (D / C) v (direct form II
 * transposed, the state s0, s1) */
#define FREE_B_CAS(t, wt)                                                                     \
    do {                                                                                      \
        const v4d v_ = target[t] - (wt), e_ = v_ + s0;                                        \
        s0 = s1 + CD[2] * v_ - CD[0] * e_;                                                    \
        s1 = CD[3] * v_ - CD[1] * e_;                                                         \
        ebuf[t] = e_;                                                                         \
        ee += e_ * e_;                                                                        \
    } while (0)
#define FREE_F_ZERO(t) zero
#define FREE_B_H(t, yt) (hbuf[(t)] = (yt))
/* the error's recursion (denominator AE, each step followed by BODY) and the impulse
 * response's side by side, then the rest of the impulse response */
#define FREE_FUSED(AE, BODY)                                                                  \
    do {                                                                                      \
        for (Py_ssize_t t = 0; t < K; ++t) {                                                  \
            v4d yt, ht;                                                                       \
            FREE_STEP(Z, AE, ebuf[t], yt, n);                                                 \
            BODY(t, yt);                                                                      \
            FREE_STEP(Zh, A, zero, ht, n);                                                    \
            hbuf[t + 1] = ht;                                                                 \
        }                                                                                     \
        FREE_REC(Zh, A, n, 0, K + 1, K + L, FREE_F_ZERO, FREE_B_H);                           \
    } while (0)
    if (fuse && cascade) {
        FREE_FUSED(A1, FREE_B_CAS);
    } else if (fuse) {
        FREE_FUSED(A, FREE_B_ERR);
    } else {
        if (cascade)
            FREE_REC(Z, A1, n, rounds, 0, K, FREE_F_ERR, FREE_B_CAS);
        else
            FREE_REC(Z, A, n, rounds, 0, K, FREE_F_ERR, FREE_B_ERR);
        /* in rounds of 4 n steps; after each, where the energy of what is left of h is so
         * small in every lane that the tail after K is below FREE_TAIL, h stops (the small
         * algebra then takes the Gram matrix as I).  From the state z before step s, the
         * rest of h is the impulse response of z(q) / den(q), whose energy is at most
         * (2 n - 1) r(0) |z|^2 (Gershgorin on the Toeplitz matrix of h's autocorrelation r,
         * |r(k)| <= r(0) = E_0, the energy of h, 1 / sc_0^2); and the tail, the window after
         * K of the normalised basis, is at most n cb times the energy of h after K - n + 1 */
        v4d zmax;
        for (int l = 0; l < 4; ++l)
            zmax[l] = FREE_TAIL * o.sc[0][l] * o.sc[0][l] /
                      (1.01 * (double)n * (2 * n - 1) * o.cb[l]);
        Py_ssize_t s = 1;
        while (s < K + L) {
            const Py_ssize_t e = s + 4 * n < K + L ? s + 4 * n : K + L;
            FREE_REC(Zh, A, n, rounds, s, e, FREE_F_ZERO, FREE_B_H);
            s = e;
            if (s > K - n + 1) continue;
            v4d z2 = zero;
            for (int i = 0; i < n; ++i) z2 += Zh[i] * Zh[i];
            int small = 1;
            for (int l = 0; l < w; ++l)
                if (!(z2[l] < zmax[l])) small = 0;
            if (small) {
                o.early = 1;
                break;
            }
        }
    }
    /* 3. w(i) = sum_(t >= i) h(t - i) e(t), the anti-causal recursion, for i < n (step s at
     * t = K - 1 - s) */
    v4d wv[FREE_MAXN];
    for (int i = 0; i < n; ++i) Z[i] = wv[i] = zero;
#define FREE_F_BACK(s) ebuf[K - 1 - (s)]
#define FREE_B_BACK(s, yt)                                                                    \
    do {                                                                                      \
        if (K - 1 - (s) < n) wv[K - 1 - (s)] = (yt);                                          \
    } while (0)
    FREE_REC(Z, A, n, rounds, 0, K, FREE_F_BACK, FREE_B_BACK);
    /* 4 to 6 */
    alg(J, q, buf, wv, &ee, &o);
    const v4d *Nc = o.Nc, left = o.left;
    const int *good = o.good, run = o.run;
    /* 7. the fitted free response removed from e */
    for (int i = 0; i < n; ++i) Z[i] = zero;
    v4d sse = left;
    double *err[4] = {NULL, NULL, NULL, NULL};
    for (Py_ssize_t l = 0; l < w && J->errors; ++l) err[l] = J->errors + row[l] * K;
    if (run) sse = zero;
#define FREE_F_FIT(t) ((t) < n ? Nc[(t)] : zero)
#define FREE_B_FIT(t, yt)                                                                     \
    do {                                                                                      \
        const v4d e_ = ebuf[t] - (yt);                                                        \
        sse += e_ * e_;                                                                       \
        if (err[0])                                                                           \
            for (Py_ssize_t l_ = 0; l_ < w; ++l_) err[l_][t] = e_[l_];                        \
    } while (0)
    if (run) FREE_REC(Z, A, n, rounds, 0, K, FREE_F_FIT, FREE_B_FIT);
#undef FREE_F_ERR
#undef FREE_B_ERR
#undef FREE_B_CAS
#undef FREE_FUSED
#undef FREE_F_ZERO
#undef FREE_B_H
#undef FREE_F_BACK
#undef FREE_B_BACK
#undef FREE_F_FIT
#undef FREE_B_FIT
    for (Py_ssize_t l = 0; l < w; ++l) {
        J->sse[row[l]] = good[l] ? sse[l] : NAN;
    }
}

/* Steps of the impulse response per unit of order that the decay probe runs */
#define FREE_PROBE 4

/* The decay probe of the block at q (rows q .. q + 3 of the population, in its order): key[p]
 * the energy of h over the last n of its first FREE_PROBE n samples relative to their whole
 * energy, large where a pole is near the circle.  The blocks then take the rows in the order
 * of key, slowest first (free_order): blocks of alike rows, so that fewer of them need the
 * tail after the record or the whole impulse response, and the costliest start first. */
static inline __attribute__((always_inline)) void free_probe_impl(const free_job *J, Py_ssize_t q,
                                                                  double *key, const int n,
                                                                  const int wide)
{
    const Py_ssize_t w = (J->P - q < 4) ? J->P - q : 4, M = FREE_PROBE * n;
    const v4d zero = {0, 0, 0, 0};
    v4d A[FREE_MAXN], Z[FREE_MAXN], all = zero, late = zero;
    for (int i = 0; i < n; ++i)
        for (int l = 0; l < 4; ++l) A[i][l] = J->a[(q + (l < w ? l : 0)) * n + i];
    for (int i = 0; i < n; ++i) Z[i] = zero;
    {
        v4d ht, f = zero + 1.0;
        FREE_STEP(Z, A, f, ht, n);
        all = ht * ht;
    }
#define FREE_F_NONE(t) zero
#define FREE_B_PROBE(t, yt)                                                                   \
    do {                                                                                      \
        const v4d y2_ = (yt) * (yt);                                                          \
        all += y2_;                                                                           \
        if ((t) >= M - n) late += y2_;                                                        \
    } while (0)
    FREE_REC(Z, A, n, wide, 1, M, FREE_F_NONE, FREE_B_PROBE);
#undef FREE_F_NONE
#undef FREE_B_PROBE
    for (Py_ssize_t l = 0; l < w; ++l) key[q + l] = late[l] / all[l];
}

typedef void (*free_quad_fn)(const free_job *, Py_ssize_t, v4d *);
typedef void (*free_probe_fn)(const free_job *, Py_ssize_t, double *);
/* a block is 4 candidates, one 256-bit vector; the AVX-512 build runs 256-bit vectors too,
 * but has 32 of them: the state and the a_k of the recursions, and the small algebra's
 * accumulators, stay in registers */
#if defined(AR_X86)
#define FREE_QUAD(n)                                                                          \
    FREE_QUAD_ISA(n, g, AR_TGT_G, 0) FREE_QUAD_ISA(n, v3_, AR_TGT_V3, 0) FREE_QUAD_ISA(n, v4_, AR_TGT_V4, 1)
#else
#define FREE_QUAD(n) FREE_QUAD_ISA(n, g, , 0)
#endif
/* free_quad_<isa><n> and its small algebra, not inlined into it (see free_algebra_impl) */
#define FREE_QUAD_ISA(n, isa, TGT, wide)                                                      \
    TGT static __attribute__((noinline)) void free_alg_##isa##n(                              \
        const free_job *J, Py_ssize_t q, v4d *b, const v4d *wv, const v4d *ee, free_alg *o)   \
    {                                                                                         \
        free_algebra_impl(J, q, b, wv, ee, o, n, wide);                                       \
    }                                                                                         \
    TGT static void free_quad_##isa##n(const free_job *J, Py_ssize_t q, v4d *b)               \
    {                                                                                         \
        free_quad_impl(J, q, b, n, wide, free_alg_##isa##n);                                  \
    }                                                                                         \
    TGT static void free_probe_##isa##n(const free_job *J, Py_ssize_t q, double *key)         \
    {                                                                                         \
        free_probe_impl(J, q, key, n, wide);                                                  \
    }
FREE_QUAD(1) FREE_QUAD(2) FREE_QUAD(3) FREE_QUAD(4) FREE_QUAD(5) FREE_QUAD(6)
FREE_QUAD(7) FREE_QUAD(8) FREE_QUAD(9) FREE_QUAD(10) FREE_QUAD(11) FREE_QUAD(12)
FREE_QUAD(13) FREE_QUAD(14) FREE_QUAD(15) FREE_QUAD(16) FREE_QUAD(17) FREE_QUAD(18)
FREE_QUAD(19) FREE_QUAD(20) FREE_QUAD(21) FREE_QUAD(22) FREE_QUAD(23) FREE_QUAD(24)
static const free_quad_fn free_quads_generic[FREE_MAXN + 1] = AR_TABLE24(free_quad_g);
static const free_probe_fn free_probes_generic[FREE_MAXN + 1] = AR_TABLE24(free_probe_g);
#if defined(AR_X86)
static const free_quad_fn free_quads_v3[FREE_MAXN + 1] = AR_TABLE24(free_quad_v3_);
static const free_quad_fn free_quads_v4[FREE_MAXN + 1] = AR_TABLE24(free_quad_v4_);
static const free_probe_fn free_probes_v3[FREE_MAXN + 1] = AR_TABLE24(free_probe_v3_);
static const free_probe_fn free_probes_v4[FREE_MAXN + 1] = AR_TABLE24(free_probe_v4_);
#endif

typedef struct {
    free_job J;
    free_quad_fn fn;
    free_probe_fn probe;
    double *key; /* (P,): the decay probe's */
} free_ctx;

typedef struct {
    double key;
    Py_ssize_t row;
} free_rank;

/* slowest decay first (a NaN first of all), then the population's order */
static int free_rank_cmp(const void *x, const void *y)
{
    const free_rank *a = (const free_rank *)x, *b = (const free_rank *)y;
    const int na = isnan(a->key), nb = isnan(b->key);
    if (na != nb) return nb - na;
    if (!na && a->key != b->key) return a->key < b->key ? 1 : -1;
    return (a->row > b->row) - (a->row < b->row);
}

/* Block u of the decay probe */
static int free_probe_unit(const void *ctx, Py_ssize_t u, void **scratch)
{
    const free_ctx *c = (const free_ctx *)ctx;
    (void)scratch;
    FLUSH_SUBNORMALS_BEGIN;
    c->probe(&c->J, 4 * u, c->key);
    FLUSH_SUBNORMALS_END;
    return 0;
}

/* Scratch of up to this many bytes is kept by each thread between calls (the helper threads
 * persist): a fresh buffer of some 150 KB (K = 1,500) is mapped and faulted in anew at
 * every call, as long as the fit of a whole small population.  Larger ones are per call. */
#define FREE_KEEP (4u << 20)
static __thread v4d *free_kept = NULL;
static __thread size_t free_kept_count = 0;

/* Block u of a fit; the scratch holds e, h and the two basis windows of one block (the
 * thread's kept buffer when it is small enough, else one for this call). */
static int free_unit(const void *ctx, Py_ssize_t u, void **scratch)
{
    const free_ctx *c = (const free_ctx *)ctx;
    const size_t count = (size_t)(2 * c->J.K + c->J.L + 2 * c->J.n * c->J.L);
    v4d *buf;
    if (count * sizeof(v4d) <= FREE_KEEP) {
        if (free_kept_count < count) {
            free(free_kept);
            free_kept = (v4d *)aligned_alloc(32, count * sizeof(v4d));
            free_kept_count = free_kept ? count : 0;
            if (!free_kept) return -1;
        }
        buf = free_kept;
    } else {
        if (!*scratch) {
            *scratch = aligned_alloc(32, count * sizeof(v4d));
            if (!*scratch) return -1;
        }
        buf = (v4d *)*scratch;
    }
    FLUSH_SUBNORMALS_BEGIN;
    c->fn(&c->J, 4 * u, buf);
    FLUSH_SUBNORMALS_END;
    return 0;
}

static PyObject *py_free_fit(PyObject *self, PyObject *args)
{
    PyObject *objs[11] = {NULL};
    Py_buffer bufs[11];
    int have[11] = {0}, n_threads = 1;
    Py_ssize_t window, num_stride = 0;
    double cancel;
    static const char *names[11] = {"a",          "num",     "reg",      "target",
                                    "basis",      "energies", "errors_out", "sse_out",
                                    "coef_out",   "first",   "noise"};
    if (!PyArg_ParseTuple(args, "OOOOOOndOOO|iOO", &objs[0], &objs[1], &objs[2], &objs[3],
                          &objs[4], &objs[5], &window, &cancel, &objs[6], &objs[7], &objs[8],
                          &n_threads, &objs[9], &objs[10]))
        return NULL;
    PyObject *result = NULL;
    for (int i = 0; i < 11; ++i) {
        if (objs[i] == NULL) continue;
        if (objs[i] == Py_None) {
            /* basis and energies: both or neither; first and noise: both or neither */
            if (i == 4 || i == 5 || i == 6 || i == 9 || i == 10) continue;
            PyErr_Format(PyExc_TypeError, "free_fit: %s is required", names[i]);
            goto done;
        }
        if (i == 1) {
            num_stride = get_rows(objs[1], &bufs[1], "free_fit", "num");
            if (num_stride < 0) goto done;
            have[1] = 1;
            continue;
        }
        if (get_buffer(objs[i], &bufs[i], i >= 6, names[i]) < 0) goto done;
        have[i] = 1;
        if (check_format(&bufs[i], "d", names[i]) < 0) goto done;
    }
    const Py_ssize_t P = bufs[0].shape[0], n = bufs[0].ndim == 2 ? bufs[0].shape[1] : 0;
    const Py_ssize_t nb = bufs[1].ndim == 2 ? bufs[1].shape[1] : -1;
    const Py_ssize_t K = bufs[3].ndim == 1 ? bufs[3].shape[0] : 0;
    if (bufs[0].ndim != 2 || n < 1 || n > FREE_MAXN || bufs[1].ndim != 2 ||
        bufs[1].shape[0] != P || nb > 64 || bufs[2].ndim != 2 || bufs[2].shape[0] != K ||
        bufs[2].shape[1] != nb || K < 1 || have[4] != have[5] ||
        (have[4] && (bufs[4].ndim != 3 || bufs[4].shape[0] != P || bufs[4].shape[1] != n ||
                     bufs[4].shape[2] != n || bufs[5].ndim != 2 || bufs[5].shape[0] != P ||
                     bufs[5].shape[1] != n)) ||
        window < n ||
        (have[6] && (bufs[6].ndim != 2 || bufs[6].shape[0] != P || bufs[6].shape[1] != K)) ||
        bufs[7].ndim != 1 || bufs[7].shape[0] != P || bufs[8].ndim != 2 ||
        bufs[8].shape[0] != P || bufs[8].shape[1] != n || have[9] != have[10] ||
        (have[9] && (bufs[9].ndim != 2 || bufs[9].shape[0] != P || bufs[9].shape[1] != n ||
                     bufs[10].ndim != 2 || bufs[10].shape[0] != P ||
                     bufs[10].shape[1] != 4))) {
        PyErr_SetString(PyExc_ValueError,
                        "free_fit: a (P, n) with 1 <= n <= 24, num (P, nb) with nb <= 64, reg "
                        "(K, nb), target (K,), basis (P, n, n) and energies (P, n) or both None, "
                        "window >= n, "
                        "errors_out (P, K) or None, sse_out (P,), coef_out (P, n), first (P, n) "
                        "and noise (P, 4) or both None");
        goto done;
    }
    free_ctx ctx;
    ctx.J = (free_job){(const double *)bufs[0].buf, (const double *)bufs[1].buf,
                       (const double *)bufs[2].buf, (const double *)bufs[3].buf,
                       have[4] ? (const double *)bufs[4].buf : NULL,
                       have[5] ? (const double *)bufs[5].buf : NULL,
                       P, n, nb, K, window, num_stride,
                       have[6] ? (double *)bufs[6].buf : NULL, (double *)bufs[7].buf,
                       (double *)bufs[8].buf, cancel,
                       have[9] ? (const double *)bufs[9].buf : NULL,
                       have[10] ? (const double *)bufs[10].buf : NULL, NULL};
#if defined(AR_X86)
    ctx.fn = ar_simd == 2   ? free_quads_v4[n]
             : ar_simd == 1 ? free_quads_v3[n]
                            : free_quads_generic[n];
    ctx.probe = ar_simd == 2   ? free_probes_v4[n]
                : ar_simd == 1 ? free_probes_v3[n]
                               : free_probes_generic[n];
#else
    ctx.fn = free_quads_generic[n];
    ctx.probe = free_probes_generic[n];
#endif
    /* more than one block: the rows in the order of the decay probe (see free_probe_impl) */
    int rc = 0;
    Py_ssize_t *order = NULL;
    free_rank *rank = NULL;
    ctx.key = NULL;
    if (P > 4) {
        ctx.key = (double *)malloc((size_t)P * sizeof(double));
        order = (Py_ssize_t *)malloc((size_t)P * sizeof(Py_ssize_t));
        rank = (free_rank *)malloc((size_t)P * sizeof(free_rank));
        if (!ctx.key || !order || !rank) rc = -1;
    }
    Py_BEGIN_ALLOW_THREADS
    if (P > 4 && rc == 0) {
        run_units_serial(&ctx, free_probe_unit, (P + 3) / 4);
        for (Py_ssize_t p = 0; p < P; ++p) rank[p] = (free_rank){ctx.key[p], p};
        qsort(rank, (size_t)P, sizeof(free_rank), free_rank_cmp);
        for (Py_ssize_t p = 0; p < P; ++p) order[p] = rank[p].row;
        ctx.J.order = order;
    }
    if (rc == 0) rc = run_units(&ctx, free_unit, (P + 3) / 4, n_threads);
    Py_END_ALLOW_THREADS
    free(ctx.key);
    free(order);
    free(rank);
    if (rc < 0) {
        PyErr_NoMemory();
        goto done;
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < 11; ++i)
        if (have[i]) PyBuffer_Release(&bufs[i]);
    return result;
}
#endif
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC pop_options
#endif
