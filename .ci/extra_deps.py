"""Print the requirements of one optional extra of pyproject.toml, one per line.

CI installs the docs extra's packages with these, as ``pip install -e ".[docs]"`` would build
the compiled extension a second time.
"""

import sys
from pathlib import Path

try:
    import tomllib
except ImportError:  # Python 3.10: the project depends on tomli there
    import tomli as tomllib

pyproject = tomllib.loads((Path(__file__).resolve().parents[1] / "pyproject.toml").read_text())
print("\n".join(pyproject["project"]["optional-dependencies"][sys.argv[1]]))
