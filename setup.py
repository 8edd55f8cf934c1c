"""Build hook for the optional compiled kernels (all metadata lives in pyproject.toml).

``flexid._kernels`` is a small C extension with the inner loops of the batched ARX costs,
built from the C files of ``src/flexid/kernels`` (one job each; ``module.c`` is the Python
glue, ``simd.h`` the header they share).  It is marked optional: where no C compiler is
available the build skips it and flexid uses its NumPy/SciPy reference path
(``flexid.kernels.BACKEND`` says which one runs).
"""

import os

from setuptools import Extension, setup

_SOURCES = ["module", "pool", "polynomial", "recursion", "numerator", "initial_state",
            "twin_rotor", "modal", "flagged"]  # fmt: skip
_HEADERS = ["simd", "pool", "polynomial", "recursion", "numerator", "initial_state",
            "twin_rotor", "modal", "flagged", "flagged_lanes"]  # fmt: skip

setup(
    ext_modules=[
        Extension(
            "flexid._kernels",
            sources=[f"src/flexid/kernels/{name}.c" for name in _SOURCES],
            depends=[f"src/flexid/kernels/{name}.h" for name in _HEADERS],
            extra_compile_args=["-O3", "-pthread"] if os.name != "nt" else ["/O2"],
            extra_link_args=["-pthread"] if os.name != "nt" else [],
            optional=True,
        )
    ]
)
