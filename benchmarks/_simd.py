"""The ``--simd`` option of the kernel benchmarks: the compiled kernels' instruction set."""

from __future__ import annotations

import argparse

from flexid import kernels


def simd_from_arguments(description: str) -> str:
    """Parse ``--simd {generic,avx2,avx512}``, force that instruction set, return its name.

    Default: the best the CPU has; ``"none"`` where the kernels are NumPy's.
    """
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--simd", choices=["generic", "avx2", "avx512"], default=None)
    args = parser.parse_args()
    if kernels.BACKEND != "c":
        return "none"
    from flexid import _kernels

    if args.simd:
        _kernels.simd(args.simd)
    return _kernels.simd()[0]
