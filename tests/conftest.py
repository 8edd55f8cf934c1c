"""Test configuration: one BLAS thread (small matrices are much slower with threaded BLAS on
a loaded 2-core machine), set before numpy is imported by the test modules."""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
