"""Time and peak memory of reading a large CSV record with :func:`flexid.data.load`.

Writes a plain CSV (header ``t,u,y`` by default, or ``u,y`` with ``--no-time``) of
``--samples`` rows into a temporary folder, reads it back with :func:`flexid.data.load`, and
prints the wall time, the tracemalloc peak of the read (NumPy's arrays and every Python
object), the process's peak resident set (``ru_maxrss``, which also counts the interpreter and
the libraries) and, for scale, the bytes of the record's float64 arrays ``u`` and ``y``.

Run::

    python benchmarks/bench_load.py                      # 1,000,000 samples
    python benchmarks/bench_load.py --samples 5000000 --no-time

Each measurement runs in a fresh process: ``ru_maxrss`` is the peak of the whole process
since it started (so the file is written by another one), and tracemalloc's bookkeeping
slows the read and takes memory of its own (so time and resident set come from an untraced
read).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path


def write_csv(path: Path, samples: int, with_time: bool, seed: int = 0) -> None:
    """Write a record of ``samples`` rows: a random input and a first-order response.

    Parameters
    ----------
    path : pathlib.Path
        Destination.
    samples : int
        Number of rows.
    with_time : bool
        Whether to write a ``t`` column (seconds, step 0.001).
    seed : int, optional
        Seed of the input.
    """
    import numpy as np

    rng = np.random.default_rng(seed)
    block = 200_000  # rows formatted at a time: the writer's own memory stays small
    state = 0.0
    with open(path, "w", encoding="utf-8") as handle:
        handle.write("t,u,y\n" if with_time else "u,y\n")
        for first in range(0, samples, block):
            n = min(block, samples - first)
            u = rng.standard_normal(n)
            y = np.empty(n)
            for k in range(n):  # y(t) = 0.9 y(t-1) + u(t-1), seeded from the last block
                y[k] = state
                state = 0.9 * state + u[k]
            cols = [u, y]
            if with_time:
                cols.insert(0, (first + np.arange(n)) * 1e-3)
            np.savetxt(handle, np.column_stack(cols), delimiter=",", fmt="%.10g")


def measure(path: Path, trace: bool) -> dict[str, float]:
    """Read ``path`` with :func:`flexid.data.load` and measure the read.

    Parameters
    ----------
    path : pathlib.Path
        The CSV file.
    trace : bool
        Trace allocations with :mod:`tracemalloc` (which slows the read and takes memory of
        its own, so time and resident set are measured in another process, untraced).

    Returns
    -------
    dict
        ``samples``, ``seconds``, ``array_bytes`` (of ``u`` and ``y``), and either
        ``tracemalloc_peak`` or ``maxrss_before`` and ``maxrss_after`` (bytes).
    """
    from flexid.data import load

    scale = 1 if sys.platform == "darwin" else 1024  # ru_maxrss: bytes on macOS, KiB on Linux
    out: dict[str, float] = {}
    out["maxrss_before"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale
    if trace:
        tracemalloc.start()
    t0 = time.perf_counter()
    data = load(path)
    out["seconds"] = time.perf_counter() - t0
    if trace:
        out["tracemalloc_peak"] = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    out["maxrss_after"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale
    out["samples"] = data.n_samples
    out["array_bytes"] = data.u.nbytes + data.y.nbytes
    return out


def _child(*args: str) -> str:
    """Run this script with ``args`` in a fresh interpreter; its standard output."""
    run = subprocess.run(
        [sys.executable, __file__, *args], check=True, capture_output=True, text=True
    )
    return run.stdout


def main(argv: list[str] | None = None) -> int:
    """Write the CSV, then read it in two fresh processes: untraced, and under tracemalloc.

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=1_000_000, help="rows (default 1e6)")
    parser.add_argument("--no-time", action="store_true", help="columns u,y only (no t)")
    parser.add_argument("--write", help=argparse.SUPPRESS)  # internal: write this file
    parser.add_argument("--read", help=argparse.SUPPRESS)  # internal: measure this file
    parser.add_argument("--trace", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.write:
        write_csv(Path(args.write), args.samples, not args.no_time)
        return 0
    if args.read:
        print(json.dumps(measure(Path(args.read), args.trace)))
        return 0
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "record.csv"
        options = ["--samples", str(args.samples), *(["--no-time"] if args.no_time else [])]
        _child(*options, "--write", str(path))
        size = path.stat().st_size
        plain = json.loads(_child("--read", str(path)))
        traced = json.loads(_child("--read", str(path), "--trace"))
    mb = 1e6
    arrays = plain["array_bytes"]
    grown = plain["maxrss_after"] - plain["maxrss_before"]
    peak = traced["tracemalloc_peak"]
    print(f"file             : {plain['samples']:,} samples, {size / mb:.1f} MB")
    print(f"load time        : {plain['seconds']:.2f} s")
    print(f"float64 arrays   : {arrays / mb:.1f} MB (u and y)")
    print(f"tracemalloc peak : {peak / mb:.1f} MB ({peak / arrays:.2f} x the arrays)")
    print(
        f"ru_maxrss        : {plain['maxrss_after'] / mb:.1f} MB peak resident, "
        f"+{grown / mb:.1f} MB during the read ({grown / arrays:.2f} x the arrays)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
