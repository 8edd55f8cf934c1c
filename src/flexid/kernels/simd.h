/*
 * simd.h: what every file of flexid._kernels shares, and nothing else: the C and Python
 * headers, the vector types, the instruction sets a kernel is compiled for and the macros
 * that make one copy of a kernel per order and instruction set and choose among them at run
 * time, and the subnormal flushing of the least-squares fits.
 *
 * Each kernel is written once, as an always-inlined function of its order (a constant in
 * every copy, so that its loops unroll and its state stays in registers), and compiled three
 * times on x86-64 with GCC: AVX-512 ("avx512": 32 vector registers, the kernels still run
 * 256-bit vectors of 4 candidates), AVX2/FMA ("avx2") and the baseline ("generic", at -O2: it
 * runs only on CPUs from before 2013).  flexid_simd says which copies run (set at import to
 * the best the CPU has, and by _kernels.simd()); SIMD_PICK reads it.  Elsewhere (other
 * compilers or CPUs) the generic copies alone are built.  The copies of a kernel live in the
 * file of that kernel, with everything they inline, so that the compiler sees exactly the
 * code it inlines and contracts into each.
 */
#ifndef FLEXID_SIMD_H
#define FLEXID_SIMD_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#if defined(_MSC_VER)
#define restrict __restrict
#endif

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

/* The instruction set in use: 0 generic, 1 avx2, 2 avx512 (module.c sets it). */
extern int flexid_simd;

#if defined(__GNUC__)
/* 4 candidates (or rotors) per vector, one per lane; aligned(8): loads from any double */
typedef double v4d __attribute__((vector_size(32), aligned(8)));
typedef double v2d __attribute__((vector_size(16), aligned(8)));
typedef long long v4i __attribute__((vector_size(32), aligned(8)));
/* the vector helpers are always inlined, so no vector crosses a call boundary */
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

/* The kernels' copies on x86-64 with GCC: AVX-512, AVX2/FMA, and the baseline */
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
#define SIMD_X86 1
#define SIMD_V4 __attribute__((target("avx2,fma,avx512f,avx512vl,avx512dq,avx512bw")))
#define SIMD_V3 __attribute__((target("avx2,fma")))
/* The baseline copies of the kernels run only on x86-64 CPUs without AVX2/FMA (pre-2013):
 * compiled at -O2 they lose little there, and the build takes a third of the time. */
#define SIMD_G __attribute__((optimize("O2")))
#else
#define SIMD_G
#endif

/* A function outside the per-order tables with an AVX2/FMA clone chosen at load time */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define SIMD_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define SIMD_CLONES
#endif

/* SIMD_COPIES(DEF, n): DEF(n, isa, TARGET, wide) once per instruction set, isa the suffix of
 * the copy's name (g, v3_, v4_), wide 1 where 32 vector registers hold a kernel's state. */
#if defined(SIMD_X86)
#define SIMD_COPIES(DEF, n) DEF(n, g, SIMD_G, 0) DEF(n, v3_, SIMD_V3, 0) DEF(n, v4_, SIMD_V4, 1)
#else
#define SIMD_COPIES(DEF, n) DEF(n, g, SIMD_G, 0)
#endif
/* SIMD_COPIES for the orders 1 .. 16 and 1 .. 24 */
#define SIMD_ORDERS16(DEF)                                                                    \
    SIMD_COPIES(DEF, 1) SIMD_COPIES(DEF, 2) SIMD_COPIES(DEF, 3) SIMD_COPIES(DEF, 4)           \
    SIMD_COPIES(DEF, 5) SIMD_COPIES(DEF, 6) SIMD_COPIES(DEF, 7) SIMD_COPIES(DEF, 8)           \
    SIMD_COPIES(DEF, 9) SIMD_COPIES(DEF, 10) SIMD_COPIES(DEF, 11) SIMD_COPIES(DEF, 12)        \
    SIMD_COPIES(DEF, 13) SIMD_COPIES(DEF, 14) SIMD_COPIES(DEF, 15) SIMD_COPIES(DEF, 16)
#define SIMD_ORDERS24(DEF)                                                                    \
    SIMD_ORDERS16(DEF)                                                                        \
    SIMD_COPIES(DEF, 17) SIMD_COPIES(DEF, 18) SIMD_COPIES(DEF, 19) SIMD_COPIES(DEF, 20)       \
    SIMD_COPIES(DEF, 21) SIMD_COPIES(DEF, 22) SIMD_COPIES(DEF, 23) SIMD_COPIES(DEF, 24)

/* The initialiser of a table of the copies p1 .. p16 (p24) by order, entry 0 NULL */
#define SIMD_TABLE16(p)                                                                       \
    {                                                                                         \
        NULL, p##1, p##2, p##3, p##4, p##5, p##6, p##7, p##8, p##9, p##10, p##11, p##12,      \
            p##13, p##14, p##15, p##16                                                        \
    }
#define SIMD_TABLE24(p)                                                                       \
    {                                                                                         \
        NULL, p##1, p##2, p##3, p##4, p##5, p##6, p##7, p##8, p##9, p##10, p##11, p##12,      \
            p##13, p##14, p##15, p##16, p##17, p##18, p##19, p##20, p##21, p##22, p##23, p##24 \
    }

/* The one of three things (tables, functions) of the instruction set in use; the generic
 * one where only that is built (the others are then not named) */
#if defined(SIMD_X86)
#define SIMD_PICK(g, v3, v4) (flexid_simd == 2 ? (v4) : flexid_simd == 1 ? (v3) : (g))
#else
#define SIMD_PICK(g, v3, v4) (g)
#endif

#endif /* FLEXID_SIMD_H */
