"""The scripts in ``examples/`` run, check their own claims, and leave no files in the repo.

Each script runs in a fresh interpreter in a temporary working directory (where it writes its
data, figures and result stores).  It fails when it exits non-zero (an example raises
``SystemExit`` when one of its own checks fails) or prints a line that ends in ``False``.

The optimiser plugin package is tested without installing it: the entry point its
``pyproject.toml`` declares is written to a ``.dist-info`` folder on ``PYTHONPATH``, which is
what ``pip install ./examples/plugin_optimiser`` gives flexid to find.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import flexid

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
GALLERY = EXAMPLES / "gallery"  # figure scripts the documentation's gallery runs
SCRIPTS = sorted(EXAMPLES.glob("*.py")) + sorted(GALLERY.glob("*.py"))
PLUGIN = EXAMPLES / "plugin_optimiser"
TIMEOUT = 300  # s; a generous bound: it only stops a hung example, it times nothing

_FALSE_CLAIM = re.compile(r"\bFalse\s*$", re.MULTILINE)


def _environment(**extra: str) -> dict[str, str]:
    env = dict(os.environ)
    env["MPLBACKEND"] = "Agg"  # figures without a display
    env.update(extra)
    return env


def _files(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*") if "__pycache__" not in p.parts}


def test_every_example_is_covered():
    assert SCRIPTS, "no example scripts found"
    assert {p.name for p in EXAMPLES.iterdir() if p.is_dir()} == {PLUGIN.name, GALLERY.name}
    assert not [p for p in GALLERY.iterdir() if p.is_dir() and p.name != "__pycache__"]


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_example_runs_and_its_claims_hold(script, tmp_path):
    before = _files(EXAMPLES)
    run = subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        env=_environment(),
    )
    assert run.returncode == 0, f"{script.name} failed:\n{run.stdout}\n{run.stderr}"
    false = _FALSE_CLAIM.findall(run.stdout)
    assert not false, f"{script.name} printed a false claim:\n{run.stdout}"
    assert _files(EXAMPLES) == before, f"{script.name} wrote into examples/"


def _install_free(plugin: Path, site: Path) -> None:
    """Make ``plugin``'s declared entry points visible to importlib.metadata from ``site``."""
    project = tomllib.loads((plugin / "pyproject.toml").read_text())["project"]
    groups = project["entry-points"]
    info = site / f"{project['name'].replace('-', '_')}-{project['version']}.dist-info"
    info.mkdir(parents=True)
    info.joinpath("METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {project['name']}\nVersion: {project['version']}\n"
    )
    text = "".join(
        f"[{group}]\n" + "".join(f"{name} = {target}\n" for name, target in entries.items())
        for group, entries in groups.items()
    )
    info.joinpath("entry_points.txt").write_text(text)


def test_plugin_optimiser_is_found_and_runs_by_name(tmp_path):
    site = tmp_path / "site"
    _install_free(PLUGIN, site)
    record = tmp_path / "record.csv"
    flexid.generate("manipulator", preset="paper-manipulator", n_samples=600, seed=3).save(record)
    path = os.pathsep.join(
        [str(site), str(PLUGIN / "src"), *filter(None, [os.environ.get("PYTHONPATH")])]
    )
    # the command of the plugin's docstring, with a small budget
    options = "--na 4 --optimiser annealing --param temperature=0.5 --budget 1500"
    run = subprocess.run(
        [sys.executable, "-m", "flexid", "identify", str(record), *options.split(), "--json"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        env=_environment(PYTHONPATH=path),
    )
    assert run.returncode == 0, run.stderr
    result = json.loads(run.stdout)
    assert result["optimiser"] == "annealing"
    assert result["params"]["temperature"] == 0.5
