/*
 * initial_state.c: the estimated initial state, and nothing else.
 *
 *   free_fit(a, num, reg, target, basis, energies, window, cancel, errors_out, sse_out,
 *            coef_out[, threads[, first, noise]])
 *       The error of 1/den filters with the initial state fitted by least squares
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
 * algebra of the normalised basis on 4 lanes at once.
 *
 * The rows run in blocks of 4 candidates (one per SIMD lane, one copy per order and
 * instruction set, simd.h) with subnormals flushed to zero, split between `threads` threads;
 * with more than one block, in the order of a decay probe (free_probe_impl).
 */
#include "initial_state.h"
#include "pool.h"

/* The estimated initial state is compiled at -O2 on every instruction set: -O3 makes it no
 * faster (measured, OE and BJ of order 16 at K = 1,500) and doubles the build's time. */
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC push_options
#pragma GCC optimize("O2")
#endif
#if defined(__GNUC__)
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
SIMD_ORDERS24(FREE_QUAD_ISA)
static const free_quad_fn free_quads_generic[FREE_MAXN + 1] = SIMD_TABLE24(free_quad_g);
static const free_probe_fn free_probes_generic[FREE_MAXN + 1] = SIMD_TABLE24(free_probe_g);
#if defined(SIMD_X86)
static const free_quad_fn free_quads_v3[FREE_MAXN + 1] = SIMD_TABLE24(free_quad_v3_);
static const free_quad_fn free_quads_v4[FREE_MAXN + 1] = SIMD_TABLE24(free_quad_v4_);
static const free_probe_fn free_probes_v3[FREE_MAXN + 1] = SIMD_TABLE24(free_probe_v3_);
static const free_probe_fn free_probes_v4[FREE_MAXN + 1] = SIMD_TABLE24(free_probe_v4_);
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

int flexid_free_fit(const free_job *J, int n_threads)
{
    const Py_ssize_t P = J->P;
    free_ctx ctx;
    ctx.J = *J;
    ctx.J.order = NULL;
    ctx.fn = SIMD_PICK(free_quads_generic, free_quads_v3, free_quads_v4)[J->n];
    ctx.probe = SIMD_PICK(free_probes_generic, free_probes_v3, free_probes_v4)[J->n];
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
    if (P > 4 && rc == 0) {
        flexid_run_units_serial(&ctx, free_probe_unit, (P + 3) / 4);
        for (Py_ssize_t p = 0; p < P; ++p) rank[p] = (free_rank){ctx.key[p], p};
        qsort(rank, (size_t)P, sizeof(free_rank), free_rank_cmp);
        for (Py_ssize_t p = 0; p < P; ++p) order[p] = rank[p].row;
        ctx.J.order = order;
    }
    if (rc == 0) rc = flexid_run_units(&ctx, free_unit, (P + 3) / 4, n_threads);
    free(ctx.key);
    free(order);
    free(rank);
    return rc;
}
#endif
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC pop_options
#endif
