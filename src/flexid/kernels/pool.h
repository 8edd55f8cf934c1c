/*
 * pool.h: the thread pool of flexid._kernels (pool.c), for the kernels that split a
 * population between threads.
 */
#ifndef FLEXID_POOL_H
#define FLEXID_POOL_H

#include "simd.h"

/* One unit of a job (a block of candidates): ctx the job, scratch a pointer of the thread
 * running it (NULL at first; allocated by the unit on first use, freed with free() at the
 * end).  0, or -1 when out of memory. */
typedef int (*unit_fn)(const void *ctx, Py_ssize_t unit, void **scratch);

/* Runs units 0 .. n_units - 1 of fn on up to n_threads threads; 0, or -1 out of memory.
 * Called without the GIL. */
int flexid_run_units(const void *ctx, unit_fn fn, Py_ssize_t n_units, int n_threads);
/* The same on the calling thread alone. */
int flexid_run_units_serial(const void *ctx, unit_fn fn, Py_ssize_t n_units);
/* At module import: a child process made by fork starts without helpers. */
void flexid_pool_init(void);

#endif /* FLEXID_POOL_H */
