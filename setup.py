"""Build hook for the optional compiled kernels (all metadata lives in pyproject.toml).

``flexid._kernels`` is a small C extension with the inner loops of the batched ARX costs.
It is marked optional: where no C compiler is available the build skips it and flexid
uses its NumPy/SciPy reference path (``flexid.kernels.BACKEND`` says which one runs).
"""

import os

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "flexid._kernels",
            sources=["src/flexid/_kernels.c"],
            extra_compile_args=["-O3", "-pthread"] if os.name != "nt" else ["/O2"],
            extra_link_args=["-pthread"] if os.name != "nt" else [],
            optional=True,
        )
    ]
)
