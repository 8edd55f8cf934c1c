/*
 * modal.c: the regressors of the modal state-space cost and the products it needs of them,
 * and nothing else.
 *
 *   modal_regressors(poles, u, phi, m, feedthrough, free_response[, threads])
 *   modal_normal(poles, u, target, gram, rhs, m, feedthrough, free_response[, threads])
 *   modal_residual(poles, u, target, coef, residual, sse, m, feedthrough, free_response
 *                  [, threads])
 *   modal_fit(poles, u, target, yy, gram, rhs, fitted, used, x0, sse, ok, m, feedthrough,
 *             estimate, ridge, rounding, tolerance[, threads])
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
 *       their sum of squares into sse (P,).  The last two never store phi: each block of
 *       rows is made, used and dropped.  Candidates are split between `threads` threads,
 *       one a unit; the results do not depend on it.
 *       modal_fit is flexid.costs.modal.ModalCost's fit from the normal equations, the
 *       compiled route of its NumPy steps (its notes): each candidate's normal equations into
 *       gram and rhs (free_response = estimate); the least-squares coefficients, scaled to a
 *       unit diagonal with the ridge, into fitted; with estimate the shared initial state
 *       into x0 (else zeros); the realised model's coefficients into used; the sum of
 *       squares of its errors from the expansion y'y - 2 c' rhs + c' gram c (yy (ny,) the
 *       target's own), or NaN where its rounding bound, rounding (|y_o| + sum_i |c_i|
 *       sqrt(gram_ii))^2 summed over the outputs, exceeds tolerance of it; ok 0 where a
 *       Cholesky factor met a non-positive pivot (its other outputs are then unset).
 *
 * Every column is s x(t - 1) or s x(t - 2) of one second-order recursion x(t) = alpha
 * x(t - 1) + beta x(t - 2) + u_j(t) (or of no input), a "lane":
 *   a mode and input j:      alpha = -a1, beta = -a2, from rest; columns x(t - 1), x(t - 2);
 *   a real pole and input j: alpha = p, beta = 0, from rest; column x(t - 1);
 *   a mode's free response:  alpha = -a1, beta = -a2, no input, x(-1) = 1, x(-2) = 0:
 *                            x(t - 1) is the first column, and -a2 x(t - 2) the second (the
 *                            first row of A^t for the companion matrix A = [[-a1, -a2],
 *                            [1, 0]], whose second entry is -a2 times the first one step
 *                            back: the same numbers as the recursion from e2);
 *   a real pole's:           alpha = p, no input, x(-1) = 1: p^t.
 * The lanes advance together, four to a vector, each vector's two states held in registers
 * over a block of rows, so each multiply-add serves four recursions and their chains overlap
 * in the pipeline.  A row is held in the lanes' own order (every x(t - 1), then every
 * x(t - 2), then the inputs, zero-padded to whole vectors: "internal" columns) and mapped,
 * with its scale, to the documented order only where it leaves the kernel.
 *
 * The normal equations are summed over blocks of MODAL_BLOCK rows in tiles of 4 rows by 16,
 * 8 or 4 columns from each band's diagonal on, their sums in registers, with at least eight
 * sums in flight (a multiply-add's latency is four cycles and two issue per cycle).  The
 * products of two x(t - 2) columns
 * are not summed: they are those of the x(t - 1) columns over one row fewer (every lane's
 * x(-2) is 0), so that block is the x(t - 1) block less the last row's products.  Each
 * candidate runs in one copy per instruction set (simd.h; the one in use picked at run
 * time): AVX-512 with 512-bit tiles, AVX2/FMA with 256-bit ones, the baseline in plain
 * loops.  They sum in different orders, so their results differ by rounding (within 1e-12
 * of the largest entry on 700 rows).  The recursions run with subnormals flushed to zero
 * (simd.h): a fast pole's free response decays through them.
 */
#include "modal.h"
#include "pool.h"

#define MODAL_BLOCK 64 /* rows per block of the normal equations' sums */

#if defined(__GNUC__)
/* 8 columns of a tile in one 512-bit vector, for the AVX-512 copy */
typedef double v8d __attribute__((vector_size(64), aligned(8)));
#endif


/* One candidate's lanes and the unit's buffers (internal column order). */
typedef struct {
    Py_ssize_t L4;                  /* lanes, padded to a multiple of 4 */
    Py_ssize_t kp;                  /* internal columns: 2 L4 + nu feedthrough, padded */
    double *alpha, *beta, *gamma;   /* gamma: nu x L4, 1 where lane l is driven by input j */
    double *x1, *x2;                /* x(t - 1), x(t - 2) of every lane */
    double *last;                   /* the last row's x(t - 1) */
    double *rows;                   /* MODAL_BLOCK x kp */
    double *g, *h;                  /* kp x kp (the tiles summed), ny x kp */
    double *c;                      /* ny x kp: coef in internal order */
    double *scale;                  /* k: each documented column's factor */
    double *dense;                  /* modal_fit's small matrices */
    Py_ssize_t *map;                /* k: each documented column's internal one */
} modal_lanes;

static Py_ssize_t modal_lane_count(const modal_job *J)
{
    const Py_ssize_t L = (J->m + J->r) * J->nu + (J->free_response ? J->m + J->r : 0);
    return (L + 3) / 4 * 4;
}

static Py_ssize_t modal_internal(const modal_job *J)
{
    return (2 * modal_lane_count(J) + (J->feedthrough ? J->nu : 0) + 3) / 4 * 4;
}

/* The doubles of a unit's scratch before its map. */
static size_t modal_doubles(const modal_job *J)
{
    const size_t L4 = (size_t)modal_lane_count(J), kp = (size_t)modal_internal(J);
    const size_t ny = (size_t)(J->ny > 0 ? J->ny : 1);
    const size_t k = (size_t)J->k, ns = (size_t)(J->nu * (2 * J->m + J->r));
    const size_t F = (size_t)(2 * J->m + J->r);
    const size_t dense = k * k + 2 * k + 2 * ny * F * ns + ns * ns + ns;
    return (5 + (size_t)J->nu) * L4 + MODAL_BLOCK * kp + kp * kp + 2 * kp * ny + k +
           (J->used ? dense : 0);
}

/* The lanes of candidate cand from rest (and its free responses from their starts). */
static void modal_begin(const modal_job *J, Py_ssize_t cand, void *buf, modal_lanes *S)
{
    const Py_ssize_t m = J->m, r = J->r, nu = J->nu, L4 = modal_lane_count(J);
    const Py_ssize_t kp = modal_internal(J), ny = J->ny > 0 ? J->ny : 1;
    double *d = (double *)buf;
    S->L4 = L4;
    S->kp = kp;
    S->alpha = d;
    S->beta = d + L4;
    S->x1 = d + 2 * L4;
    S->x2 = d + 3 * L4;
    S->last = d + 4 * L4;
    S->gamma = d + 5 * L4;
    S->rows = S->gamma + nu * L4;
    S->g = S->rows + MODAL_BLOCK * kp;
    S->h = S->g + kp * kp;
    S->c = S->h + kp * ny;
    S->scale = S->c + kp * ny;
    S->dense = S->scale + J->k;
    S->map = (Py_ssize_t *)(d + modal_doubles(J));
    memset(d, 0, sizeof(double) * (size_t)((5 + nu) * L4 + MODAL_BLOCK * kp));
    for (Py_ssize_t i = 0; i < J->k; ++i) S->scale[i] = 1.0;
    const double *poles = J->poles + cand * (2 * m + r);
    const Py_ssize_t feed = 2 * m * nu + r * nu, free0 = feed + (J->feedthrough ? nu : 0);
    Py_ssize_t l = 0;
    for (Py_ssize_t g = 0; g < m; ++g)
        for (Py_ssize_t j = 0; j < nu; ++j, ++l) {
            S->alpha[l] = -poles[2 * g];
            S->beta[l] = -poles[2 * g + 1];
            S->gamma[j * L4 + l] = 1.0;
            S->map[2 * l] = l;
            S->map[2 * l + 1] = L4 + l;
        }
    for (Py_ssize_t g = 0; g < r; ++g)
        for (Py_ssize_t j = 0; j < nu; ++j, ++l) {
            S->alpha[l] = poles[2 * m + g];
            S->gamma[j * L4 + l] = 1.0;
            S->map[2 * m * nu + g * nu + j] = l;
        }
    for (Py_ssize_t j = 0; j < nu && J->feedthrough; ++j) S->map[feed + j] = 2 * L4 + j;
    if (!J->free_response) return;
    for (Py_ssize_t g = 0; g < m; ++g, ++l) {
        S->alpha[l] = -poles[2 * g];
        S->beta[l] = -poles[2 * g + 1];
        S->x1[l] = 1.0;
        S->map[free0 + 2 * g] = l;
        S->map[free0 + 2 * g + 1] = L4 + l;
        S->scale[free0 + 2 * g + 1] = -poles[2 * g + 1];
    }
    for (Py_ssize_t g = 0; g < r; ++g, ++l) {
        S->alpha[l] = poles[2 * m + g];
        S->x1[l] = 1.0;
        S->map[free0 + 2 * m + g] = l;
    }
}

/* The lanes l .. l + 4 w - 1 (w vectors) over b rows: their states into the rows (internal
 * order) and one step on per row, the states held in registers across the block. */
static inline __attribute__((always_inline)) void
modal_run_lanes(modal_lanes *S, const double *restrict u, Py_ssize_t nu, Py_ssize_t b,
                double *restrict rows, Py_ssize_t l, const int w, const int isa)
{
    const Py_ssize_t L4 = S->L4, kp = S->kp;
#if defined(__GNUC__)
    if (isa > 0) {
        v4d X1[2], X2[2], A[2], B[2];
        for (int v = 0; v < w; ++v) {
            X1[v] = *(const v4d *)(S->x1 + l + 4 * v);
            X2[v] = *(const v4d *)(S->x2 + l + 4 * v);
            A[v] = *(const v4d *)(S->alpha + l + 4 * v);
            B[v] = *(const v4d *)(S->beta + l + 4 * v);
        }
        for (Py_ssize_t t = 0; t < b; ++t) {
            double *rt = rows + t * kp;
            const double *ut = u + t * nu;
            for (int v = 0; v < w; ++v) {
                *(v4d *)(rt + l + 4 * v) = X1[v];
                *(v4d *)(rt + L4 + l + 4 * v) = X2[v];
                /* x(t - 2) and the inputs first: one multiply-add on the chain through x(t - 1) */
                v4d base = B[v] * X2[v];
                for (Py_ssize_t j = 0; j < nu; ++j)
                    base += *(const v4d *)(S->gamma + j * L4 + l + 4 * v) * ut[j];
                X2[v] = X1[v];
                X1[v] = A[v] * X1[v] + base;
            }
        }
        for (int v = 0; v < w; ++v) {
            *(v4d *)(S->x1 + l + 4 * v) = X1[v];
            *(v4d *)(S->x2 + l + 4 * v) = X2[v];
        }
        return;
    }
#endif
    for (Py_ssize_t t = 0; t < b; ++t)
        for (Py_ssize_t i = l; i < l + 4 * w; ++i) {
            const double x1 = S->x1[i], x2 = S->x2[i];
            rows[t * kp + i] = x1;
            rows[t * kp + L4 + i] = x2;
            double base = S->beta[i] * x2;
            for (Py_ssize_t j = 0; j < nu; ++j) base += S->gamma[j * L4 + i] * u[t * nu + j];
            S->x2[i] = x1;
            S->x1[i] = S->alpha[i] * x1 + base;
        }
}

/* Rows t0 .. t0 + b - 1 (internal order) of the regressors, every lane b steps on (one
 * input, the common case, a constant of its own copy). */
static inline __attribute__((always_inline)) void
modal_rows(const modal_job *J, modal_lanes *S, Py_ssize_t t0, Py_ssize_t b, double *rows,
           const int isa)
{
    const Py_ssize_t nu = J->nu, L4 = S->L4, kp = S->kp;
    const double *u = J->u + t0 * nu;
    Py_ssize_t l = 0;
    if (nu == 1) {
        for (; l + 8 <= L4; l += 8) modal_run_lanes(S, u, 1, b, rows, l, 2, isa);
        if (l < L4) modal_run_lanes(S, u, 1, b, rows, l, 1, isa);
    } else {
        for (; l + 8 <= L4; l += 8) modal_run_lanes(S, u, nu, b, rows, l, 2, isa);
        if (l < L4) modal_run_lanes(S, u, nu, b, rows, l, 1, isa);
    }
    if (J->feedthrough)
        for (Py_ssize_t t = 0; t < b; ++t)
            for (Py_ssize_t j = 0; j < nu; ++j) rows[t * kp + 2 * L4 + j] = u[t * nu + j];
}

/* The fit of row rt (internal order) by one output's coefficients c (kp). */
static inline __attribute__((always_inline)) double
modal_row_fit(const double *restrict rt, const double *restrict c, Py_ssize_t kp, const int isa)
{
#if defined(__GNUC__)
    if (isa > 0) {
        v4d s0 = *(const v4d *)rt * *(const v4d *)c, s1 = {0};
        Py_ssize_t i = 4;
        for (; i + 8 <= kp; i += 8) {
            s0 += *(const v4d *)(rt + i) * *(const v4d *)(c + i);
            s1 += *(const v4d *)(rt + i + 4) * *(const v4d *)(c + i + 4);
        }
        if (i < kp) s1 += *(const v4d *)(rt + i) * *(const v4d *)(c + i);
        s0 += s1;
        return (s0[0] + s0[1]) + (s0[2] + s0[3]);
    }
#endif
    double s = 0.0;
    for (Py_ssize_t i = 0; i < kp; ++i) s += rt[i] * c[i];
    return s;
}

/* Whether the tiles summed hold entry (a, c) of the internal normal equations: the
 * x(t - 1) rows and the inputs' rows from their own band of 4 on (the diagonal), the
 * x(t - 2) rows only against the inputs (columns 2 L4 on). */
static inline int modal_summed(Py_ssize_t a, Py_ssize_t c, Py_ssize_t L4)
{
    if (a >= L4 && a < 2 * L4) return c >= 2 * L4;
    return c >= a / 4 * 4;
}

/* The first column of the tiles of the band of rows I .. I + 3 (I a multiple of 4). */
static inline Py_ssize_t modal_first(Py_ssize_t I, Py_ssize_t L4)
{
    return (I >= L4 && I < 2 * L4) ? 2 * L4 : I;
}

/* One tile's sums: rows I .. I + 3 of R against its columns J .. J + W - 1 (W = 8: v8d, or 4:
 * v4d) over b rows, into g; with `split` the even and odd rows in separate sums, added at
 * the end (twice the chains in flight, for 32-register copies). */
#define MODAL_TILE(V, W)                                                                      \
    static inline __attribute__((always_inline)) void modal_tile##W(                          \
        const double *restrict R, Py_ssize_t b, Py_ssize_t kp, Py_ssize_t I, Py_ssize_t J,    \
        double *restrict g, const int split)                                                  \
    {                                                                                         \
        V a0 = {0}, a1 = {0}, a2 = {0}, a3 = {0}, e0 = {0}, e1 = {0}, e2 = {0}, e3 = {0};     \
        Py_ssize_t t = 0;                                                                     \
        if (split)                                                                            \
            for (; t + 2 <= b; t += 2) {                                                      \
                const double *r0 = R + t * kp, *r1 = r0 + kp;                                 \
                const V x = *(const V *)(r0 + J), z = *(const V *)(r1 + J);                   \
                a0 += r0[I] * x;                                                              \
                e0 += r1[I] * z;                                                              \
                a1 += r0[I + 1] * x;                                                          \
                e1 += r1[I + 1] * z;                                                          \
                a2 += r0[I + 2] * x;                                                          \
                e2 += r1[I + 2] * z;                                                          \
                a3 += r0[I + 3] * x;                                                          \
                e3 += r1[I + 3] * z;                                                          \
            }                                                                                 \
        for (; t < b; ++t) {                                                                  \
            const double *r0 = R + t * kp;                                                    \
            const V x = *(const V *)(r0 + J);                                                 \
            a0 += r0[I] * x;                                                                  \
            a1 += r0[I + 1] * x;                                                              \
            a2 += r0[I + 2] * x;                                                              \
            a3 += r0[I + 3] * x;                                                              \
        }                                                                                     \
        *(V *)(g + I * kp + J) += a0 + e0;                                                    \
        *(V *)(g + (I + 1) * kp + J) += a1 + e1;                                              \
        *(V *)(g + (I + 2) * kp + J) += a2 + e2;                                              \
        *(V *)(g + (I + 3) * kp + J) += a3 + e3;                                              \
    }
#if defined(__GNUC__)
MODAL_TILE(v8d, 8)
MODAL_TILE(v4d, 4)

/* Rows I .. I + 3 against columns J .. J + 2 W - 1 as two vectors per row: eight sums in
 * flight, each row's four entries read once for both.  modal_tile16 (512-bit vectors) for
 * 32-register copies; modal_tile8n (256-bit) for 16-register ones, where GCC would split a
 * 512-bit vector through memory. */
#define MODAL_TILE2(NAME, V, W)                                                               \
    static inline __attribute__((always_inline)) void NAME(                                   \
        const double *restrict R, Py_ssize_t b, Py_ssize_t kp, Py_ssize_t I, Py_ssize_t J,    \
        double *restrict g)                                                                   \
    {                                                                                         \
        V a0 = {0}, a1 = {0}, a2 = {0}, a3 = {0}, b0 = {0}, b1 = {0}, b2 = {0}, b3 = {0};     \
        for (Py_ssize_t t = 0; t < b; ++t) {                                                  \
            const double *rt = R + t * kp;                                                    \
            const V x = *(const V *)(rt + J), z = *(const V *)(rt + J + W);                   \
            a0 += rt[I] * x;                                                                  \
            b0 += rt[I] * z;                                                                  \
            a1 += rt[I + 1] * x;                                                              \
            b1 += rt[I + 1] * z;                                                              \
            a2 += rt[I + 2] * x;                                                              \
            b2 += rt[I + 2] * z;                                                              \
            a3 += rt[I + 3] * x;                                                              \
            b3 += rt[I + 3] * z;                                                              \
        }                                                                                     \
        *(V *)(g + I * kp + J) += a0;                                                         \
        *(V *)(g + I * kp + J + W) += b0;                                                     \
        *(V *)(g + (I + 1) * kp + J) += a1;                                                   \
        *(V *)(g + (I + 1) * kp + J + W) += b1;                                               \
        *(V *)(g + (I + 2) * kp + J) += a2;                                                   \
        *(V *)(g + (I + 2) * kp + J + W) += b2;                                               \
        *(V *)(g + (I + 3) * kp + J) += a3;                                                   \
        *(V *)(g + (I + 3) * kp + J + W) += b3;                                               \
    }
MODAL_TILE2(modal_tile16, v8d, 8)
MODAL_TILE2(modal_tile8n, v4d, 4)

/* h's columns I .. I + W - 1 for outputs o and o + 1 (pair) over b rows, the rows in four
 * interleaved sums (eight in flight with both outputs), added at the end. */
#define MODAL_RHS(V, W)                                                                       \
    static inline __attribute__((always_inline)) void modal_rhs##W(                           \
        const double *restrict R, const double *restrict Y, Py_ssize_t b, Py_ssize_t kp,      \
        Py_ssize_t ny, Py_ssize_t o, Py_ssize_t I, double *restrict h, const int pair)        \
    {                                                                                         \
        V a0 = {0}, a1 = {0}, a2 = {0}, a3 = {0}, c0 = {0}, c1 = {0}, c2 = {0}, c3 = {0};     \
        Py_ssize_t t = 0;                                                                     \
        for (; t + 4 <= b; t += 4) {                                                          \
            const double *r = R + t * kp + I, *y = Y + t * ny + o;                            \
            const V x0 = *(const V *)r, x1 = *(const V *)(r + kp);                            \
            const V x2 = *(const V *)(r + 2 * kp), x3 = *(const V *)(r + 3 * kp);             \
            a0 += y[0] * x0;                                                                  \
            a1 += y[ny] * x1;                                                                 \
            a2 += y[2 * ny] * x2;                                                             \
            a3 += y[3 * ny] * x3;                                                             \
            if (pair) {                                                                       \
                c0 += y[1] * x0;                                                              \
                c1 += y[ny + 1] * x1;                                                         \
                c2 += y[2 * ny + 1] * x2;                                                     \
                c3 += y[3 * ny + 1] * x3;                                                     \
            }                                                                                 \
        }                                                                                     \
        for (; t < b; ++t) {                                                                  \
            const V x = *(const V *)(R + t * kp + I);                                         \
            a0 += Y[t * ny + o] * x;                                                          \
            if (pair) c0 += Y[t * ny + o + 1] * x;                                            \
        }                                                                                     \
        *(V *)(h + o * kp + I) += (a0 + a1) + (a2 + a3);                                      \
        if (pair) *(V *)(h + (o + 1) * kp + I) += (c0 + c1) + (c2 + c3);                      \
    }
MODAL_RHS(v8d, 8)
MODAL_RHS(v4d, 4)
#endif

/* g (kp x kp, the entries modal_summed names) += R' R and h (ny x kp) += Y' R for a block of
 * b rows R (row-major, kp a multiple of 4) and targets Y (row-major, ny); isa 2 for copies
 * with 32 vector registers, 1 with 16, 0 the baseline (plain loops: GCC splits the wider
 * vectors of the others through memory there). */
static inline __attribute__((always_inline)) void
modal_block(const double *restrict R, const double *restrict Y, Py_ssize_t b, Py_ssize_t kp,
            Py_ssize_t L4, Py_ssize_t ny, double *restrict g, double *restrict h, const int isa)
{
#if defined(__GNUC__)
    if (isa > 0) {
        for (Py_ssize_t I = 0; I < kp; I += 4) {
            Py_ssize_t J = modal_first(I, L4);
            if (isa == 2) { /* from the band's tile of 16: a few entries more, fewer loops */
                if (J == I) J = I / 16 * 16;
                for (; J + 16 <= kp; J += 16) modal_tile16(R, b, kp, I, J, g);
            }
            for (; J + 8 <= kp; J += 8)
                if (isa == 2)
                    modal_tile8(R, b, kp, I, J, g, 1);
                else
                    modal_tile8n(R, b, kp, I, J, g);
            if (J < kp) modal_tile4(R, b, kp, I, J, g, 1);
        }
        for (Py_ssize_t o = 0; o < ny; o += 2) {
            const int pair = o + 1 < ny;
            Py_ssize_t I = 0;
            if (isa == 2)
                for (; I + 8 <= kp; I += 8) modal_rhs8(R, Y, b, kp, ny, o, I, h, pair);
            for (; I < kp; I += 4) modal_rhs4(R, Y, b, kp, ny, o, I, h, pair);
        }
        return;
    }
#endif
    for (Py_ssize_t t = 0; t < b; ++t) {
        const double *rt = R + t * kp;
        for (Py_ssize_t i = 0; i < kp; ++i) {
            const double ri = rt[i];
            double *gi = g + i * kp;
            for (Py_ssize_t j = modal_first(i / 4 * 4, L4); j < kp; ++j) gi[j] += ri * rt[j];
            for (Py_ssize_t o = 0; o < ny; ++o) h[o * kp + i] += Y[t * ny + o] * ri;
        }
    }
}

/* Entry (a, c) of the internal normal equations, from the tiles summed. */
static double modal_entry(const modal_lanes *S, Py_ssize_t a, Py_ssize_t c)
{
    const Py_ssize_t L4 = S->L4, kp = S->kp;
    if (modal_summed(a, c, L4)) return S->g[a * kp + c];
    if (modal_summed(c, a, L4)) return S->g[c * kp + a];
    /* both x(t - 2): the x(t - 1) products less the last row's */
    const Py_ssize_t i = a - L4, j = c - L4;
    const double *g = S->g;
    const double full = modal_summed(i, j, L4) ? g[i * kp + j] : g[j * kp + i];
    return full - S->last[i] * S->last[j];
}

/* X (n, q) solves (D^-1 G D^-1 + ridge I) D X = D^-1 B, D the square roots of G's diagonal
 * (1 where it is 0): the normal equations scaled to a unit diagonal with a ridge, by a
 * Cholesky factor in work (n (n + 1)); 0, or -1 at a non-positive pivot. */
static inline __attribute__((always_inline)) int
modal_solve(const double *G, const double *B, Py_ssize_t n, Py_ssize_t q, double ridge,
            double *work, double *X)
{
    double *A = work, *d = work + n * n; /* d: 1 / sqrt(G_ii) */
    for (Py_ssize_t i = 0; i < n; ++i) {
        const double g = fabs(G[i * n + i]);
        d[i] = g > 0.0 ? 1.0 / sqrt(g) : 1.0;
    }
    for (Py_ssize_t j = 0; j < n; ++j) { /* lower factor, column by column */
        double s = G[j * n + j] * d[j] * d[j] + ridge;
        for (Py_ssize_t p = 0; p < j; ++p) s -= A[j * n + p] * A[j * n + p];
        if (!(s > 0.0)) return -1;
        const double pivot = sqrt(s), inverse = 1.0 / pivot;
        A[j * n + j] = pivot;
        for (Py_ssize_t i = j + 1; i < n; ++i) {
            double v = G[i * n + j] * d[i] * d[j];
            for (Py_ssize_t p = 0; p < j; ++p) v -= A[i * n + p] * A[j * n + p];
            A[i * n + j] = v * inverse;
        }
    }
    for (Py_ssize_t c = 0; c < q; ++c) {
        for (Py_ssize_t i = 0; i < n; ++i) { /* L w = D^-1 b */
            double v = B[i * q + c] * d[i];
            for (Py_ssize_t p = 0; p < i; ++p) v -= A[i * n + p] * X[p * q + c];
            X[i * q + c] = v / A[i * n + i];
        }
        for (Py_ssize_t i = n - 1; i >= 0; --i) { /* L' v = w */
            double v = X[i * q + c];
            for (Py_ssize_t p = i + 1; p < n; ++p) v -= A[p * n + i] * X[p * q + c];
            X[i * q + c] = v / A[i * n + i];
        }
        for (Py_ssize_t i = 0; i < n; ++i) X[i * q + c] *= d[i];
    }
    return 0;
}

/* modal_fit's steps for one candidate from its normal equations (module notes; the NumPy
 * route is ModalCost._fit's): 0, or -1 at a non-positive pivot. */
static inline __attribute__((always_inline)) int
modal_fit_candidate(const modal_job *J, modal_lanes *S, Py_ssize_t cand)
{
    const Py_ssize_t m = J->m, r = J->r, nu = J->nu, ny = J->ny, k = J->k;
    const Py_ssize_t ns = nu * (2 * m + r), F = 2 * m + r;
    const Py_ssize_t k_in = ns + (J->feedthrough ? nu : 0);
    const double *G = J->gram + cand * k * k, *H = J->rhs + cand * k * ny;
    const double *poles = J->poles + cand * (2 * m + r);
    double *coef = J->fitted + cand * k * ny, *used = J->used + cand * k * ny;
    double *x0 = J->x0 + cand * ns;
    double *work = S->dense, *Lm = work + k * k + k, *ML = Lm + ny * F * ns;
    double *normal = ML + ny * F * ns, *toward = normal + ns * ns;
    if (modal_solve(G, H, k, ny, J->ridge, work, coef) != 0) return -1;
    memcpy(used, coef, sizeof(double) * (size_t)(k_in * ny));
    memset(x0, 0, sizeof(double) * (size_t)ns);
    if (J->estimate) {
        /* Lm[o][f][i]: output o's free-response coefficient f from x0 = e_i
         * (ModalCost._free_map); column i has entries only in its own group's rows f0(i)
         * .. f0(i) + width(i) - 1 (a mode's two, a real pole's one), so the products with M,
         * the free basis's Gram matrix, run over those rows alone */
        Py_ssize_t i = 0;
        for (Py_ssize_t g = 0; g < m; ++g) {
            const double a1 = poles[2 * g], a2 = poles[2 * g + 1];
            const double s10 = -1.0 / a2, s11 = -a1 / a2; /* S = [[0, 1], [s10, s11]] */
            for (Py_ssize_t j = 0; j < nu; ++j, i += 2)
                for (Py_ssize_t o = 0; o < ny; ++o) {
                    const double c1 = coef[i * ny + o], c2 = coef[(i + 1) * ny + o];
                    double *Lo = Lm + o * F * ns;
                    Lo[(2 * g) * ns + i] = c1;
                    Lo[(2 * g) * ns + i + 1] = c2;
                    Lo[(2 * g + 1) * ns + i] = c2 * s10;
                    Lo[(2 * g + 1) * ns + i + 1] = c1 + c2 * s11;
                }
        }
        for (Py_ssize_t g = 0; g < r; ++g)
            for (Py_ssize_t j = 0; j < nu; ++j, ++i)
                for (Py_ssize_t o = 0; o < ny; ++o)
                    Lm[o * F * ns + (2 * m + g) * ns + i] = coef[i * ny + o];
#define MODAL_ROWS(c) ((c) < 2 * m * nu ? 2 * ((c) / (2 * nu)) : 2 * m + ((c) - 2 * m * nu) / nu)
#define MODAL_WIDTH(c) ((c) < 2 * m * nu ? 2 : 1)
        /* ML = M L; toward = sum_o (M L)' beta_o, beta the free-response coefficients */
        for (Py_ssize_t o = 0; o < ny; ++o)
            for (Py_ssize_t c = 0; c < ns; ++c) {
                const Py_ssize_t e0 = MODAL_ROWS(c), w = MODAL_WIDTH(c);
                for (Py_ssize_t f = 0; f < F; ++f) {
                    double v = 0.0;
                    for (Py_ssize_t e = e0; e < e0 + w; ++e)
                        v += G[(k_in + f) * k + k_in + e] * Lm[o * F * ns + e * ns + c];
                    ML[o * F * ns + f * ns + c] = v;
                }
            }
        for (Py_ssize_t a = 0; a < ns; ++a) {
            const Py_ssize_t e0 = MODAL_ROWS(a), w = MODAL_WIDTH(a);
            double t = 0.0;
            for (Py_ssize_t o = 0; o < ny; ++o)
                for (Py_ssize_t f = 0; f < F; ++f)
                    t += ML[o * F * ns + f * ns + a] * coef[(k_in + f) * ny + o];
            toward[a] = t;
            for (Py_ssize_t c = 0; c < ns; ++c) { /* normal = sum_o L' M L */
                double v = 0.0;
                for (Py_ssize_t o = 0; o < ny; ++o)
                    for (Py_ssize_t f = e0; f < e0 + w; ++f)
                        v += Lm[o * F * ns + f * ns + a] * ML[o * F * ns + f * ns + c];
                normal[a * ns + c] = v;
            }
        }
        if (modal_solve(normal, toward, ns, 1, J->ridge, work, x0) != 0) return -1;
        for (Py_ssize_t f = 0; f < F; ++f)
            for (Py_ssize_t o = 0; o < ny; ++o) used[(k_in + f) * ny + o] = 0.0;
        for (Py_ssize_t c = 0; c < ns; ++c) { /* the free responses L x0 */
            const Py_ssize_t e0 = MODAL_ROWS(c), w = MODAL_WIDTH(c);
            for (Py_ssize_t e = e0; e < e0 + w; ++e)
                for (Py_ssize_t o = 0; o < ny; ++o)
                    used[(k_in + e) * ny + o] += Lm[o * F * ns + e * ns + c] * x0[c];
        }
#undef MODAL_ROWS
#undef MODAL_WIDTH
    }
    /* the sum of squares from the expansion, where its rounding bound allows */
    double total = 0.0, bound = 0.0;
    for (Py_ssize_t o = 0; o < ny; ++o) {
        double quad = 0.0, lin = 0.0, weight = 0.0;
        for (Py_ssize_t i = 0; i < k; ++i) {
            const double ci = used[i * ny + o];
            double row = 0.0;
            for (Py_ssize_t j = 0; j < k; ++j) row += G[i * k + j] * used[j * ny + o];
            quad += ci * row;
            lin += ci * H[i * ny + o];
            weight += fabs(ci) * sqrt(fabs(G[i * k + i]));
        }
        total += (J->yy[o] - 2.0 * lin) + quad;
        const double scale = sqrt(J->yy[o]) + weight;
        bound += J->rounding * scale * scale;
    }
    J->sse[cand] = bound <= J->tolerance * total ? total : NAN;
    return 0;
}

/* A candidate's rows, normal equations and errors (what J asks for); isa as modal_block's. */
static inline __attribute__((always_inline)) void
modal_candidate_in(const modal_job *J, modal_lanes *S, Py_ssize_t cand, const int isa)
{
    const Py_ssize_t N = J->N, ny = J->ny, k = J->k, kp = S->kp, L4 = S->L4;
    double *gram = J->gram ? J->gram + cand * k * k : NULL;
    double *rhs = J->rhs ? J->rhs + cand * k * ny : NULL;
    double *res = J->residual ? J->residual + cand * N * ny : NULL;
    double sse = 0.0;
    if (gram) {
        memset(S->g, 0, sizeof(double) * (size_t)(kp * kp));
        memset(S->h, 0, sizeof(double) * (size_t)(kp * ny));
    }
    if (J->coef) { /* the coefficients in internal order (zero on padding columns) */
        memset(S->c, 0, sizeof(double) * (size_t)(kp * ny));
        const double *coef = J->coef + cand * k * ny;
        for (Py_ssize_t i = 0; i < k; ++i)
            for (Py_ssize_t o = 0; o < ny; ++o)
                S->c[o * kp + S->map[i]] = S->scale[i] * coef[i * ny + o];
    }
    FLUSH_SUBNORMALS_BEGIN;
    for (Py_ssize_t t0 = 0; t0 < N; t0 += MODAL_BLOCK) {
        const Py_ssize_t b = N - t0 < MODAL_BLOCK ? N - t0 : MODAL_BLOCK;
        modal_rows(J, S, t0, b, S->rows, isa);
        if (J->phi)
            for (Py_ssize_t t = 0; t < b; ++t) {
                double *out = J->phi + (cand * N + t0 + t) * k;
                for (Py_ssize_t i = 0; i < k; ++i)
                    out[i] = S->scale[i] * S->rows[t * kp + S->map[i]];
            }
        if (gram) modal_block(S->rows, J->target + t0 * ny, b, kp, L4, ny, S->g, S->h, isa);
        if (J->coef)
            for (Py_ssize_t t = 0; t < b; ++t) {
                const double *rt = S->rows + t * kp, *yt = J->target + (t0 + t) * ny;
                for (Py_ssize_t o = 0; o < ny; ++o) {
                    const double e = yt[o] - modal_row_fit(rt, S->c + o * kp, kp, isa);
                    if (res) res[(t0 + t) * ny + o] = e;
                    sse += e * e;
                }
            }
        if (t0 + b == N) memcpy(S->last, S->rows + (b - 1) * kp, sizeof(double) * (size_t)L4);
    }
    FLUSH_SUBNORMALS_END;
    if (gram) /* the documented order and scale */
        for (Py_ssize_t i = 0; i < k; ++i) {
            const Py_ssize_t a = S->map[i];
            for (Py_ssize_t j = 0; j < k; ++j)
                gram[i * k + j] = S->scale[i] * S->scale[j] * modal_entry(S, a, S->map[j]);
            for (Py_ssize_t o = 0; o < ny; ++o) rhs[i * ny + o] = S->scale[i] * S->h[o * kp + a];
        }
    if (J->sse && !J->used) J->sse[cand] = sse;
    if (J->used) J->ok[cand] = modal_fit_candidate(J, S, cand) == 0;
}

/* modal_candidate_in once per instruction set (simd.h), the one in use picked at run time */
#if defined(SIMD_X86)
SIMD_V4 static void modal_candidate_v4(const modal_job *J, modal_lanes *S, Py_ssize_t cand)
{
    modal_candidate_in(J, S, cand, 2);
}
SIMD_V3 static void modal_candidate_v3(const modal_job *J, modal_lanes *S, Py_ssize_t cand)
{
    modal_candidate_in(J, S, cand, 1);
}
#endif
SIMD_G static void modal_candidate_g(const modal_job *J, modal_lanes *S, Py_ssize_t cand)
{
    modal_candidate_in(J, S, cand, 0);
}

static int modal_unit(const void *ctx, Py_ssize_t cand, void **scratch)
{
    const modal_job *J = (const modal_job *)ctx;
    const size_t bytes = sizeof(double) * modal_doubles(J) + sizeof(Py_ssize_t) * (size_t)J->k;
    if (*scratch == NULL && (*scratch = malloc(bytes)) == NULL) return -1;
    modal_lanes S;
    modal_begin(J, cand, *scratch, &S);
    SIMD_PICK(modal_candidate_g, modal_candidate_v3, modal_candidate_v4)(J, &S, cand);
    return 0;
}

int flexid_modal_run(const modal_job *J, int n_threads)
{
    return flexid_run_units(J, modal_unit, J->P, n_threads < 1 ? 1 : n_threads);
}
