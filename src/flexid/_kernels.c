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
 *   ar_run(a, forced, state, target, y_out, sse_out)
 *       The autoregressive recursion y(t) = f(t) - sum_i a_i y(t - i), t = 0..K-1, for
 *       every candidate: a (P, na), forced (P, K), state (P, na) holding
 *       [y(-1), ..., y(-na)] (or (na,) shared by all candidates), target (K,) or None,
 *       y_out (P, K) or None, sse_out (P,) or None (sum over t of (target - y)^2).
 *
 *   twin_rotor_run(params, x, u, out, n_sub, h, lock_yaw, square_law)
 *       The twin rotor's RK4 (flexid.envs.twin_rotor_physics: the equations of its batched
 *       ``derivatives`` and ``_rk4``, with the constants divided out once and sin, cos and
 *       tanh as inline polynomials, 4 rotors per SIMD vector): x (B, 7) states, updated in
 *       place; u (S, B, 2) voltages held over each of S samples; out (S, B, 7) or None, the
 *       states after each sample; params (22,) in the order of TRS_PARAMS below, shared by
 *       every rotor, or (B, 22), one row per rotor (a population of parameter sets); n_sub
 *       substeps of length h per sample.
 *
 * The recursion runs on blocks of LANES candidates at once, with the block's history in
 * one contiguous buffer, so that the compiler turns the lane loops into SIMD instructions;
 * on x86-64 with GCC an AVX2/FMA clone is chosen at load time when the CPU has it.  The
 * GIL is released while the kernels run.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdlib.h>
#include <stdint.h>
#include <string.h>

#if defined(_MSC_VER)
#define restrict __restrict
#endif

#define LANES 16 /* lanes per block, in vectors of 4 doubles */

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define FLEXID_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define FLEXID_CLONES
#endif

/* ------------------------------------------------------------------ Schur-Cohn */

static void schur_cohn_rows(const double *a, Py_ssize_t P, Py_ssize_t n, unsigned char *out,
                            double *c)
{
    for (Py_ssize_t p = 0; p < P; ++p) {
        const double *row = a + p * n;
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

/* One block of LANES candidates.  hist has (na + K) * LANES doubles: rows 0..na-1 hold the
 * initial state, row na + t the output at t (first filled with the forced term).  With
 * GCC/Clang the lanes are held in four 4-wide vector registers (GCC vector extensions),
 * which keeps the accumulators out of memory across the loop over the lags. */
#if defined(__GNUC__)
typedef double v4d __attribute__((vector_size(32), aligned(8)));

/* nv vectors of 4 lanes; nv is a constant in each caller, so acc[] and s[] live in
 * registers */
static inline __attribute__((always_inline)) void
ar_block_impl(const double *restrict coef, double *restrict hist, Py_ssize_t na, Py_ssize_t K,
              const double *restrict target, double *restrict sse, const int nv)
{
    const Py_ssize_t lanes = 4 * nv;
    v4d s[LANES / 4], acc[LANES / 4];
    for (int v = 0; v < nv; ++v) s[v] = (v4d){0, 0, 0, 0};
    for (Py_ssize_t t = 0; t < K; ++t) {
        v4d *cur = (v4d *)(hist + (na + t) * lanes);
        for (int v = 0; v < nv; ++v) acc[v] = cur[v];
        for (Py_ssize_t k = na; k >= 1; --k) {
            const v4d *past = (const v4d *)(hist + (na + t - k) * lanes);
            const v4d *ck = (const v4d *)(coef + (k - 1) * lanes);
            for (int v = 0; v < nv; ++v) acc[v] -= ck[v] * past[v];
        }
        for (int v = 0; v < nv; ++v) cur[v] = acc[v];
        if (target) {
            const double yt = target[t];
            for (int v = 0; v < nv; ++v) {
                const v4d e = yt - acc[v];
                s[v] += e * e;
            }
        }
    }
    for (int v = 0; v < nv; ++v)
        for (int j = 0; j < 4; ++j) sse[4 * v + j] = s[v][j];
}

FLEXID_CLONES
static void ar_block(const double *restrict coef, double *restrict hist, Py_ssize_t na,
                     Py_ssize_t K, const double *restrict target, double *restrict sse)
{
    ar_block_impl(coef, hist, na, K, target, sse, LANES / 4);
}

FLEXID_CLONES
static void ar_block_narrow(const double *restrict coef, double *restrict hist, Py_ssize_t na,
                            Py_ssize_t K, const double *restrict target, double *restrict sse)
{
    ar_block_impl(coef, hist, na, K, target, sse, 1);
}
#define HAVE_NARROW 1
#else
static void ar_block(const double *restrict coef, double *restrict hist, Py_ssize_t na,
                     Py_ssize_t K, const double *restrict target, double *restrict sse)
{
    double s[LANES] = {0};
    for (Py_ssize_t t = 0; t < K; ++t) {
        double *cur = hist + (na + t) * LANES;
        for (Py_ssize_t k = na; k >= 1; --k) {
            const double *past = hist + (na + t - k) * LANES;
            const double *ck = coef + (k - 1) * LANES;
            for (int j = 0; j < LANES; ++j) cur[j] -= ck[j] * past[j];
        }
        if (target) {
            for (int j = 0; j < LANES; ++j) {
                const double e = target[t] - cur[j];
                s[j] += e * e;
            }
        }
    }
    for (int j = 0; j < LANES; ++j) sse[j] = s[j];
}
#endif

static void ar_rows(const double *a, const double *forced, const double *state,
                    Py_ssize_t state_stride, const double *target, double *y, double *sse,
                    Py_ssize_t P, Py_ssize_t na, Py_ssize_t K, double *coef, double *hist)
{
    double s[LANES];
    for (Py_ssize_t g = 0; g < P;) {
        Py_ssize_t lanes = LANES;
#ifdef HAVE_NARROW
        if (P - g <= 4) lanes = 4; /* a short tail: one 4-lane block, not a mostly empty wide one */
#endif
        const Py_ssize_t w = (P - g < lanes) ? P - g : lanes;
        memset(coef, 0, (size_t)(na > 0 ? na : 1) * lanes * sizeof(double));
        if (w < lanes) memset(hist, 0, (size_t)(na + K) * lanes * sizeof(double));
        for (Py_ssize_t j = 0; j < w; ++j) {
            const double *aj = a + (g + j) * na;
            const double *sj = state + (g + j) * state_stride;
            for (Py_ssize_t i = 0; i < na; ++i) {
                coef[i * lanes + j] = aj[i];
                hist[(na - 1 - i) * lanes + j] = sj[i]; /* y(-1-i) */
            }
        }
        /* transpose the block's forced terms into the history rows: time outer, so the
         * writes are contiguous and the reads are w sequential streams */
        const double *fg = forced + g * K;
        for (Py_ssize_t t = 0; t < K; ++t) {
            double *row = hist + (na + t) * lanes;
            for (Py_ssize_t j = 0; j < w; ++j) row[j] = fg[j * K + t];
        }
#ifdef HAVE_NARROW
        if (lanes == 4)
            ar_block_narrow(coef, hist, na, K, target, s);
        else
#endif
            ar_block(coef, hist, na, K, target, s);
        if (y) {
            double *yg = y + g * K;
            for (Py_ssize_t t = 0; t < K; ++t) {
                const double *row = hist + (na + t) * lanes;
                for (Py_ssize_t j = 0; j < w; ++j) yg[j * K + t] = row[j];
            }
        }
        if (sse)
            for (Py_ssize_t j = 0; j < w; ++j) sse[g + j] = s[j];
        g += w;
    }
}

/* ------------------------------------------------------------------ Python glue */

/* n doubles aligned to a cache line (vectors that straddle two lines defeat store-to-load
 * forwarding in the recursion); free *raw afterwards. */
static double *alloc_aligned(size_t n, void **raw)
{
    *raw = malloc(n * sizeof(double) + 64);
    if (!*raw) return NULL;
    return (double *)(((uintptr_t)*raw + 63) & ~(uintptr_t)63);
}

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

static PyObject *py_schur_cohn(PyObject *self, PyObject *args)
{
    PyObject *a_obj, *out_obj;
    Py_buffer a, out;
    if (!PyArg_ParseTuple(args, "OO", &a_obj, &out_obj)) return NULL;
    if (get_buffer(a_obj, &a, 0, "a") < 0) return NULL;
    if (get_buffer(out_obj, &out, 1, "out") < 0) {
        PyBuffer_Release(&a);
        return NULL;
    }
    PyObject *result = NULL;
    if (check_format(&a, "d", "a") < 0 || check_format(&out, "B", "out") < 0) goto done;
    if (a.ndim != 2 || out.ndim != 1 || out.shape[0] != a.shape[0]) {
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
    schur_cohn_rows((const double *)a.buf, P, n, (unsigned char *)out.buf, c);
    Py_END_ALLOW_THREADS
    free(c);
    result = Py_None;
    Py_INCREF(result);
done:
    PyBuffer_Release(&a);
    PyBuffer_Release(&out);
    return result;
}

static PyObject *py_ar_run(PyObject *self, PyObject *args)
{
    PyObject *objs[6];
    Py_buffer bufs[6];
    int have[6] = {0};
    static const char *names[6] = {"a", "forced", "state", "target", "y_out", "sse_out"};
    if (!PyArg_ParseTuple(args, "OOOOOO", &objs[0], &objs[1], &objs[2], &objs[3], &objs[4],
                          &objs[5]))
        return NULL;
    PyObject *result = NULL;
    for (int i = 0; i < 6; ++i) {
        if (objs[i] == Py_None) {
            if (i < 3) {
                PyErr_Format(PyExc_TypeError, "ar_run: %s is required", names[i]);
                goto done;
            }
            continue;
        }
        if (get_buffer(objs[i], &bufs[i], i >= 4, names[i]) < 0) goto done;
        have[i] = 1;
        if (check_format(&bufs[i], "d", names[i]) < 0) goto done;
    }
    if (bufs[0].ndim != 2 || bufs[1].ndim != 2) {
        PyErr_SetString(PyExc_ValueError, "ar_run: a must be (P, na) and forced (P, K)");
        goto done;
    }
    Py_ssize_t P = bufs[0].shape[0], na = bufs[0].shape[1], K = bufs[1].shape[1];
    if (bufs[1].shape[0] != P) {
        PyErr_SetString(PyExc_ValueError, "ar_run: a and forced differ in P");
        goto done;
    }
    Py_ssize_t state_stride;
    if (bufs[2].ndim == 1 && bufs[2].shape[0] == na) {
        state_stride = 0;
    } else if (bufs[2].ndim == 2 && bufs[2].shape[0] == P && bufs[2].shape[1] == na) {
        state_stride = na;
    } else {
        PyErr_SetString(PyExc_ValueError, "ar_run: state must be (na,) or (P, na)");
        goto done;
    }
    if (have[3] && (bufs[3].ndim != 1 || bufs[3].shape[0] != K)) {
        PyErr_SetString(PyExc_ValueError, "ar_run: target must be (K,)");
        goto done;
    }
    if (have[4] && (bufs[4].ndim != 2 || bufs[4].shape[0] != P || bufs[4].shape[1] != K)) {
        PyErr_SetString(PyExc_ValueError, "ar_run: y_out must be (P, K)");
        goto done;
    }
    if (have[5] && (bufs[5].ndim != 1 || bufs[5].shape[0] != P)) {
        PyErr_SetString(PyExc_ValueError, "ar_run: sse_out must be (P,)");
        goto done;
    }
    void *coef_raw = NULL, *hist_raw = NULL;
    double *coef = alloc_aligned((size_t)(na > 0 ? na : 1) * LANES, &coef_raw);
    double *hist = alloc_aligned((size_t)(na + K > 0 ? na + K : 1) * LANES, &hist_raw);
    if (!coef || !hist) {
        free(coef_raw);
        free(hist_raw);
        PyErr_NoMemory();
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    ar_rows((const double *)bufs[0].buf, (const double *)bufs[1].buf,
            (const double *)bufs[2].buf, state_stride,
            have[3] ? (const double *)bufs[3].buf : NULL, have[4] ? (double *)bufs[4].buf : NULL,
            have[5] ? (double *)bufs[5].buf : NULL, P, na, K, coef, hist);
    Py_END_ALLOW_THREADS
    free(coef_raw);
    free(hist_raw);
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < 6; ++i)
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

static void trs_run(const double *p, Py_ssize_t p_stride, double *x, const double *u,
                    double *out, Py_ssize_t S, Py_ssize_t B, long n_sub, double h, int lock,
                    int square)
{
    static const trs_block_fn blocks[2][2] = {
        {trs_block, trs_block_sq},
        {trs_block_lock, trs_block_lock_sq},
    };
    trs_consts c;
    const trs_block_fn block = blocks[lock != 0][square != 0];
    for (Py_ssize_t g = 0; g < B; g += 4) {
        /* lanes past the last rotor take the block's first parameters (they run at rest) */
        const double *lanes[4];
        for (Py_ssize_t j = 0; j < 4; ++j) lanes[j] = p + p_stride * (g + j < B ? g + j : g);
        trs_fold(lanes, &c);
        block(&c, x, u, out, S, B, g, n_sub, h);
    }
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

static void trs_run(const double *params, Py_ssize_t p_stride, double *x, const double *u,
                    double *out, Py_ssize_t S, Py_ssize_t B, long n_sub, double h, int lock,
                    int square)
{
    double k1[7], k2[7], k3[7], k4[7], y[7];
    const double hh = 0.5 * h, h6 = h / 6.0;
    for (Py_ssize_t s = 0; s < S; ++s) {
        for (Py_ssize_t b = 0; b < B; ++b) {
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

static PyObject *py_twin_rotor_run(PyObject *self, PyObject *args)
{
    PyObject *objs[4];
    Py_buffer bufs[4];
    int have[4] = {0};
    static const char *names[4] = {"params", "x", "u", "out"};
    long n_sub;
    double h;
    int lock, square;
    if (!PyArg_ParseTuple(args, "OOOOldpp", &objs[0], &objs[1], &objs[2], &objs[3], &n_sub, &h,
                          &lock, &square))
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
    Py_BEGIN_ALLOW_THREADS
    trs_run((const double *)bufs[0].buf, rows ? TRS_PARAMS : 0, (double *)bufs[1].buf,
            (const double *)bufs[2].buf, have[3] ? (double *)bufs[3].buf : NULL, S, B, n_sub, h,
            lock, square);
    Py_END_ALLOW_THREADS
    result = Py_None;
    Py_INCREF(result);
done:
    for (int i = 0; i < 4; ++i)
        if (have[i]) PyBuffer_Release(&bufs[i]);
    return result;
}

static PyMethodDef methods[] = {
    {"schur_cohn", py_schur_cohn, METH_VARARGS,
     "schur_cohn(a, out): strict stability of monic denominators a (P, n) into out (P,) uint8."},
    {"ar_run", py_ar_run, METH_VARARGS,
     "ar_run(a, forced, state, target, y_out, sse_out): batched AR recursion (see module)."},
    {"twin_rotor_run", py_twin_rotor_run, METH_VARARGS,
     "twin_rotor_run(params, x, u, out, n_sub, h, lock_yaw, square_law): twin rotor RK4; "
     "params (22,) shared or (B, 22) per rotor."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_kernels",
    "Compiled inner loops of flexid's batched ARX costs (optional; see flexid.kernels).", -1,
    methods,
};

PyMODINIT_FUNC PyInit__kernels(void) { return PyModule_Create(&module); }
