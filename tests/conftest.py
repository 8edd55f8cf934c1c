"""Test configuration: one BLAS thread (small matrices are much slower with threaded BLAS on
a loaded 2-core machine), set before numpy is imported by the test modules."""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
if "PYTEST_XDIST_WORKER" in os.environ:
    # one pytest worker per core (pytest -n auto): the compiled kernels' threads would only
    # take turns with the other workers' (the tests that split a population set the count)
    os.environ.setdefault("FLEXID_THREADS", "1")
