/*
 * module.c: the Python glue of flexid._kernels, and nothing else: the arguments of every
 * entry point checked and turned into the job of its kernel, the kernel run without the GIL,
 * the method table and the module's initialisation.
 *
 * flexid._kernels holds the compiled inner loops of flexid's costs.  It is optional: the
 * package works without it (flexid.kernels falls back to the NumPy/SciPy reference path,
 * which the tests compare against this code).  Its entry points, each documented in the file
 * of its kernel:
 *
 *   schur_cohn(a, out), poly_mul(p, q, out)                               polynomial.c
 *   ar_run(a, forced, state, target, y_out, sse_out[, threads])           recursion.c
 *   arx_run(a, b, reg, state, target, y_out, sse_out[, threads[, first]]) recursion.c
 *   twin_rotor_run(params, x, u, out, n_sub, h, lock_yaw, square_law[, threads])
 *                                                                         twin_rotor.c
 *   arx_fit(a, reg, state0, target, offset, b_out, ok_out[, threads])     numerator.c
 *   arx_fit_shifted(a, reg, state0, target, offset, L, tol, b_out, ok_out, sse_out
 *                   [, threads[, free_state[, d, targets]]])              numerator.c
 *   free_fit(a, num, reg, target, basis, energies, window, cancel, errors_out, sse_out,
 *            coef_out[, threads[, first, noise]])                         initial_state.c
 *   flagged_fit(a, basis, lead, fbasis, sig, target, targets, restart, tol, coef_out,
 *               sse_out, ok_out[, threads])                               flagged.c
 *   modal_regressors(poles, u, phi, m, feedthrough, free_response[, threads])
 *   modal_normal(poles, u, target, gram, rhs, m, feedthrough, free_response[, threads])
 *   modal_residual(poles, u, target, coef, residual, sse, m, feedthrough, free_response
 *                  [, threads])
 *   modal_fit(poles, u, target, yy, gram, rhs, fitted, used, x0, sse, ok, m, feedthrough,
 *             estimate, ridge, rounding, tolerance[, threads])             modal.c
 *
 * and simd([name]), defined here: the instruction set the kernels run (simd.h), (in use,
 * best) as names, and with a name ("generic", "avx2", "avx512") that one from then on.
 *
 * An entry point's array arguments are described by a table (arg_spec: name, format, read or
 * written, rows some stride apart, None accepted), which get_args checks and acquires in
 * one go; the entry point then checks the shapes its kernel needs (SHAPE), fills the job and
 * runs it (RUN_WITHOUT_GIL), and finish releases the arrays and returns None, or NULL with
 * the exception set (MemoryError where the kernel ran out of memory).  Arrays are float64
 * ('d') unless said otherwise and C-contiguous, except those taken as rows: 2-D, each row
 * contiguous, the rows some non-negative number of doubles apart (e.g. a column block of a
 * population array).  The threads argument is the most threads a kernel splits its
 * population between (pool.c); the results do not depend on it.
 */
#include "simd.h"
#include "flagged.h"
#include "initial_state.h"
#include "modal.h"
#include "numerator.h"
#include "polynomial.h"
#include "pool.h"
#include "recursion.h"
#include "twin_rotor.h"

/* ------------------------------------------------------------------ instruction sets */

int flexid_simd = 0;             /* the one in use */
static int flexid_simd_best = 0; /* the best the CPU runs */
#if defined(__GNUC__)
static const char *const simd_names[3] = {"generic", "avx2", "avx512"};
#else
static const char *const simd_names[1] = {"scalar"};
#endif

static void simd_detect(void)
{
#if defined(SIMD_X86)
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
        flexid_simd_best = 1;
        if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
            __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw"))
            flexid_simd_best = 2;
    }
#endif
}

static PyObject *py_simd(PyObject *self, PyObject *args)
{
    const char *name = NULL;
    if (!PyArg_ParseTuple(args, "|z", &name)) return NULL;
    if (name) {
        int level = -1;
        for (int i = 0; i <= flexid_simd_best; ++i)
            if (strcmp(name, simd_names[i]) == 0) level = i;
        if (level < 0) {
            PyErr_Format(PyExc_ValueError, "simd: %s is not one this CPU runs (best: %s)",
                         name, simd_names[flexid_simd_best]);
            return NULL;
        }
        flexid_simd = level;
    }
    return Py_BuildValue("(ss)", simd_names[flexid_simd], simd_names[flexid_simd_best]);
}

/* ------------------------------------------------------------------ array arguments */

/* How an entry point takes one array argument */
typedef struct {
    const char *name;
    char format;   /* struct format of the items: 'd' float64, 'B' uint8 */
    char kind;     /* 'r' read, 'w' written (both C-contiguous), 's' read as rows (see the top) */
    char optional; /* None (or not passed) accepted */
} arg_spec;

/* One array argument of a call */
typedef struct {
    Py_buffer view;
    int have;          /* view holds a buffer (released by finish) */
    Py_ssize_t stride; /* kind 's': the row stride in doubles */
} arg;

#define IN(name) {name, 'd', 'r', 0}
#define IN_OPT(name) {name, 'd', 'r', 1}
#define ROWS(name) {name, 'd', 's', 0}
#define OUT(name) {name, 'd', 'w', 0}
#define OUT_OPT(name) {name, 'd', 'w', 1}
#define OUT_U8(name) {name, 'B', 'w', 0}
#define ROWS_OPT(name) {name, 'd', 's', 1}

/* rc of an entry point: an exception is set (0: the kernel ran, -1: it ran out of memory) */
#define RAISED (-2)

static int check_format(const char *fn, const Py_buffer *view, char want, const char *name)
{
    const char *fmt = view->format ? view->format : "B";
    if (fmt[0] == '<' || fmt[0] == '=' || fmt[0] == '@') ++fmt;
    if (fmt[0] != want || fmt[1] != '\0') {
        PyErr_Format(PyExc_TypeError, "%s: %s: expected format '%c', got '%s'", fn, name, want,
                     fmt);
        return -1;
    }
    return 0;
}

/* A (P, n) float64 array whose rows are contiguous, some (non-negative) number of doubles
 * apart; its row stride in doubles, or -1 with an exception set (and view released). */
static Py_ssize_t get_rows(const char *fn, PyObject *obj, Py_buffer *view, const char *name)
{
    if (PyObject_GetBuffer(obj, view, PyBUF_STRIDES | PyBUF_FORMAT) < 0) {
        PyErr_Format(PyExc_TypeError, "%s: %s: expected a buffer", fn, name);
        return -1;
    }
    if (check_format(fn, view, 'd', name) < 0) goto fail;
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

/* The n array arguments objs (NULL: not passed) of fn as spec describes them, into v (zeroed
 * by the caller); 0, or RAISED with an exception set (the arrays acquired so far are
 * released by finish). */
static int get_args(const char *fn, const arg_spec *spec, int n, PyObject *const *objs,
                    arg *v)
{
    for (int i = 0; i < n; ++i) {
        const arg_spec *s = &spec[i];
        if (objs[i] == NULL || objs[i] == Py_None) {
            if (s->optional) continue;
            PyErr_Format(PyExc_TypeError, "%s: %s is required", fn, s->name);
            return RAISED;
        }
        if (s->kind == 's') {
            v[i].stride = get_rows(fn, objs[i], &v[i].view, s->name);
            if (v[i].stride < 0) return RAISED;
            v[i].have = 1;
            continue;
        }
        const int writable = s->kind == 'w';
        const int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
        if (PyObject_GetBuffer(objs[i], &v[i].view, flags) < 0) {
            PyErr_Format(PyExc_TypeError, "%s: %s: expected a C-contiguous%s buffer", fn,
                         s->name, writable ? " writable" : "");
            return RAISED;
        }
        v[i].have = 1;
        if (check_format(fn, &v[i].view, s->format, s->name) < 0) return RAISED;
    }
    return 0;
}

/* 1 where a holds an array of nd dimensions of the sizes dims (ANY: any size) */
#define ANY PY_SSIZE_T_MIN
static int shape_is(const arg *a, int nd, const Py_ssize_t *dims)
{
    if (!a->have || a->view.ndim != nd) return 0;
    for (int k = 0; k < nd; ++k)
        if (dims[k] != ANY && a->view.shape[k] != dims[k]) return 0;
    return 1;
}
/* SHAPE(a, d0, d1, ...): a holds an array of that shape; OPT_SHAPE: or nothing */
#define SHAPE(a, ...)                                                                         \
    shape_is((a), (int)(sizeof((Py_ssize_t[]){__VA_ARGS__}) / sizeof(Py_ssize_t)),           \
             (Py_ssize_t[]){__VA_ARGS__})
#define OPT_SHAPE(a, ...) (!(a)->have || SHAPE(a, __VA_ARGS__))
/* size k of a, or -1 where a holds no array of more than k dimensions */
static Py_ssize_t dim(const arg *a, int k)
{
    return a->have && a->view.ndim > k ? a->view.shape[k] : -1;
}
#define DATA(a) ((a)->have ? (double *)(a)->view.buf : NULL)

/* RAISED with a ValueError */
static int invalid(const char *message)
{
    PyErr_SetString(PyExc_ValueError, message);
    return RAISED;
}

/* rc <- call, run without the GIL */
#define RUN_WITHOUT_GIL(rc, call)                                                             \
    do {                                                                                      \
        Py_BEGIN_ALLOW_THREADS                                                                \
        (rc) = (call);                                                                        \
        Py_END_ALLOW_THREADS                                                                  \
    } while (0)

/* The end of every entry point: the n arrays of v released; None, or NULL with the
 * exception set (MemoryError for rc -1). */
static PyObject *finish(arg *v, int n, int rc)
{
    for (int i = 0; i < n; ++i)
        if (v[i].have) PyBuffer_Release(&v[i].view);
    if (rc == RAISED) return NULL;
    if (rc < 0) return PyErr_NoMemory();
    Py_RETURN_NONE;
}

/* ------------------------------------------------------------------ entry points */

static PyObject *py_schur_cohn(PyObject *self, PyObject *args)
{
    enum { A, OUT_, N };
    static const arg_spec spec[N] = {ROWS("a"), OUT_U8("out")};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    if (!PyArg_ParseTuple(args, "OO", &o[A], &o[OUT_])) return NULL;
    int rc = get_args("schur_cohn", spec, N, o, v);
    if (rc == 0 && !SHAPE(&v[OUT_], dim(&v[A], 0)))
        rc = invalid("schur_cohn: a must be (P, n) and out (P,)");
    if (rc == 0)
        RUN_WITHOUT_GIL(rc, flexid_schur_cohn(DATA(&v[A]), v[A].stride, dim(&v[A], 0),
                                              dim(&v[A], 1), (unsigned char *)v[OUT_].view.buf));
    return finish(v, N, rc);
}

/* with the GIL: the products are small, and the caller's NumPy route takes microseconds */
static PyObject *py_poly_mul(PyObject *self, PyObject *args)
{
    enum { P_, Q_, OUT_, N };
    static const arg_spec spec[N] = {ROWS("p"), ROWS("q"), OUT("out")};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    if (!PyArg_ParseTuple(args, "OOO", &o[P_], &o[Q_], &o[OUT_])) return NULL;
    int rc = get_args("poly_mul", spec, N, o, v);
    const Py_ssize_t P = dim(&v[P_], 0), a = dim(&v[P_], 1), b = dim(&v[Q_], 1);
    if (rc == 0 && (dim(&v[Q_], 0) != P || a < 1 || b < 1 || !SHAPE(&v[OUT_], P, a + b - 1)))
        rc = invalid("poly_mul: p (P, a) and q (P, b) with a, b >= 1, out (P, a + b - 1)");
    if (rc == 0)
        flexid_poly_mul(DATA(&v[P_]), v[P_].stride, a, DATA(&v[Q_]), v[Q_].stride, b, P,
                        DATA(&v[OUT_]));
    return finish(v, N, rc);
}

/* The arrays ar_run and arx_run share (state, target, y_out, sse_out), checked against J's
 * P, na, K and first and put into J; 0 or RAISED. */
#define AR_TAIL IN("state"), IN_OPT("target"), OUT_OPT("y_out"), OUT_OPT("sse_out")
static int ar_tail(const char *fn, arg *v, ar_job *J)
{
    if (SHAPE(&v[0], J->na)) {
        J->state_stride = 0;
    } else if (SHAPE(&v[0], J->P, J->na)) {
        J->state_stride = J->na;
    } else {
        PyErr_Format(PyExc_ValueError, "%s: state must be (na,) or (P, na)", fn);
        return RAISED;
    }
    if (!OPT_SHAPE(&v[1], J->K - J->first)) {
        PyErr_Format(PyExc_ValueError, "%s: target must be (K - first,)", fn);
        return RAISED;
    }
    if (!OPT_SHAPE(&v[2], J->P, J->K)) {
        PyErr_Format(PyExc_ValueError, "%s: y_out must be (P, K)", fn);
        return RAISED;
    }
    if (!OPT_SHAPE(&v[3], J->P)) {
        PyErr_Format(PyExc_ValueError, "%s: sse_out must be (P,)", fn);
        return RAISED;
    }
    J->state = DATA(&v[0]);
    J->target = DATA(&v[1]);
    J->y = DATA(&v[2]);
    J->sse = DATA(&v[3]);
    return 0;
}

static PyObject *py_ar_run(PyObject *self, PyObject *args)
{
    enum { A, FORCED, STATE, N = STATE + 4 };
    static const arg_spec spec[N] = {IN("a"), IN("forced"), AR_TAIL};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    int n_threads = 1;
    if (!PyArg_ParseTuple(args, "OOOOOO|i", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5],
                          &n_threads))
        return NULL;
    int rc = get_args("ar_run", spec, N, o, v);
    ar_job J = {0};
    J.P = dim(&v[A], 0);
    J.na = dim(&v[A], 1);
    J.K = dim(&v[FORCED], 1);
    if (rc == 0 && (!SHAPE(&v[A], ANY, ANY) || !SHAPE(&v[FORCED], ANY, ANY)))
        rc = invalid("ar_run: a must be (P, na) and forced (P, K)");
    if (rc == 0 && dim(&v[FORCED], 0) != J.P) rc = invalid("ar_run: a and forced differ in P");
    J.a = DATA(&v[A]);
    J.a_stride = J.na;
    J.forced = DATA(&v[FORCED]);
    if (rc == 0) rc = ar_tail("ar_run", v + STATE, &J);
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_ar_run(&J, n_threads));
    return finish(v, N, rc);
}

static PyObject *py_arx_run(PyObject *self, PyObject *args)
{
    enum { A, B, REG, STATE, N = STATE + 4 };
    static const arg_spec spec[N] = {ROWS("a"), ROWS("b"), IN("reg"), AR_TAIL};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    int n_threads = 1;
    Py_ssize_t first = 0;
    if (!PyArg_ParseTuple(args, "OOOOOOO|in", &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6],
                          &n_threads, &first))
        return NULL;
    int rc = get_args("arx_run", spec, N, o, v);
    ar_job J = {0};
    J.P = dim(&v[A], 0);
    J.na = dim(&v[A], 1);
    J.nb = dim(&v[B], 1);
    J.K = dim(&v[REG], 0);
    if (rc == 0 && (dim(&v[B], 0) != J.P || !SHAPE(&v[REG], ANY, J.nb)))
        rc = invalid("arx_run: a must be (P, na), b (P, nb) and reg (K, nb)");
    if (rc == 0 && J.nb > AR_MAXNB && AR_MAXNB > 0) {
        PyErr_Format(PyExc_ValueError, "arx_run: at most %d input terms (nb)", AR_MAXNB);
        rc = RAISED;
    }
    if (rc == 0 && (first < 0 || first > J.K)) rc = invalid("arx_run: first must be in [0, K]");
    J.a = DATA(&v[A]);
    J.b = DATA(&v[B]);
    J.a_stride = v[A].stride;
    J.b_stride = v[B].stride;
    J.reg = DATA(&v[REG]);
    J.first = first;
    if (rc == 0) rc = ar_tail("arx_run", v + STATE, &J);
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_ar_run(&J, n_threads));
    return finish(v, N, rc);
}

static PyObject *py_twin_rotor_run(PyObject *self, PyObject *args)
{
    enum { PARAMS, X, U, OUT_, N };
    static const arg_spec spec[N] = {IN("params"), OUT("x"), IN("u"), OUT_OPT("out")};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    long n_sub;
    double h;
    int lock, square, n_threads = 1;
    if (!PyArg_ParseTuple(args, "OOOOldpp|i", &o[0], &o[1], &o[2], &o[3], &n_sub, &h, &lock,
                          &square, &n_threads))
        return NULL;
    int rc = get_args("twin_rotor_run", spec, N, o, v);
    const Py_ssize_t B = dim(&v[X], 0), S = dim(&v[U], 0);
    /* params (22,) shared by every rotor, or (B, 22): one row per rotor */
    const int rows = v[PARAMS].have && v[PARAMS].view.ndim == 2;
    if (rc == 0 && (!(SHAPE(&v[PARAMS], TRS_PARAMS) || SHAPE(&v[PARAMS], B, TRS_PARAMS)) ||
                    !SHAPE(&v[X], ANY, 7) || !SHAPE(&v[U], ANY, B, 2) || n_sub < 1))
        rc = invalid("twin_rotor_run: params (22,) or (B, 22), x (B, 7), u (S, B, 2), "
                     "n_sub >= 1");
    if (rc == 0 && !OPT_SHAPE(&v[OUT_], S, B, 7))
        rc = invalid("twin_rotor_run: out must be (S, B, 7)");
    const trs_job job = {
        DATA(&v[PARAMS]), rows ? TRS_PARAMS : 0, DATA(&v[X]), DATA(&v[U]), DATA(&v[OUT_]), S,
        B, n_sub, h, lock, square,
    };
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_twin_rotor_run(&job, n_threads));
    return finish(v, N, rc);
}

/* The sizes of a modal job from poles (P, 2 m + r) and u (N, nu), into J; 0 or RAISED. */
static int modal_sizes(const char *fn, arg *poles, arg *u, Py_ssize_t m, int feedthrough,
                       int free_response, modal_job *J)
{
    const Py_ssize_t P = dim(poles, 0), width = dim(poles, 1), N = dim(u, 0), nu = dim(u, 1);
    if (!SHAPE(poles, P, width) || !SHAPE(u, N, nu) || m < 0 || width - 2 * m < 0 || nu < 1 ||
        N < 1) {
        PyErr_Format(PyExc_ValueError, "%s: poles (P, 2 m + r) and u (N, nu)", fn);
        return RAISED;
    }
    J->poles = DATA(poles);
    J->u = DATA(u);
    J->P = P;
    J->m = m;
    J->r = width - 2 * m;
    J->N = N;
    J->nu = nu;
    J->k = nu * width + (feedthrough ? nu : 0) + (free_response ? width : 0);
    J->feedthrough = feedthrough;
    J->free_response = free_response;
    return 0;
}

static PyObject *py_modal_regressors(PyObject *self, PyObject *args)
{
    enum { POLES, U, PHI, N };
    static const arg_spec spec[N] = {IN("poles"), IN("u"), OUT("phi")};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    Py_ssize_t m;
    int feedthrough, free_response, n_threads = 1;
    if (!PyArg_ParseTuple(args, "OOOnpp|i", &o[POLES], &o[U], &o[PHI], &m, &feedthrough,
                          &free_response, &n_threads))
        return NULL;
    int rc = get_args("modal_regressors", spec, N, o, v);
    modal_job J = {0};
    if (rc == 0)
        rc = modal_sizes("modal_regressors", &v[POLES], &v[U], m, feedthrough, free_response, &J);
    if (rc == 0 && !SHAPE(&v[PHI], J.P, J.N, J.k))
        rc = invalid("modal_regressors: phi must be (P, N, k)");
    J.phi = DATA(&v[PHI]);
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_modal_run(&J, n_threads));
    return finish(v, N, rc);
}

static PyObject *py_modal_normal(PyObject *self, PyObject *args)
{
    enum { POLES, U, TARGET, GRAM, RHS, N };
    static const arg_spec spec[N] = {IN("poles"), IN("u"), IN("target"), OUT("gram"),
                                     OUT("rhs")};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    Py_ssize_t m;
    int feedthrough, free_response, n_threads = 1;
    if (!PyArg_ParseTuple(args, "OOOOOnpp|i", &o[POLES], &o[U], &o[TARGET], &o[GRAM], &o[RHS],
                          &m, &feedthrough, &free_response, &n_threads))
        return NULL;
    int rc = get_args("modal_normal", spec, N, o, v);
    modal_job J = {0};
    if (rc == 0)
        rc = modal_sizes("modal_normal", &v[POLES], &v[U], m, feedthrough, free_response, &J);
    J.ny = dim(&v[TARGET], 1);
    if (rc == 0 && (J.ny < 1 || !SHAPE(&v[TARGET], J.N, J.ny) ||
                    !SHAPE(&v[GRAM], J.P, J.k, J.k) || !SHAPE(&v[RHS], J.P, J.k, J.ny)))
        rc = invalid("modal_normal: target (N, ny), gram (P, k, k), rhs (P, k, ny)");
    J.target = DATA(&v[TARGET]);
    J.gram = DATA(&v[GRAM]);
    J.rhs = DATA(&v[RHS]);
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_modal_run(&J, n_threads));
    return finish(v, N, rc);
}

static PyObject *py_modal_residual(PyObject *self, PyObject *args)
{
    enum { POLES, U, TARGET, COEF, RESIDUAL, SSE, N };
    static const arg_spec spec[N] = {IN("poles"), IN("u"), IN("target"), IN("coef"),
                                     OUT_OPT("residual"), OUT("sse")};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    Py_ssize_t m;
    int feedthrough, free_response, n_threads = 1;
    if (!PyArg_ParseTuple(args, "OOOOOOnpp|i", &o[POLES], &o[U], &o[TARGET], &o[COEF],
                          &o[RESIDUAL], &o[SSE], &m, &feedthrough, &free_response, &n_threads))
        return NULL;
    int rc = get_args("modal_residual", spec, N, o, v);
    modal_job J = {0};
    if (rc == 0)
        rc = modal_sizes("modal_residual", &v[POLES], &v[U], m, feedthrough, free_response, &J);
    J.ny = dim(&v[TARGET], 1);
    if (rc == 0 && (J.ny < 1 || !SHAPE(&v[TARGET], J.N, J.ny) ||
                    !SHAPE(&v[COEF], J.P, J.k, J.ny) ||
                    !OPT_SHAPE(&v[RESIDUAL], J.P, J.N, J.ny) || !SHAPE(&v[SSE], J.P)))
        rc = invalid("modal_residual: target (N, ny), coef (P, k, ny), residual (P, N, ny) "
                     "or None, sse (P,)");
    J.target = DATA(&v[TARGET]);
    J.coef = DATA(&v[COEF]);
    J.residual = DATA(&v[RESIDUAL]);
    J.sse = DATA(&v[SSE]);
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_modal_run(&J, n_threads));
    return finish(v, N, rc);
}

static PyObject *py_modal_fit(PyObject *self, PyObject *args)
{
    enum { POLES, U, TARGET, YY, GRAM, RHS, FITTED, USED, X0, SSE, OK, N };
    static const arg_spec spec[N] = {IN("poles"), IN("u"),        IN("target"), IN("yy"),
                                     OUT("gram"),  OUT("rhs"),     OUT("fitted"), OUT("used"),
                                     OUT("x0"),    OUT("sse"),     OUT_U8("ok")};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    Py_ssize_t m;
    int feedthrough, estimate, n_threads = 1;
    double ridge, rounding, tolerance;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOOnppddd|i", &o[POLES], &o[U], &o[TARGET], &o[YY],
                          &o[GRAM], &o[RHS], &o[FITTED], &o[USED], &o[X0], &o[SSE], &o[OK], &m,
                          &feedthrough, &estimate, &ridge, &rounding, &tolerance, &n_threads))
        return NULL;
    int rc = get_args("modal_fit", spec, N, o, v);
    modal_job J = {0};
    if (rc == 0) rc = modal_sizes("modal_fit", &v[POLES], &v[U], m, feedthrough, estimate, &J);
    J.ny = dim(&v[TARGET], 1);
    if (rc == 0 && (J.ny < 1 || !SHAPE(&v[TARGET], J.N, J.ny) || !SHAPE(&v[YY], J.ny) ||
                    !SHAPE(&v[GRAM], J.P, J.k, J.k) || !SHAPE(&v[RHS], J.P, J.k, J.ny) ||
                    !SHAPE(&v[FITTED], J.P, J.k, J.ny) || !SHAPE(&v[USED], J.P, J.k, J.ny) ||
                    !SHAPE(&v[X0], J.P, J.nu * (2 * J.m + J.r)) || !SHAPE(&v[SSE], J.P) ||
                    !SHAPE(&v[OK], J.P)))
        rc = invalid("modal_fit: target (N, ny), yy (ny,), gram (P, k, k), rhs, fitted and "
                     "used (P, k, ny), x0 (P, nu (2 m + r)), sse and ok (P,)");
    J.target = DATA(&v[TARGET]);
    J.yy = DATA(&v[YY]);
    J.gram = DATA(&v[GRAM]);
    J.rhs = DATA(&v[RHS]);
    J.fitted = DATA(&v[FITTED]);
    J.used = DATA(&v[USED]);
    J.x0 = DATA(&v[X0]);
    J.sse = DATA(&v[SSE]);
    J.ok = (unsigned char *)v[OK].view.buf;
    J.ridge = ridge;
    J.rounding = rounding;
    J.tolerance = tolerance;
    J.estimate = estimate;
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_modal_run(&J, n_threads));
    return finish(v, N, rc);
}

#if defined(__GNUC__)
static PyObject *py_arx_fit(PyObject *self, PyObject *args)
{
    enum { A, REG, STATE0, TARGET, B_OUT, OK_OUT, N };
    static const arg_spec spec[N] = {ROWS("a"),     IN("reg"),    IN("state0"),
                                     IN("target"), OUT("b_out"), OUT_U8("ok_out")};
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    int n_threads = 1;
    Py_ssize_t offset;
    if (!PyArg_ParseTuple(args, "OOOOnOO|i", &o[A], &o[REG], &o[STATE0], &o[TARGET], &offset,
                          &o[B_OUT], &o[OK_OUT], &n_threads))
        return NULL;
    int rc = get_args("arx_fit", spec, N, o, v);
    const Py_ssize_t P = dim(&v[A], 0), na = dim(&v[A], 1), T = dim(&v[REG], 0),
                     nb = dim(&v[REG], 1), K = T - offset;
    if (rc == 0 && (na < 1 || na > AR_MAXNA || nb < 1 || nb > FIT_MAXNB || offset < 0 ||
                    K < 1 || !SHAPE(&v[REG], T, nb) || !SHAPE(&v[STATE0], na) ||
                    !SHAPE(&v[TARGET], K) || !SHAPE(&v[B_OUT], P, nb) ||
                    !SHAPE(&v[OK_OUT], P)))
        rc = invalid("arx_fit: a (P, na) with 1 <= na <= 16, reg (T, nb) with 1 <= nb <= 16, "
                     "state0 (na,), target (T - offset,), b_out (P, nb), ok_out (P,)");
    const fit_ctx problem = {
        DATA(&v[A]), v[A].stride, P, na, nb, DATA(&v[REG]), T, DATA(&v[STATE0]),
        DATA(&v[TARGET]), offset, DATA(&v[B_OUT]), (unsigned char *)v[OK_OUT].view.buf, NULL,
    };
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_arx_fit(&problem, n_threads));
    return finish(v, N, rc);
}

static PyObject *py_arx_fit_shifted(PyObject *self, PyObject *args)
{
    enum { A, REG, STATE0, TARGET, B_OUT, OK_OUT, SSE_OUT, D, TARGETS, N };
    static const arg_spec spec[N] = {
        ROWS("a"),       IN("reg"),          IN("state0"), IN("target"),    OUT("b_out"),
        OUT_U8("ok_out"), OUT_OPT("sse_out"), IN_OPT("d"),  IN_OPT("targets"),
    };
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    int n_threads = 1, free_state = 0;
    Py_ssize_t offset, L;
    double tol;
    if (!PyArg_ParseTuple(args, "OOOOnndOOO|iiOO", &o[A], &o[REG], &o[STATE0], &o[TARGET],
                          &offset, &L, &tol, &o[B_OUT], &o[OK_OUT], &o[SSE_OUT], &n_threads,
                          &free_state, &o[D], &o[TARGETS]))
        return NULL;
    int rc = get_args("arx_fit_shifted", spec, N, o, v);
    const Py_ssize_t P = dim(&v[A], 0), na = dim(&v[A], 1), T = dim(&v[REG], 0),
                     nb = dim(&v[REG], 1), K = T - offset;
    const Py_ssize_t Lmin = na > nb - 1 ? na : nb - 1, nd1 = dim(&v[D], 1);
    const int sse = v[SSE_OUT].have, d = v[D].have, targets = v[TARGETS].have;
    if (rc == 0 &&
        (na < 1 || na > VP_MAXNA || nb < 1 || nb > FIT_MAXNB || offset < 0 || K < 1 ||
         !SHAPE(&v[REG], T, nb) || !SHAPE(&v[STATE0], na) || !SHAPE(&v[TARGET], K) ||
         !SHAPE(&v[B_OUT], P, nb) || !SHAPE(&v[OK_OUT], P) || (L != 0 && L != Lmin) ||
         (sse && (!SHAPE(&v[SSE_OUT], P) || offset != 0)) ||
         (free_state && (L != Lmin || sse)) ||
         (d && (!SHAPE(&v[D], P, ANY) || nd1 < 1 || nd1 > nb || sse ||
                (L && !(free_state && nb - 1 <= na)))) ||
         (targets && (!SHAPE(&v[TARGETS], P, K) || sse))))
        rc = invalid("arx_fit_shifted: a (P, na) with 1 <= na <= 24, reg (T, nb) with 1 <= "
                     "nb <= 16, state0 (na,), target (T - offset,), L 0 or max(na, nb - 1) "
                     "(the latter with free_state), b_out (P, nb), ok_out (P,), sse_out "
                     "(P,) with offset 0 and without free_state, or None; d (P, nd + 1) "
                     "with nd < nb, with L 0 or free_state and nb - 1 <= na; targets (P, "
                     "T - offset); neither with sse_out");
    const vp_ctx problem = {
        DATA(&v[A]), v[A].stride, P, na, nb, L, DATA(&v[REG]), T, DATA(&v[STATE0]),
        DATA(&v[TARGET]), offset, DATA(&v[B_OUT]), (unsigned char *)v[OK_OUT].view.buf,
        DATA(&v[SSE_OUT]), tol, free_state ? na : 0, DATA(&v[D]), DATA(&v[TARGETS]),
        d ? nd1 : 0, d ? nd1 - 1 : 0, targets ? K : 0, NULL, NULL,
    };
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_arx_fit_shifted(&problem, n_threads));
    return finish(v, N, rc);
}

static PyObject *py_free_fit(PyObject *self, PyObject *args)
{
    enum { A, NUM, REG, TARGET, BASIS, ENERGIES, ERRORS, SSE, COEF, FIRST, NOISE, N };
    static const arg_spec spec[N] = {
        IN("a"),     ROWS("num"),         IN("reg"),          IN("target"),
        IN_OPT("basis"), IN_OPT("energies"), OUT_OPT("errors_out"), OUT("sse_out"),
        OUT("coef_out"), IN_OPT("first"),    IN_OPT("noise"),
    };
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    int n_threads = 1;
    Py_ssize_t window;
    double cancel;
    if (!PyArg_ParseTuple(args, "OOOOOOndOOO|iOO", &o[A], &o[NUM], &o[REG], &o[TARGET],
                          &o[BASIS], &o[ENERGIES], &window, &cancel, &o[ERRORS], &o[SSE],
                          &o[COEF], &n_threads, &o[FIRST], &o[NOISE]))
        return NULL;
    int rc = get_args("free_fit", spec, N, o, v);
    const Py_ssize_t P = dim(&v[A], 0), n = dim(&v[A], 1), nb = dim(&v[NUM], 1),
                     K = dim(&v[TARGET], 0);
    /* basis and energies: both or neither; first and noise: both or neither */
    if (rc == 0 &&
        (!SHAPE(&v[A], P, n) || n < 1 || n > FREE_MAXN || dim(&v[NUM], 0) != P ||
         nb > FREE_MAXNB || !SHAPE(&v[TARGET], K) || K < 1 || !SHAPE(&v[REG], K, nb) ||
         v[BASIS].have != v[ENERGIES].have || !OPT_SHAPE(&v[BASIS], P, n, n) ||
         !OPT_SHAPE(&v[ENERGIES], P, n) || window < n || !OPT_SHAPE(&v[ERRORS], P, K) ||
         !SHAPE(&v[SSE], P) || !SHAPE(&v[COEF], P, n) || v[FIRST].have != v[NOISE].have ||
         !OPT_SHAPE(&v[FIRST], P, n) || !OPT_SHAPE(&v[NOISE], P, 4)))
        rc = invalid("free_fit: a (P, n) with 1 <= n <= 24, num (P, nb) with nb <= 64, reg "
                     "(K, nb), target (K,), basis (P, n, n) and energies (P, n) or both None, "
                     "window >= n, errors_out (P, K) or None, sse_out (P,), coef_out (P, n), "
                     "first (P, n) and noise (P, 4) or both None");
    const free_job job = {
        DATA(&v[A]), DATA(&v[NUM]), DATA(&v[REG]), DATA(&v[TARGET]), DATA(&v[BASIS]),
        DATA(&v[ENERGIES]), P, n, nb, K, window, v[NUM].stride, DATA(&v[ERRORS]),
        DATA(&v[SSE]), DATA(&v[COEF]), cancel, DATA(&v[FIRST]), DATA(&v[NOISE]), NULL,
    };
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_free_fit(&job, n_threads));
    return finish(v, N, rc);
}
static PyObject *py_flagged_fit(PyObject *self, PyObject *args)
{
    enum { A, LEAD, SIG, TARGET, TARGETS, STATE, COEF, SSE, OK, N };
    static const arg_spec spec[N] = {
        ROWS("a"),         ROWS_OPT("lead"),   IN("sig"),      IN_OPT("target"),
        IN_OPT("targets"), IN_OPT("state"),    OUT("coef_out"), OUT("sse_out"),
        OUT_U8("ok_out"),
    };
    PyObject *o[N] = {NULL};
    arg v[N] = {0};
    int n_threads = 1, free_state, restart;
    double tol;
    if (!PyArg_ParseTuple(args, "OOOOOOppdOOO|i", &o[A], &o[LEAD], &o[SIG], &o[TARGET],
                          &o[TARGETS], &o[STATE], &free_state, &restart, &tol, &o[COEF],
                          &o[SSE], &o[OK], &n_threads))
        return NULL;
    int rc = get_args("flagged_fit", spec, N, o, v);
    const Py_ssize_t P = dim(&v[A], 0), n = dim(&v[A], 1), nb = dim(&v[COEF], 1),
                     Ns = dim(&v[SIG], 0), nl = v[LEAD].have ? dim(&v[LEAD], 1) : 1,
                     K = v[TARGET].have ? dim(&v[TARGET], 0) : dim(&v[TARGETS], 1);
    if (rc == 0 &&
        (n < 1 || n > FL_MAXN || nb < 1 || nb > FL_MAXNB || !SHAPE(&v[COEF], P, nb) ||
         (v[LEAD].have && (dim(&v[LEAD], 0) != P || nl < 1 || nl > FL_MAXNL)) ||
         !SHAPE(&v[SIG], Ns) || v[TARGET].have == v[TARGETS].have ||
         !OPT_SHAPE(&v[TARGET], K) || !OPT_SHAPE(&v[TARGETS], P, K) || K < 1 || K > Ns ||
         !OPT_SHAPE(&v[STATE], n) || (v[STATE].have && !v[TARGET].have) ||
         !SHAPE(&v[SSE], P) || !SHAPE(&v[OK], P)))
        rc = invalid("flagged_fit: a (P, n) with 1 <= n <= 24, lead (P, nl) with 1 <= nl <= 8 "
                     "or None, sig (N,), target (K,) or targets (P, K) (one of them) with 1 <= "
                     "K <= N, state (n,) with target or None, coef_out (P, nb) with 1 <= nb <= "
                     "16, sse_out (P,), ok_out (P,)");
    const fl_ctx problem = {
        DATA(&v[A]), DATA(&v[LEAD]), DATA(&v[SIG]), DATA(&v[TARGET]), DATA(&v[TARGETS]),
        DATA(&v[STATE]), P, n, nb, nl, Ns, K, v[A].stride,
        v[LEAD].have ? v[LEAD].stride : 0, free_state, restart, tol, DATA(&v[COEF]),
        DATA(&v[SSE]), (unsigned char *)v[OK].view.buf,
    };
    if (rc == 0) RUN_WITHOUT_GIL(rc, flexid_flagged_fit(&problem, n_threads));
    return finish(v, N, rc);
}
#endif

/* ------------------------------------------------------------------ the module */

static PyMethodDef methods[] = {
    {"poly_mul", py_poly_mul, METH_VARARGS,
     "poly_mul(p, q, out): row-wise polynomial products of p (P, a) and q (P, b) into out."},
    {"schur_cohn", py_schur_cohn, METH_VARARGS,
     "schur_cohn(a, out): strict stability of monic denominators a (P, n) into out (P,) uint8."},
    {"ar_run", py_ar_run, METH_VARARGS,
     "ar_run(a, forced, state, target, y_out, sse_out[, threads]): batched AR recursion "
     "(see recursion.c)."},
    {"arx_run", py_arx_run, METH_VARARGS,
     "arx_run(a, b, reg, state, target, y_out, sse_out[, threads[, first]]): batched ARX "
     "recursion, the input part computed from the regressor rows reg, sse over t >= first "
     "(see recursion.c)."},
    {"modal_regressors", py_modal_regressors, METH_VARARGS,
     "modal_regressors(poles, u, phi, m, feedthrough, free_response[, threads]): the modal "
     "state-space cost's regressors of every candidate (see modal.c)."},
    {"modal_normal", py_modal_normal, METH_VARARGS,
     "modal_normal(poles, u, target, gram, rhs, m, feedthrough, free_response[, threads]): "
     "their normal equations (see modal.c)."},
    {"modal_residual", py_modal_residual, METH_VARARGS,
     "modal_residual(poles, u, target, coef, residual, sse, m, feedthrough, free_response"
     "[, threads]): their fit's errors and sums of squares (see modal.c)."},
    {"modal_fit", py_modal_fit, METH_VARARGS,
     "modal_fit(poles, u, target, yy, gram, rhs, fitted, used, x0, sse, ok, m, feedthrough, "
     "estimate, ridge, rounding, tolerance[, threads]): every candidate's fit from its normal "
     "equations (see modal.c)."},
    {"twin_rotor_run", py_twin_rotor_run, METH_VARARGS,
     "twin_rotor_run(params, x, u, out, n_sub, h, lock_yaw, square_law[, threads]): twin rotor "
     "RK4; params (22,) shared or (B, 22) per rotor (see twin_rotor.c)."},
#if defined(__GNUC__)
    {"arx_fit", py_arx_fit, METH_VARARGS,
     "arx_fit(a, reg, state0, target, offset, b_out, ok_out[, threads]): least-squares "
     "numerators of the simulation cost for denominators a (see numerator.c)."},
    {"arx_fit_shifted", py_arx_fit_shifted, METH_VARARGS,
     "arx_fit_shifted(a, reg, state0, target, offset, L, tol, b_out, ok_out, sse_out"
     "[, threads[, free_state[, d, targets]]]): arx_fit for regressor columns that are delays "
     "of one signal, from two recursions and lag sums (see numerator.c)."},
    {"free_fit", py_free_fit, METH_VARARGS,
     "free_fit(a, num, reg, target, basis, energies, window, cancel, errors_out, sse_out, "
     "coef_out[, threads[, first, noise]]): errors of 1/den filters with the initial state "
     "fitted (see initial_state.c)."},
    {"flagged_fit", py_flagged_fit, METH_VARARGS,
     "flagged_fit(a, lead, sig, target, targets, state, free, restart, tol, coef_out, sse_out, "
     "ok_out[, threads]): the fitted numerator, solved in the orthogonal numerators' basis "
     "(see flagged.c)."},
#endif
    {"simd", py_simd, METH_VARARGS,
     "simd([name]): (in use, best) instruction sets of the kernels; with a name ('generic', "
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
    flexid_pool_init();
    simd_detect();
    flexid_simd = flexid_simd_best;
    return PyModule_Create(&module);
}
