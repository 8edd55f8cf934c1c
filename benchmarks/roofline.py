"""This CPU's floating-point limits: FMA latency and throughput of one core (a roofline).

A tiny C program, compiled at run time with the system C compiler (``cc``, or ``$CC``),
times chains of fused multiply-adds on vectors of 4 doubles (the width flexid's kernels
use; AVX2/FMA on x86-64 when the CPU has it, the compiler's generic vectors otherwise):

* **latency**: one dependent chain ``x = x * a + b``: the time of one FMA whose input is the
  previous one's result (what a recursion step waits for);
* **throughput**: 1 to 12 independent chains (12 fit the 16 vector registers of AVX2), the
  best rate in double-precision FMAs per second (what a kernel with enough independent work
  can reach on one core); and the same on every core at once, one process pinned to each
  (what threads can reach together: less than the sum where the cores share execution
  units, or are busy with other work).

Each is the best of several repeats (the machine may be shared: the least disturbed run is
the closest to the hardware).  :func:`bound` turns an FMA count into the time bound it
implies.  Run on its own: ``python benchmarks/roofline.py``.
"""

from __future__ import annotations

import os
import platform
import shutil
import subprocess
import tempfile
from functools import lru_cache
from pathlib import Path

_SOURCE = r"""
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
typedef double v4d __attribute__((vector_size(32)));
static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}
#if defined(__x86_64__) && defined(__GNUC__)
#define ISA __attribute__((target("avx2,fma")))
#else
#define ISA
#endif
/* nc independent chains of x = x * a + b on 4-double vectors, n rounds; seconds taken */
#define CHAINS(NC)                                                                     \
    ISA __attribute__((noinline)) static double run##NC(long n, double *sink)          \
    {                                                                                  \
        const v4d a = {0.999999, 0.999999, 0.999999, 0.999999};                        \
        const v4d b = {1e-9, 1e-9, 1e-9, 1e-9};                                        \
        v4d x[NC];                                                                     \
        for (int j = 0; j < NC; ++j) x[j] = (v4d){1, 1, 1, 1} * (double)(j + 1);       \
        double t = now();                                                              \
        for (long i = 0; i < n; ++i) {                                                 \
            _Pragma("GCC unroll 16") for (int j = 0; j < NC; ++j) x[j] = x[j] * a + b; \
        }                                                                              \
        t = now() - t;                                                                 \
        v4d s = {0, 0, 0, 0};                                                          \
        for (int j = 0; j < NC; ++j) s += x[j];                                        \
        *sink += s[0];                                                                 \
        return t;                                                                      \
    }
CHAINS(1)
CHAINS(4)
CHAINS(8)
CHAINS(10)
CHAINS(12)
int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 1000000;
    double sink = 0, lat = 1e9, thr = 0;
    int isa = 0;
#if defined(__x86_64__) && defined(__GNUC__)
    if (!__builtin_cpu_supports("avx2") || !__builtin_cpu_supports("fma")) {
        printf("nofma\n");
        return 0;
    }
    isa = 1;
#endif
    static double (*const fns[])(long, double *) = {run1, run4, run8, run10, run12};
    static const int nc[] = {1, 4, 8, 10, 12};
    for (int r = 0; r < 7; ++r) {
        double t = run1(n * 8, &sink);
        if (t / (8.0 * n) < lat) lat = t / (8.0 * n);
        for (int k = 1; k < 5; ++k) {
            double rate = 4.0 * nc[k] * n / fns[k](n, &sink);
            if (rate > thr) thr = rate;
        }
    }
    printf("%s %.6g %.6g %g\n", isa ? "avx2-fma" : "generic", lat, thr, sink);
    return 0;
}
"""


def _compile(tmp: str) -> Path | None:
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        return None
    src, exe = Path(tmp, "fma.c"), Path(tmp, "fma")
    src.write_text(_SOURCE)
    # -ffp-contract=fast: x * a + b is one FMA instruction where the target has one
    done = subprocess.run([cc, "-O2", "-ffp-contract=fast", str(src), "-o", str(exe)],
                          capture_output=True, text=True)  # fmt: skip
    return exe if done.returncode == 0 else None


def _parse(text: str) -> dict:
    fields = text.split()
    if len(fields) < 3:
        return {}
    return {"isa": fields[0], "latency": float(fields[1]), "throughput": float(fields[2])}


def _pinned(cpu: int):
    return lambda: os.sched_setaffinity(0, {cpu})


@lru_cache(maxsize=1)
def measure(rounds: int = 400_000) -> dict:
    """FMA latency and throughput of one core, and of all of them, or ``{}`` without cc.

    Returns
    -------
    dict
        ``latency`` (seconds per dependent FMA), ``throughput`` (double-precision FMAs per
        second on one core, 4-double vectors, all independent), ``throughput_all`` (the sum
        over the cores this process may use, each running the test at the same time, pinned
        to its core: less than ``cores`` times ``throughput`` where "cores" share execution
        units or are busy), ``cores``, ``isa`` (``"avx2-fma"`` or ``"generic"``), ``lanes``.
    """
    with tempfile.TemporaryDirectory() as tmp:
        exe = _compile(tmp)
        if exe is None:
            return {}
        out = subprocess.run([str(exe), str(rounds)], capture_output=True, text=True, timeout=120)
        roof = _parse(out.stdout)
        if not roof:
            return {}
        try:
            cpus = sorted(os.sched_getaffinity(0))
        except (AttributeError, OSError):  # pragma: no cover - not Linux
            cpus = []
        total = roof["throughput"]
        if len(cpus) > 1:
            procs = [subprocess.Popen([str(exe), str(rounds)], stdout=subprocess.PIPE, text=True,
                                      preexec_fn=_pinned(c)) for c in cpus]  # fmt: skip
            total = sum(_parse(p.communicate(timeout=120)[0]).get("throughput", 0.0)
                        for p in procs)  # fmt: skip
    roof.update(throughput_all=total, cores=max(1, len(cpus)), lanes=4,
                machine=platform.machine())  # fmt: skip
    return roof


def bound(fmas: float, roof: dict | None = None, all_cores: bool = False) -> float:
    """Shortest time for ``fmas`` double-precision FMAs at one core's (or all cores')
    throughput, in seconds."""
    roof = roof if roof is not None else measure()
    if not roof:
        return float("nan")
    return fmas / roof["throughput_all" if all_cores else "throughput"]


def main() -> None:
    roof = measure()
    if not roof:
        print("no C compiler: the roofline cannot be measured")
        return
    print(f"FMA ({roof['isa']}, {roof['lanes']} doubles per vector, one core):")
    print(f"  latency     {roof['latency'] * 1e9:6.3f} ns per dependent FMA")
    print(f"  throughput  {roof['throughput'] * 1e-9:6.2f} double FMAs per ns "
          f"({roof['throughput'] * roof['latency'] / roof['lanes']:.1f} vector FMAs "
          "in flight per latency)")  # fmt: skip
    print(f"  all {roof['cores']} cores at once: {roof['throughput_all'] * 1e-9:6.2f} double "
          f"FMAs per ns ({roof['throughput_all'] / roof['throughput']:.2f}x one core)")  # fmt: skip


if __name__ == "__main__":
    main()
