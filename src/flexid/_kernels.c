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
 *       The twin rotor's RK4 (flexid.envs.twin_rotor_physics: the same equations as its
 *       batched ``derivatives`` and ``_rk4``, in the same order of operations): x (B, 7)
 *       states, updated in place; u (S, B, 2) voltages held over each of S samples;
 *       out (S, B, 7) or None, the states after each sample; params (22,) in the order of
 *       TRS_PARAMS below; n_sub substeps of length h per sample.
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

static void trs_run(const double *p, double *x, const double *u, double *out, Py_ssize_t S,
                    Py_ssize_t B, long n_sub, double h, int lock, int square)
{
    double k1[7], k2[7], k3[7], k4[7], y[7];
    const double hh = 0.5 * h, h6 = h / 6.0;
    for (Py_ssize_t s = 0; s < S; ++s) {
        for (Py_ssize_t b = 0; b < B; ++b) {
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
    if (bufs[0].ndim != 1 || bufs[0].shape[0] != TRS_PARAMS || bufs[1].ndim != 2 ||
        bufs[1].shape[1] != 7 || bufs[2].ndim != 3 || bufs[2].shape[1] != bufs[1].shape[0] ||
        bufs[2].shape[2] != 2 || n_sub < 1) {
        PyErr_SetString(PyExc_ValueError,
                        "twin_rotor_run: params (22,), x (B, 7), u (S, B, 2), n_sub >= 1");
        goto done;
    }
    Py_ssize_t S = bufs[2].shape[0], B = bufs[1].shape[0];
    if (have[3] && (bufs[3].ndim != 3 || bufs[3].shape[0] != S || bufs[3].shape[1] != B ||
                    bufs[3].shape[2] != 7)) {
        PyErr_SetString(PyExc_ValueError, "twin_rotor_run: out must be (S, B, 7)");
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    trs_run((const double *)bufs[0].buf, (double *)bufs[1].buf, (const double *)bufs[2].buf,
            have[3] ? (double *)bufs[3].buf : NULL, S, B, n_sub, h, lock, square);
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
     "twin_rotor_run(params, x, u, out, n_sub, h, lock_yaw, square_law): twin rotor RK4."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_kernels",
    "Compiled inner loops of flexid's batched ARX costs (optional; see flexid.kernels).", -1,
    methods,
};

PyMODINIT_FUNC PyInit__kernels(void) { return PyModule_Create(&module); }
