/*
 * pool.c: the thread pool of flexid._kernels, and nothing else.
 *
 * Entry points (pool.h): flexid_run_units(ctx, fn, n_units, n_threads) runs the units of a
 * job (blocks of candidates) on the calling thread and up to n_threads - 1 helper threads;
 * flexid_run_units_serial runs them on the calling thread; flexid_pool_init registers the
 * after-fork reset.  POSIX threads where the compiler is GCC-compatible on a Unix; elsewhere
 * every job runs on the calling thread.
 *
 * A job's units are claimed one at a time, by the calling thread and by up to n - 1 helper
 * threads woken for the call.  The caller waits only for units a helper has claimed, never
 * for a helper to wake or to finish: on a busy machine a helper the scheduler runs late
 * finds nothing left (the shared record is freed by whichever of them lets go of it last),
 * so threads cost at most their wake-up when they do not help.  A unit function gets a
 * scratch pointer of its thread (allocated by it on first use, freed with free() at the end)
 * and returns -1 when out of memory.  The callers release the GIL around all of it.
 */

#include "pool.h"

/* Helper threads for one call (the population split between them): POSIX threads */
#if defined(__GNUC__) && !defined(_WIN32) && (defined(__unix__) || defined(__APPLE__))
#define FLEXID_THREADS 1
#endif

int flexid_run_units_serial(const void *ctx, unit_fn fn, Py_ssize_t n_units)
{
    void *scratch = NULL;
    int rc = 0;
    for (Py_ssize_t u = 0; u < n_units && rc == 0; ++u) rc = fn(ctx, u, &scratch);
    free(scratch);
    return rc;
}

#if defined(FLEXID_THREADS)
#include <pthread.h>
#include <time.h>
typedef struct {
    const void *ctx;    /* read only while a claimed unit runs: the caller is waiting then */
    unit_fn fn;
    Py_ssize_t n_units;
    Py_ssize_t next;    /* next unclaimed unit (atomic) */
    Py_ssize_t done;    /* units finished (atomic) */
    int failed;         /* a unit ran out of memory (atomic) */
    int refs;           /* the caller and every helper started (atomic) */
    int waiting;        /* the caller sleeps on cond (under lock) */
    int joined;         /* helpers that took the job (atomic) */
    int max_helpers;    /* how many may work on it */
    pthread_mutex_t lock;
    pthread_cond_t cond;
} pool_shared;

static void pool_release(pool_shared *sh)
{
    if (__atomic_sub_fetch(&sh->refs, 1, __ATOMIC_ACQ_REL) == 0) {
        pthread_mutex_destroy(&sh->lock);
        pthread_cond_destroy(&sh->cond);
        free(sh);
    }
}

static void pool_claim(pool_shared *sh)
{
    void *scratch = NULL;
    for (;;) {
        const Py_ssize_t u = __atomic_fetch_add(&sh->next, 1, __ATOMIC_RELAXED);
        if (u >= sh->n_units) break;
        if (sh->fn(sh->ctx, u, &scratch) < 0) __atomic_store_n(&sh->failed, 1, __ATOMIC_RELAXED);
        if (__atomic_add_fetch(&sh->done, 1, __ATOMIC_ACQ_REL) == sh->n_units) {
            pthread_mutex_lock(&sh->lock);
            if (sh->waiting) pthread_cond_signal(&sh->cond);
            pthread_mutex_unlock(&sh->lock);
        }
    }
    free(scratch);
}

/* The helper threads: started on first use and then kept, waiting for the next job (starting
 * a thread costs tens of microseconds, as much as a whole small population).  One caller at a
 * time posts a job to them (pool_busy); another one meanwhile runs its job alone. */
static pthread_mutex_t pool_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t pool_wake = PTHREAD_COND_INITIALIZER;
static pool_shared *pool_job = NULL; /* the posted job (under pool_lock) */
static unsigned long pool_gen = 0;   /* jobs posted so far (under pool_lock) */
static int pool_helpers = 0;         /* helper threads started (under pool_lock) */
static int pool_busy = 0;            /* a caller owns the helpers (atomic) */
static int pool_sleepers = 0;        /* helpers blocked on pool_wake (under pool_lock) */

/* Waking a sleeping thread costs the caller a system call and the helper tens of
 * microseconds, as much as the whole job of one call of an optimiser's generation; the
 * calls of a run come back after the optimiser's own work (about 0.2 ms a generation in
 * Python), so a helper first spins this long on the word it waits for, and the caller on
 * the units a helper still runs. */
#define POOL_SPIN_HELPER 1e-3 /* seconds: between the calls of a run */
#define POOL_SPIN_CALLER 2e-5 /* seconds: for the last units a helper runs */
static double pool_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}
static inline void pool_pause(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}
/* Spins until *word differs from value (1) or the time is up (0). */
static int pool_spin_ul(const unsigned long *word, unsigned long value, double seconds)
{
    const double end = pool_now() + seconds;
    for (;;) {
        for (int i = 0; i < 64; ++i) {
            if (__atomic_load_n(word, __ATOMIC_ACQUIRE) != value) return 1;
            pool_pause();
        }
        if (pool_now() > end) return 0;
    }
}

static void *pool_helper(void *arg)
{
    (void)arg;
    unsigned long seen = 0;
    for (;;) {
        pool_spin_ul(&pool_gen, seen, POOL_SPIN_HELPER);
        pthread_mutex_lock(&pool_lock);
        while (!(pool_job && pool_gen != seen)) {
            if (!pool_job) seen = pool_gen; /* a job posted meanwhile is over */
            ++pool_sleepers;
            pthread_cond_wait(&pool_wake, &pool_lock);
            --pool_sleepers;
        }
        pool_shared *sh = pool_job;
        seen = pool_gen;
        __atomic_add_fetch(&sh->refs, 1, __ATOMIC_ACQ_REL);
        pthread_mutex_unlock(&pool_lock);
        /* no more helpers on a job than its caller asked for */
        if (__atomic_add_fetch(&sh->joined, 1, __ATOMIC_ACQ_REL) <= sh->max_helpers)
            pool_claim(sh);
        pool_release(sh);
    }
    return NULL;
}

/* In a child process made by fork the helpers do not exist: start afresh. */
static void pool_after_fork(void)
{
    pthread_mutex_init(&pool_lock, NULL);
    pthread_cond_init(&pool_wake, NULL);
    pool_job = NULL;
    pool_helpers = 0;
    pool_busy = 0;
    pool_sleepers = 0;
}
#endif

/* Runs units 0 .. n_units - 1 of fn on up to n_threads threads; 0, or -1 out of memory. */
int flexid_run_units(const void *ctx, unit_fn fn, Py_ssize_t n_units, int n_threads)
{
#if defined(FLEXID_THREADS)
    if (n_threads > n_units) n_threads = (int)n_units;
    if (n_threads > 64) n_threads = 64;
    pool_shared *sh = NULL;
    if (n_threads > 1 && !__atomic_exchange_n(&pool_busy, 1, __ATOMIC_ACQUIRE)) {
        sh = (pool_shared *)calloc(1, sizeof(pool_shared));
        if (!sh) __atomic_store_n(&pool_busy, 0, __ATOMIC_RELEASE);
    }
    if (sh) {
        sh->ctx = ctx;
        sh->fn = fn;
        sh->n_units = n_units;
        sh->refs = 1;
        sh->max_helpers = n_threads - 1;
        pthread_mutex_init(&sh->lock, NULL);
        pthread_cond_init(&sh->cond, NULL);
        pthread_mutex_lock(&pool_lock);
        if (pool_helpers < n_threads - 1) {
            pthread_attr_t attr;
            pthread_attr_init(&attr);
            pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
            while (pool_helpers < n_threads - 1) {
                pthread_t tid;
                if (pthread_create(&tid, &attr, pool_helper, NULL) != 0) break;
                ++pool_helpers;
            }
            pthread_attr_destroy(&attr);
        }
        pool_job = sh;
        __atomic_store_n(&pool_gen, pool_gen + 1, __ATOMIC_RELEASE);
        if (pool_sleepers) pthread_cond_broadcast(&pool_wake);
        pthread_mutex_unlock(&pool_lock);
        pool_claim(sh);
        if (__atomic_load_n(&sh->done, __ATOMIC_ACQUIRE) < n_units) {
            const double end = pool_now() + POOL_SPIN_CALLER;
            while (__atomic_load_n(&sh->done, __ATOMIC_ACQUIRE) < n_units && pool_now() < end)
                for (int i = 0; i < 64; ++i) pool_pause();
        }
        if (__atomic_load_n(&sh->done, __ATOMIC_ACQUIRE) < n_units) {
            pthread_mutex_lock(&sh->lock);
            sh->waiting = 1;
            while (__atomic_load_n(&sh->done, __ATOMIC_ACQUIRE) < n_units)
                pthread_cond_wait(&sh->cond, &sh->lock);
            pthread_mutex_unlock(&sh->lock);
        }
        pthread_mutex_lock(&pool_lock);
        pool_job = NULL;
        pthread_mutex_unlock(&pool_lock);
        __atomic_store_n(&pool_busy, 0, __ATOMIC_RELEASE);
        const int failed = __atomic_load_n(&sh->failed, __ATOMIC_ACQUIRE);
        pool_release(sh);
        return failed ? -1 : 0;
    }
#else
    (void)n_threads;
#endif
    return flexid_run_units_serial(ctx, fn, n_units);
}

void flexid_pool_init(void)
{
#if defined(FLEXID_THREADS)
    pthread_atfork(NULL, NULL, pool_after_fork);
#endif
}
