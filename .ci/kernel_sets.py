"""Print a second OpenBLAS kernel set this CPU runs and NumPy CPU features to switch off.

Output: ``CORETYPE NPY_FEATURES`` on one line, ``-`` for none.  ``.ci/run`` reruns the
numerically sensitive tests with them, so rounding that depends on the kernel set (blocking,
FMA, vector width) is exercised on every machine, not only on another one.
"""

import platform


def cpu_flags() -> set[str]:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith(("flags", "Features")):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def coretype() -> str:
    machine = platform.machine().lower()
    flags = cpu_flags()
    if machine in ("x86_64", "amd64"):
        if "avx512f" in flags:
            return "Haswell"  # AVX2 + FMA instead of AVX-512
        if "avx2" in flags:
            return "Sandybridge"  # AVX without FMA instead of Haswell/Zen
        if "avx" in flags:
            return "Nehalem"  # SSE only
    if machine in ("aarch64", "arm64") and flags:
        return "ARMV8"  # the generic kernels
    return "-"


def numpy_features_off() -> str:
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:
        return "-"
    for name in ("X86_V3", "AVX2"):
        if features.get(name):
            return name
    return "-"


if __name__ == "__main__":
    print(coretype(), numpy_features_off())
