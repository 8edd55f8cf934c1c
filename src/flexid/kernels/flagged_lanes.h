/*
 * flagged_lanes.h: the kernel of flagged.c for one vector type, included by flagged.c once
 * per width (FLV the vector of FLW candidates, FLN(name) the name of its copy): 4 lanes, and
 * 8 for the AVX-512 copy.  Not a header of its own job: it is flagged.c's code, written once
 * for both widths.
 */
typedef void (*FLN(fl_rec_fn))(const FLV *A, const FLV *f, FLV *y, Py_ssize_t len, FLV *Z0);

/* y(t) = f(t) + Z_0, Z_k <- Z_(k+1) - a_(k+1) y(t): the transposed direct form with the state
 * in registers (n a constant), from the state Z0, which is left as the state after the last
 * sample (f NULL: no input) */
static inline __attribute__((always_inline)) void
FLN(fl_rec_impl)(const FLV *A, const FLV *f, FLV *y, Py_ssize_t len, FLV *Z0, const int n)
{
    const FLV zero = {0};
    FLV Z[FL_MAXN], Av[FL_MAXN];
    for (int k = 0; k < n; ++k) {
        Z[k] = Z0[k];
        Av[k] = A[k];
    }
#define FL_STEP(ft)                                                                           \
    do {                                                                                      \
        const FLV yt_ = (ft) + Z[0];                                                          \
        _Pragma("GCC unroll 24") for (int k_ = 0; k_ < n - 1; ++k_)                           \
            Z[k_] = Z[k_ + 1] - Av[k_] * yt_;                                                 \
        Z[n - 1] = zero - Av[n - 1] * yt_;                                                    \
        y[t] = yt_;                                                                           \
    } while (0)
    if (f)
        for (Py_ssize_t t = 0; t < len; ++t) FL_STEP(f[t]);
    else
        for (Py_ssize_t t = 0; t < len; ++t) FL_STEP(zero);
#undef FL_STEP
    for (int k = 0; k < n; ++k) Z0[k] = Z[k]; /* the state after y(len - 1): a run goes on */
}

/* G stages m0 .. m0 + G - 1 of the lattice (Levinson's step-up of the numerators) over
 * samples i = 0 .. len - 1, the stages' delayed values in registers: from fin = f_(m0-1) and
 * bin = b_(m0-1), and d[j] = b_(m0-1+j) one sample before the first (left as those after the
 * last), b_m(t) = b_(m-1)(t - 1) + k_m f_(m-1)(t) into out row m - m0 (ld apart) where store,
 * f_m(t) = f_(m-1)(t) + k_m b_(m-1)(t - 1), and the last stage's f and b into fout and bout
 * (which may be fin and bin: each sample is read before it is written) */
static inline __attribute__((always_inline)) void
FLN(fl_stages)(const FLV *fin, const FLV *bin, FLV *fout, FLV *bout, FLV *d, const FLV *k,
               const int G, const Py_ssize_t len, FLV *out, const Py_ssize_t ld, const int store)
{
    FLV dd[4], kk[4];
    _Pragma("GCC unroll 4") for (int j = 0; j < G; ++j) {
        dd[j] = d[j];
        kk[j] = k[j];
    }
    for (Py_ssize_t i = 0; i < len; ++i) {
        FLV fv = fin[i], bv = bin[i];
        _Pragma("GCC unroll 4") for (int j = 0; j < G; ++j) {
            const FLV old = dd[j];
            dd[j] = bv;
            bv = old + kk[j] * fv;
            fv = fv + kk[j] * old;
            if (store) out[j * ld + i] = bv;
        }
        fout[i] = fv;
        bout[i] = bv;
    }
    _Pragma("GCC unroll 4") for (int j = 0; j < G; ++j) d[j] = dd[j];
}

/* The regressors P_m(q) s, m = 0 .. count - 1, of the orthogonal numerators' basis in
 * lattice form, over the samples t = t0 .. t1 - 1 of a run that goes on from call to call:
 * P_m is the reversed step-up polynomial of order m (m <= n; kref[m] its reflection
 * coefficient, from den's step-down) and P_m = q^-(m - n) P_n above, so
 * b_m(t) = b_(m-1)(t - 1) + k_m f_(m-1)(t), f_m(t) = f_(m-1)(t) + k_m b_(m-1)(t - 1),
 * b_0 = f_0 = s: two multiply-adds a regressor and sample where the FIR filters of the basis
 * take m + 1, in groups of four stages that keep their delayed values in registers (one pass
 * over the samples a group, not one a stage).  s indexed by t, with zeros before t = 0;
 * with store, out row m (ld apart) gets b_m(t) at t - off (t0 >= off); bd (n) holds the
 * b_m(t0 - 1), m < top, zeros before the first call; f and bp (t1 - t0 each) are scratch,
 * and btop (indexed by t, count - n or more zeros before t = 0) keeps b_n for the delays. */
static inline __attribute__((always_inline)) void
FLN(fl_lattice)(const FLV *s, const FLV *kref, const int count, const int n, Py_ssize_t t0,
                Py_ssize_t t1, Py_ssize_t off, FLV *out, Py_ssize_t ld, const int store, FLV *bd,
                FLV *f, FLV *bp, FLV *btop)
{
    const int top = count - 1 < n ? count - 1 : n; /* stages of the step-up */
    const Py_ssize_t len = t1 - t0;
    FLV *o = out + (t0 - off);
    if (store)
        for (Py_ssize_t i = 0; i < len; ++i) o[i] = s[t0 + i];
    const FLV *fin = s + t0, *bin = s + t0;
    for (int m0 = 1; m0 <= top; m0 += 4) {
        const int G = top - m0 + 1 < 4 ? top - m0 + 1 : 4;
        FLV *om = o + m0 * ld, *dm = bd + m0 - 1;
        const FLV *km = kref + m0;
        if (G == 4)
            FLN(fl_stages)(fin, bin, f, bp, dm, km, 4, len, om, ld, store);
        else if (G == 3)
            FLN(fl_stages)(fin, bin, f, bp, dm, km, 3, len, om, ld, store);
        else if (G == 2)
            FLN(fl_stages)(fin, bin, f, bp, dm, km, 2, len, om, ld, store);
        else
            FLN(fl_stages)(fin, bin, f, bp, dm, km, 1, len, om, ld, store);
        fin = f;
        bin = bp;
    }
    if (count - 1 <= top) return;
    for (Py_ssize_t i = 0; i < len; ++i) btop[t0 + i] = bin[i];
    if (store)
        for (int m = top + 1; m < count; ++m) /* q^-(m - n) P_n: b_n delayed */
            for (Py_ssize_t i = 0; i < len; ++i) o[m * ld + i] = btop[t0 + i - (m - top)];
}

/* out[i * ros + j * cos] += sum_k X[i * len + k] Y[j * len + k], k = k0 .. k1 - 1 in order,
 * for a tile of tr x tc entries (with tri only those with b <= a, the lower half of a tile on
 * the diagonal), their sums in registers */
static inline __attribute__((always_inline)) void
FLN(fl_tile)(const FLV *X, const FLV *Y, const Py_ssize_t len, const int i0, const int j0,
        const int tr, const int tc, FLV *out, const Py_ssize_t ros, const Py_ssize_t cos,
        const Py_ssize_t k0, const Py_ssize_t k1, const int tri)
{
    FLV s[4][4];
    _Pragma("GCC unroll 4") for (int a = 0; a < tr; ++a)
        _Pragma("GCC unroll 4") for (int b = 0; b < tc; ++b)
            if (!tri || b <= a) s[a][b] = out[(i0 + a) * ros + (j0 + b) * cos];
    for (Py_ssize_t k = k0; k < k1; ++k) {
        FLV x[4], y[4];
        _Pragma("GCC unroll 4") for (int a = 0; a < tr; ++a) x[a] = X[(i0 + a) * len + k];
        _Pragma("GCC unroll 4") for (int b = 0; b < tc; ++b) y[b] = Y[(j0 + b) * len + k];
        _Pragma("GCC unroll 4") for (int a = 0; a < tr; ++a)
            _Pragma("GCC unroll 4") for (int b = 0; b < tc; ++b)
                if (!tri || b <= a) s[a][b] += x[a] * y[b];
    }
    _Pragma("GCC unroll 4") for (int a = 0; a < tr; ++a)
        _Pragma("GCC unroll 4") for (int b = 0; b < tc; ++b)
            if (!tri || b <= a) out[(i0 + a) * ros + (j0 + b) * cos] = s[a][b];
}

/* out += the nx x ny products of fl_tile over the samples k0 .. k1 - 1 (with lower, only the
 * entries j <= i), in tiles of t x t (t = 4 with 32 registers, 3 with 16), the edges in
 * 1 x t, t x 1 and 1 x 1.  Called chunk after chunk of FL_CHUNK samples, so that a chunk
 * of the rows stays close in the cache for all its tiles, and a tile's own rows in the first
 * level (tile after tile over the whole record would stream the rows, a megabyte and more,
 * from further out each time); each sum still adds its products in the order of k. */
static inline __attribute__((always_inline)) void
FLN(fl_products)(const FLV *X, const int nx, const FLV *Y, const int ny, const Py_ssize_t len,
            FLV *out, const Py_ssize_t ros, const Py_ssize_t cos, const int lower, const int t,
            const Py_ssize_t k0, const Py_ssize_t k1)
{
    const int mx = nx - nx % t, my = ny - ny % t;
    for (int i = 0; i < mx; i += t)
        for (int j = 0; j < my && (!lower || j <= i + t - 1); j += t) {
            if (lower && j == i)
                FLN(fl_tile)(X, Y, len, i, j, t, t, out, ros, cos, k0, k1, 1);
            else
                FLN(fl_tile)(X, Y, len, i, j, t, t, out, ros, cos, k0, k1, 0);
        }
    for (int i = mx; i < nx; ++i)
        for (int j = 0; j < my && (!lower || j <= i); j += t)
            FLN(fl_tile)(X, Y, len, i, j, 1, t, out, ros, cos, k0, k1, 0);
    for (int j = my; j < ny; ++j)
        for (int i = lower ? j - j % t : 0; i < mx; i += t)
            FLN(fl_tile)(X, Y, len, i, j, t, 1, out, ros, cos, k0, k1, 0);
    for (int i = mx; i < nx; ++i)
        for (int j = my; j < ny && (!lower || j <= i); ++j)
            FLN(fl_tile)(X, Y, len, i, j, 1, 1, out, ros, cos, k0, k1, 0);
}

/* The residual e = z - sum_j c_j R_j over the len samples (R rows of len, z the row after
 * the last) and st_j = sum_t R_j(t) e(t), 8 samples side by side: the sweep over the rows
 * that forms e on those 8 leaves them in the first-level cache for the sweep that adds their
 * products (each st_j in the order of t).  Each e^2 into ee[t % 8] (ee[0] for the samples
 * after the last 8); fl_sum8(ee) is then sum e^2.  e itself is not kept. */
static inline __attribute__((always_inline)) void
FLN(fl_residual)(const FLV *R, const int nr, const FLV *c, const Py_ssize_t len, FLV ee[8],
                 FLV *st)
{
    const FLV zero = {0};
    const FLV *z = R + nr * len;
    _Pragma("GCC unroll 8") for (int r = 0; r < 8; ++r) ee[r] = zero;
    for (int j = 0; j < nr; ++j) st[j] = zero;
    Py_ssize_t t = 0;
    for (; t + 8 <= len; t += 8) {
        FLV s[8];
        _Pragma("GCC unroll 8") for (int r = 0; r < 8; ++r) s[r] = z[t + r];
        for (int j = 0; j < nr; ++j) {
            const FLV cj = c[j], *x = R + j * len + t;
            _Pragma("GCC unroll 8") for (int r = 0; r < 8; ++r) s[r] -= cj * x[r];
        }
        _Pragma("GCC unroll 8") for (int r = 0; r < 8; ++r) ee[r] += s[r] * s[r];
        for (int j = 0; j < nr; ++j) {
            const FLV *x = R + j * len + t;
            FLV a = st[j];
            _Pragma("GCC unroll 8") for (int r = 0; r < 8; ++r) a += x[r] * s[r];
            st[j] = a;
        }
    }
    for (; t < len; ++t) {
        FLV s = z[t];
        for (int j = 0; j < nr; ++j) s -= c[j] * R[j * len + t];
        ee[0] += s * s;
        for (int j = 0; j < nr; ++j) st[j] += R[j * len + t] * s;
    }
}

static inline __attribute__((always_inline)) FLV FLN(fl_sum8)(const FLV ee[8])
{
    return ((ee[0] + ee[1]) + (ee[2] + ee[3])) + ((ee[4] + ee[5]) + (ee[6] + ee[7]));
}

/* Cholesky of the n x n G (lower triangle read and written) on the 4 lanes at once, the
 * reciprocals of the pivots into Rp; good[l] = 0 where a pivot is not positive and finite
 * (that lane goes on with 1, its results discarded) */
static inline __attribute__((always_inline)) void FLN(fl_cholesky)(FLV *G, FLV *Rp, const int n,
                                                              int good[FLW])
{
    const FLV one = (FLV){0} + 1.0;
    for (int j = 0; j < n; ++j) {
        FLV d = G[j * n + j];
        for (int l = 0; l < FLW; ++l)
            if (!(d[l] > 0) || !isfinite(d[l])) {
                good[l] = 0;
                d[l] = 1.0;
            }
        for (int l = 0; l < FLW; ++l) d[l] = sqrt(d[l]);
        const FLV r = one / d;
        G[j * n + j] = d;
        Rp[j] = r;
        for (int i = j + 1; i < n; ++i) G[i * n + j] *= r;
        for (int i = j + 1; i < n; ++i) {
            const FLV gij = G[i * n + j];
            for (int k = j + 1; k <= i; ++k) G[i * n + k] -= gij * G[k * n + j];
        }
    }
}

/* v <- L^-T L^-1 v, L and Rp from fl_cholesky */
static inline __attribute__((always_inline)) void FLN(fl_solve)(const FLV *L, const FLV *Rp, FLV *v,
                                                           const int n)
{
    for (int i = 0; i < n; ++i) {
        FLV s = v[i];
        for (int k = 0; k < i; ++k) s -= L[i * n + k] * v[k];
        v[i] = s * Rp[i];
    }
    for (int i = n - 1; i >= 0; --i) {
        FLV s = v[i];
        for (int k = i + 1; k < n; ++k) s -= L[k * n + i] * v[k];
        v[i] = s * Rp[i];
    }
}

/* The block of candidates q .. q + FLW - 1 (lanes past P repeat candidate q; their results are not
 * written), its signals in buf (see fl_unit) */
static inline __attribute__((always_inline)) void
FLN(fl_quad_impl)(const fl_ctx *c, Py_ssize_t q, FLV *buf, const int wide, const FLN(fl_rec_fn) rec)
{
    const Py_ssize_t P = c->P, N = c->N, K = c->K, start = N - K;
    const int n = (int)c->n, nb = (int)c->nb, nl = (int)c->nl, free_ = c->free_state;
    const int nr = nb + (free_ ? n : 0), tile = wide ? 4 : 3;
    const Py_ssize_t w = P - q < FLW ? P - q : FLW;
    const FLV zero = {0};
    Py_ssize_t row[FLW];
    for (int l = 0; l < FLW; ++l) row[l] = q + (l < w ? l : 0);
    FLV A[FL_MAXN], Lv[FL_MAXNL], Z[FL_MAXN];
    for (int k = 0; k < n; ++k)
        for (int l = 0; l < FLW; ++l) A[k][l] = c->a[row[l] * c->a_stride + k];
    for (int k = 0; k < nl && c->lead; ++k)
        for (int l = 0; l < FLW; ++l) Lv[k][l] = c->lead[row[l] * c->lead_stride + k];
    /* the scratch: w and x (or one forcing) with FL_PAD zeros before each, h, the regressors
     * and the target (rows of K), a row of K (the free response from the past outputs), the
     * Gram matrix and its factor, b_n of the lattice (FL_PAD zeros before), the lattice's two
     * rows of a span */
    FLV *wv = buf + FL_PAD, *xv = wv + N + FL_PAD, *hv = xv + N + FL_PAD;
    FLV *R = hv + K, *e = R + (Py_ssize_t)(nr + 1) * K, *G = e + K;
    FLV *Lc = G + (nr + 1) * (nr + 1);
    FLV *btop = Lc + nr * nr + FL_PAD, *fc = btop + N, *bc = fc + FL_SPAN;
    /* w(t) = sum_k lead_k sig(t - k) over t = 0 .. N - 1 (zeros before) */
    for (Py_ssize_t t = 0; t < N; ++t) {
        if (!c->lead) {
            wv[t] = zero + c->sig[t];
            continue;
        }
        FLV s = zero;
        for (int k = 0; k < nl && k <= t; ++k) s += Lv[k] * c->sig[t - k];
        wv[t] = s;
    }
    /* den's reflection coefficients k_1 .. k_n by its step-down, lane by lane (all zero,
     * the plain shifts, where it breaks down in rounding: orthogonal_numerators' rule) */
    FLV kref[FL_MAXN + 1];
    for (int l = 0; l < FLW; ++l) {
        double work[FL_MAXN], k[FL_MAXN];
        const int fine = flexid_reflection(c->a + row[l] * c->a_stride, n, work, k);
        kref[0][l] = 0.0;
        for (int m = 1; m <= n; ++m) kref[m][l] = fine ? k[m - 1] : 0.0;
    }
    for (int k = 0; k < n; ++k) Z[k] = zero;
    /* the lattice's input: x = w / den from rest, or with restart w itself (each regressor's
     * recursion then runs from rest at t = start) */
    const FLV *lin = wv;
    if (!c->restart) {
        rec(A, wv, xv, N, Z);
        lin = xv;
    }
    if (free_) { /* the impulse response from t = start: y(0) = 1 */
        for (int k = 0; k < n; ++k) Z[k] = zero;
        Z[0] = zero + 1.0;
        rec(A, NULL, hv, K, Z);
    }
    FLV *zt = R + (Py_ssize_t)nr * K;
    for (Py_ssize_t t = 0; t < K; ++t) {
        if (c->target) {
            zt[t] = zero + c->target[t];
        } else {
            for (int l = 0; l < FLW; ++l) zt[t][l] = c->targets[row[l] * K + t];
        }
    }
    if (c->state) { /* less the free response from the past outputs (ar_recursion's state) */
        for (int i = 0; i < n; ++i) {
            Z[i] = zero;
            for (int j = 1; j <= n - i; ++j) Z[i] -= A[i + j - 1] * c->state[j - 1];
        }
        rec(A, NULL, e, K, Z);
        for (Py_ssize_t t = 0; t < K; ++t) zt[t] -= e[t];
    }
    /* The regressors span by span, and the Gram matrix G (nr + 1 rows of nr + 1, its last
     * row the products with z) over each span while its rows are in the cache: the lattice
     * over the samples before start first (nothing stored), then each span's P_m(q) of the
     * input (and with restart their recursions, each going on from its state), the free
     * responses' Q_k(q) h, and the span's products, chunk by chunk */
    FLV bdx[FL_MAXN], bdh[FL_MAXN], Zr[FL_MAXNB][FL_MAXN];
    for (int k = 0; k < n; ++k) bdx[k] = bdh[k] = zero;
    for (int m = 0; m < nb; ++m)
        for (int k = 0; k < n; ++k) Zr[m][k] = zero;
    for (Py_ssize_t t = 0; t < start; t += FL_SPAN) {
        const Py_ssize_t t1 = t + FL_SPAN < start ? t + FL_SPAN : start;
        FLN(fl_lattice)(lin, kref, nb, n, t, t1, 0, R, K, 0, bdx, fc, bc, btop);
    }
    const int ld = nr + 1;
    for (int i = 0; i < ld * ld; ++i) G[i] = zero;
    for (Py_ssize_t s0 = 0; s0 < K; s0 += FL_SPAN) {
        const Py_ssize_t s1 = s0 + FL_SPAN < K ? s0 + FL_SPAN : K;
        FLN(fl_lattice)(lin, kref, nb, n, start + s0, start + s1, start, R, K, 1, bdx, fc, bc,
                        btop);
        if (c->restart)
            for (int m = 0; m < nb; ++m) rec(A, R + m * K + s0, R + m * K + s0, s1 - s0, Zr[m]);
        if (free_)
            FLN(fl_lattice)(hv, kref, n, n, s0, s1, 0, R + (Py_ssize_t)nb * K, K, 1, bdh, fc, bc,
                            NULL);
        for (Py_ssize_t k0 = s0; k0 < s1; k0 += FL_CHUNK) {
            const Py_ssize_t k1 = k0 + FL_CHUNK < s1 ? k0 + FL_CHUNK : s1;
            FLN(fl_products)(R, nr + 1, R, nr, K, G, ld, 1, 1, tile, k0, k1);
        }
    }
    FLV sc[FL_MAXR], inv[FL_MAXR], Rp[FL_MAXR], cf[FL_MAXR], st[FL_MAXR];
    for (int i = 0; i < nr; ++i)
        for (int l = 0; l < FLW; ++l) {
            const double d = sqrt(G[i * ld + i][l]);
            sc[i][l] = d == 0 ? 1.0 : d;
            inv[i][l] = 1.0 / sc[i][l];
        }
    for (int i = 0; i < nr; ++i)
        for (int j = 0; j <= i; ++j) Lc[i * nr + j] = G[i * ld + j] * inv[i] * inv[j];
    int good[FLW];
    for (int l = 0; l < FLW; ++l) good[l] = 1;
    FLN(fl_cholesky)(Lc, Rp, nr, good);
    for (int i = 0; i < nr; ++i) cf[i] = G[nr * ld + i] * inv[i];
    FLN(fl_solve)(Lc, Rp, cf, nr);
    for (int i = 0; i < nr; ++i) cf[i] *= inv[i];
    /* refinement: a lane stops once its step is below tol relative to the solution.  The
     * sum of squares at the solution: that of the residual where the lane did not move since
     * it was formed, else from it and the step s, |e - R s|^2 = |e|^2 - 2 s.R'e + s'Gs (s is
     * below 1e-9 of the solution once it stops: the correction is far smaller than |e|^2, so
     * nothing cancels, and no pass over the regressors is left for it) */
    int moving[FLW], any = 1;
    for (int l = 0; l < FLW; ++l) moving[l] = l < w;
    FLV sse = zero, raw[FL_MAXR];
    for (int it = 0; it < 2 && any; ++it) {
        FLV e8[8];
        FLN(fl_residual)(R, nr, cf, K, e8, st);
        const FLV ee = FLN(fl_sum8)(e8);
        for (int i = 0; i < nr; ++i) {
            raw[i] = st[i];
            st[i] *= inv[i];
        }
        FLN(fl_solve)(Lc, Rp, st, nr);
        for (int l = 0; l < FLW; ++l) {
            if (!moving[l]) {
                sse[l] = ee[l];
                continue;
            }
            double big = 0.0, size = 0.0, sr = 0.0, sgs = 0.0;
            for (int i = 0; i < nr; ++i) {
                const double si = st[i][l] * inv[i][l];
                st[i][l] = si;
                cf[i][l] += si;
                big = fabs(si) > big || isnan(si) ? fabs(si) : big;
                size = fabs(cf[i][l]) > size || isnan(cf[i][l]) ? fabs(cf[i][l]) : size;
                sr += si * raw[i][l];
            }
            for (int i = 0; i < nr; ++i) {
                double gs = 0.0;
                for (int j = 0; j < nr; ++j)
                    gs += (j <= i ? G[i * ld + j][l] : G[j * ld + i][l]) * st[j][l];
                sgs += st[i][l] * gs;
            }
            sse[l] = ee[l] - 2.0 * sr + sgs;
            moving[l] = !(big <= c->tol * (size > 0 ? size : 1.0));
        }
        any = 0;
        for (int l = 0; l < FLW; ++l) any |= moving[l];
    }
    /* B = sum_m c_m P_m, the P_m by the step-up of the same coefficients (the polynomials
     * the lattice applied): A_m = A_(m-1) + k_m q^-1 rev(A_(m-1)), P_m = rev(A_m) for m <= n,
     * q^-(m - n) P_n above */
    FLV Am[FL_MAXN + 1], An[FL_MAXN + 1], bq[FL_MAXNB];
    const int top = nb - 1 < n ? nb - 1 : n;
    for (int i = 0; i < nb; ++i) bq[i] = zero;
    Am[0] = zero + 1.0;
    bq[0] = cf[0];
    for (int m = 1; m <= top; ++m) {
        An[0] = Am[0];
        for (int i = 1; i < m; ++i) An[i] = Am[i] + kref[m] * Am[m - i];
        An[m] = kref[m];
        for (int i = 0; i <= m; ++i) Am[i] = An[i];
        for (int j = 0; j <= m; ++j) bq[j] += cf[m] * Am[m - j];
    }
    for (int m = top + 1; m < nb; ++m)
        for (int j = m - top; j <= m; ++j) bq[j] += cf[m] * Am[m - j];
    for (Py_ssize_t l = 0; l < w; ++l) {
        int fine = good[l] && !moving[l] && isfinite(sse[l]);
        for (int i = 0; i < nb; ++i) {
            c->coef[(q + l) * nb + i] = bq[i][l];
            fine = fine && isfinite(bq[i][l]);
        }
        c->sse[q + l] = sse[l];
        c->ok[q + l] = (unsigned char)fine;
    }
}
