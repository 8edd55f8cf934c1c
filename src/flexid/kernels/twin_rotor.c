/*
 * twin_rotor.c: the twin rotor's RK4, and nothing else.
 *
 *   twin_rotor_run(params, x, u, out, n_sub, h, lock_yaw, square_law[, threads])
 *       The twin rotor's RK4 (flexid.envs.twin_rotor_physics: the equations of its batched
 *       ``derivatives`` and ``_rk4``, with the constants divided out once and sin, cos and
 *       tanh as inline polynomials, 4 rotors per SIMD vector): x (B, 7) states, updated in
 *       place; u (S, B, 2) voltages held over each of S samples; out (S, B, 7) or None, the
 *       states after each sample; params (22,) in the order of TRS_PARAMS (twin_rotor.h),
 *       shared by every rotor, or (B, 22), one row per rotor (a population of parameter
 *       sets); n_sub substeps of length h per sample.  lock_yaw holds the yaw at rest;
 *       square_law takes each rotor's moment as tau (a tau + b) rather than tau (a |tau| +
 *       b).  The rotors are split between `threads` threads, 4 a unit.
 *
 * With GCC the block of 4 rotors has an AVX2/FMA clone chosen at load time (SIMD_CLONES)
 * beside the baseline; without GCC's vector extensions the equations run as written in the
 * reference route, one rotor at a time.
 */
#include "twin_rotor.h"
#include "pool.h"

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
    SIMD_CLONES                                                                               \
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

/* Rotors 4 u .. 4 u + 3 of the run, all its samples. */
static int trs_unit(const void *ctx, Py_ssize_t unit, void **scratch)
{
    const trs_job *J = (const trs_job *)ctx;
    (void)scratch;
    trs_group(J->p, J->p_stride, J->x, J->u, J->out, J->S, J->B, 4 * unit, J->n_sub, J->h,
              J->lock, J->square);
    return 0;
}

int flexid_twin_rotor_run(const trs_job *J, int n_threads)
{
    return flexid_run_units(J, trs_unit, (J->B + 3) / 4, n_threads < 1 ? 1 : n_threads);
}
