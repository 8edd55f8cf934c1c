/*
 * numerator.c: the fitted numerator (variable projection of the simulation cost), and
 * nothing else.
 *
 *   arx_fit(a, reg, state0, target, offset, b_out, ok_out[, threads])
 *       Least-squares numerators of the simulation cost (flexid.kernels.arx_fit): for each
 *       denominator a (P, na), 1 <= na <= 16, the b (P, nb), 1 <= nb <= 16, minimising the
 *       sum over t >= offset of (target(t - offset) - y(t))^2, y the simulation from state0
 *       (na,) with the input regressors reg (T, nb); target (T - offset,).  Writes b_out
 *       (P, nb) and ok_out (P,) uint8, 0 where the factorisation broke down or b is not
 *       finite.  See fit_quad_impl.
 *
 *   arx_fit_shifted(a, reg, state0, target, offset, L, tol, b_out, ok_out, sse_out
 *                   [, threads[, free_state[, d, targets]]])
 *       The same for regressor columns that are delays of one signal (reg[t, j] = x(t - j),
 *       flexid.kernels.arx_fit_shifted), 1 <= na <= 24, from two recursions and lag sums; L
 *       0 or max(na, nb - 1) (the delays of the impulse response in the basis), tol the
 *       largest kappa(Gs) T eps accepted (ok_out 0 above it), sse_out (P,) or None (the
 *       sums of squares of arx_run at the solution, offset 0).  With free_state the initial
 *       state is fitted with b (state0 not used); d (P, nd + 1) per-candidate FIR numerators
 *       on the signal, targets (P, T - offset) per-candidate targets.  See the section
 *       "numerator fit by shifts" below.
 *
 * Both run on blocks of 4 candidates (one per SIMD lane, one copy per order and instruction
 * set, simd.h) with subnormals flushed to zero, split between `threads` threads.
 */
#include "numerator.h"
#include "pool.h"
#include "recursion.h"

#if defined(__GNUC__)
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
    /* solve L L^T x = v in place, every lane.  The backward pass counts i_ down as i_-- > 0,
     * not i_ >= 0; --i_: all indices stay below nb <= FIT_MAXNB either way, but with -fwrapv
     * (Python's build flags) GCC 12 warns "iteration 13 invokes undefined behavior" about
     * the copy of the inner loop for i_ = nb - 1, which never runs */
#define FIT_SOLVE(v)                                                                          \
    do {                                                                                      \
        for (Py_ssize_t i_ = 0; i_ < nb; ++i_) {                                              \
            v4d s_ = (v)[i_];                                                                 \
            for (Py_ssize_t k_ = 0; k_ < i_; ++k_) s_ -= G[i_][k_] * (v)[k_];                 \
            (v)[i_] = s_ / G[i_][i_];                                                         \
        }                                                                                     \
        for (Py_ssize_t i_ = nb; i_-- > 0;) {                                                 \
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

#define FIT_PASS a, a_stride, P, na, reg, T, state0, target, offset, b_out, ok, q, hist
/* one function per nb and instruction set (nb a constant: the sums stay in registers) */
#define FIT_QUAD(n, isa, TGT, wide)                                                           \
    TGT static void fit_quad_##isa##n(FIT_ARGS) { fit_quad_impl(FIT_PASS, n); }
SIMD_ORDERS16(FIT_QUAD)
static const fit_quad_fn fit_quads_generic[FIT_MAXNB + 1] = SIMD_TABLE16(fit_quad_g);
#if defined(SIMD_X86)
static const fit_quad_fn fit_quads_v3[FIT_MAXNB + 1] = SIMD_TABLE16(fit_quad_v3_);
static const fit_quad_fn fit_quads_v4[FIT_MAXNB + 1] = SIMD_TABLE16(fit_quad_v4_);
#endif

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

int flexid_arx_fit(const fit_ctx *problem, int n_threads)
{
    fit_ctx ctx = *problem;
    ctx.fn = SIMD_PICK(fit_quads_generic, fit_quads_v3, fit_quads_v4)[ctx.nb];
    return flexid_run_units(&ctx, fit_unit, (ctx.P + 3) / 4, n_threads);
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
 * (its block, flexid_ar_quad of recursion.c, so the sums of squares are those of arx_run
 * for the same b).
 * With free_state the initial state is not given but fitted with b (MATLAB's estimated
 * initial condition): the coefficients c_l of S^l h, l < na, are unknowns beside b, which
 * makes the system m + na, and state0 is not used.  With d (P, nd + 1) the signal of each
 * candidate is D x (a Box-Jenkins or ARMAX predictor's regressors), and with targets each
 * has its own target; the pre-sample inputs of D x are not formed, so d needs them out of
 * the basis (L = 0, or free_state with nb - 1 <= na). */
#define VP_PAD 32                          /* zeros stored before each signal */
#define VP_TAIL 16                         /* samples of h run past T (>= nb - 1) */
#define VP_MAXB (FIT_MAXNB + VP_MAXNA) /* basis size m + L */

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

#define VP_REC(n, isa, TGT, wide)                                                             \
    TGT static void vp_rec_##isa##n(const vp_ctx *c, Py_ssize_t q, v4d *v, v4d *h)           \
    {                                                                                         \
        vp_rec_impl(c, q, v, h, n);                                                           \
    }
#define VP_SOLVE(n, isa, TGT, wide)                                                           \
    TGT static void vp_solve_##isa(const vp_ctx *c, Py_ssize_t q, const v4d *v, const v4d *h, \
                                   v4d *w)                                                    \
    {                                                                                         \
        vp_solve_impl(c, q, v, h, w);                                                         \
    }
SIMD_COPIES(VP_SOLVE, )
SIMD_ORDERS24(VP_REC)
static const vp_rec_fn vp_recs_generic[VP_MAXNA + 1] = SIMD_TABLE24(vp_rec_g);
#if defined(SIMD_X86)
static const vp_rec_fn vp_recs_v3[VP_MAXNA + 1] = SIMD_TABLE24(vp_rec_v3_);
static const vp_rec_fn vp_recs_v4[VP_MAXNA + 1] = SIMD_TABLE24(vp_rec_v4_);
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
        flexid_ar_quad(c->na)(&J, q);
    }
    return 0;
}

int flexid_arx_fit_shifted(const vp_ctx *problem, int n_threads)
{
    vp_ctx ctx = *problem;
    ctx.rec = SIMD_PICK(vp_recs_generic, vp_recs_v3, vp_recs_v4)[ctx.na];
    ctx.solve = SIMD_PICK(vp_solve_g, vp_solve_v3_, vp_solve_v4_);
    return flexid_run_units(&ctx, vp_unit, (ctx.P + 3) / 4, n_threads);
}
#endif
