"""A serial comparison survives a plugin that ends its process (issue #45, point 5).

An optimiser of an entry-point plugin is not trusted unless it was registered with
``trusted=True``: in the serial route its runs are done in a child process, so that one that
calls ``os._exit``, segfaults or is killed is a failed run with its reason and the other runs
go on.  Built-in optimisers, and those registered as trusted, run in the caller's process.

The plugin is a module written to a folder with a ``.dist-info`` declaring it in the
``flexid.optimisers`` entry-point group, as an installed plugin would be: child processes
and ``flexid`` subprocesses find it by name.  A run that could end the test's own process is
run through a ``flexid`` subprocess.
"""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from flexid import compare
from flexid.config import OptimiserSpec
from flexid.optimisers import (
    Optimiser,
    register,
    register_variant,
    registry,
    reload_plugins,
    unregister,
)
from helpers import tiny_spec

PLUGIN_MODULE = "flexid_untrusted_plugins"
PLUGIN_SOURCE = '''
"""Optimisers of flexid's tests of untrusted plugins."""

import os
import signal

import numpy as np

from flexid.optimisers import Optimiser, register


def _note_process(name):
    """Append ``name pid`` to the file $FLEXID_TEST_PIDS names: where the run was done."""
    path = os.environ.get("FLEXID_TEST_PIDS")
    if path:
        with open(path, "a") as f:
            f.write(f"{name} {os.getpid()}\\n")


class Walk(Optimiser):
    """A deterministic random walk from the best point."""

    name = "test-walk"

    def search(self, space, rng):
        _note_process(self.name)
        X = space.initial_population(4)
        F = yield X
        x, f = X[np.argmin(F)], F.min()
        while True:
            trial = space.clip(x + 0.1 * rng.standard_normal((4, space.dim)))
            F = yield trial
            if F.min() < f:
                x, f = trial[np.argmin(F)], F.min()


class Exits(Optimiser):
    """Ends its process with status 9 after its first population."""

    name = "test-exits"

    def search(self, space, rng):
        yield space.initial_population(4)
        os._exit(9)


class Segfaults(Optimiser):
    """Ends its process with SIGSEGV, as a crash in compiled code would."""

    name = "test-segfaults"

    def search(self, space, rng):
        yield space.initial_population(4)
        os.kill(os.getpid(), signal.SIGSEGV)
'''
#: a plugin that registers its optimiser itself, as trusted, as it is imported
TRUSTED_MODULE = "flexid_untrusted_plugins_trusted"
TRUSTED_SOURCE = f'''
from flexid.optimisers import register
from {PLUGIN_MODULE} import Walk


class TrustedWalk(Walk):
    """The same walk, declared safe to run in the caller's process."""

    name = "test-trusted-walk"


register(TrustedWalk, trusted=True)
'''
PLUGINS = {
    "test-walk": f"{PLUGIN_MODULE}:Walk",
    "test-exits": f"{PLUGIN_MODULE}:Exits",
    "test-segfaults": f"{PLUGIN_MODULE}:Segfaults",
    "test-trusted-walk": f"{TRUSTED_MODULE}:TrustedWalk",
}


@pytest.fixture(scope="module")
def plugin_site(tmp_path_factory) -> Path:
    """A folder holding the plugin module and a ``.dist-info`` that declares its optimisers."""
    site = tmp_path_factory.mktemp("site")
    (site / f"{PLUGIN_MODULE}.py").write_text(PLUGIN_SOURCE)
    (site / f"{TRUSTED_MODULE}.py").write_text(TRUSTED_SOURCE)
    info = site / "flexid_untrusted_plugins-0.1.dist-info"
    info.mkdir()
    info.joinpath("METADATA").write_text(
        "Metadata-Version: 2.1\nName: flexid-untrusted-plugins\nVersion: 0.1\n"
    )
    entries = "".join(f"{name} = {target}\n" for name, target in PLUGINS.items())
    info.joinpath("entry_points.txt").write_text("[flexid.optimisers]\n" + entries)
    return site


@pytest.fixture
def plugins(plugin_site, monkeypatch):
    """The plugin's optimisers, registered here and found by child processes (which start
    with this process's ``sys.path``)."""
    monkeypatch.syspath_prepend(str(plugin_site))
    reload_plugins()
    yield plugin_site
    for name in PLUGINS:
        unregister(name)
    # imported afresh next time, so that the module registers its own optimiser again
    sys.modules.pop(TRUSTED_MODULE, None)


def _env(site: Path) -> dict[str, str]:
    """The environment of a ``flexid`` subprocess that finds the plugin."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(site), *filter(None, [env.get("PYTHONPATH")]), *sys.path]
    )
    return env


def _rows(store: Path) -> dict[tuple[str, int], tuple]:
    with sqlite3.connect(store) as con:
        rows = con.execute("SELECT label, run, status, error, created FROM runs").fetchall()
    return {(label, run): (status, error, created) for label, run, status, error, created in rows}


def test_a_plugin_that_ends_its_process_is_a_failed_run_of_a_serial_comparison(
    plugins, tmp_path
):
    """``os._exit(9)`` and a segfault: failed runs with their reasons, exit status 0, the
    other runs done; a rerun keeps the failed runs, ``--retry-failed`` runs them again."""
    store = tmp_path / "r.sqlite"
    cmd = [
        sys.executable, "-m", "flexid", "compare", "--plant", "twin-rotor", "--na", "2",
        "--optimisers", "test-exits,sda,test-segfaults", "--runs", "2", "--budget", "200",
        "--no-figures", "--no-progress", "--store", str(store),
    ]  # fmt: skip
    exits = "the optimiser's child process died (exit code 9)"
    segfault = "the optimiser's child process died (exit code -11, SIGSEGV)"

    def run(*extra: str) -> dict[tuple[str, int], tuple]:
        done = subprocess.run([*cmd, *extra], capture_output=True, text=True, timeout=120,
                              env=_env(plugins))  # fmt: skip
        assert done.returncode == 0, (done.returncode, done.stdout, done.stderr)
        assert f"test-exits: failed runs: {exits}" in done.stdout
        assert f"test-segfaults: failed runs: {segfault}" in done.stdout
        said = [line for line in done.stdout.splitlines() if "failed runs:" in line]
        assert len(said) == 2 and max(map(len, said)) <= 100
        return _rows(store)

    first = run()
    assert {k: v[:2] for k, v in first.items()} == {
        ("ls", 0): ("ok", None),
        ("sda", 0): ("ok", None),
        ("sda", 1): ("ok", None),
        ("test-exits", 0): ("failed", exits),
        ("test-exits", 1): ("failed", exits),
        ("test-segfaults", 0): ("failed", segfault),
        ("test-segfaults", 1): ("failed", segfault),
    }
    assert run() == first  # nothing ran again, the failed runs neither
    retried = run("--retry-failed")
    assert {k: v[:2] for k, v in retried.items()} == {k: v[:2] for k, v in first.items()}
    for key, (status, _, created) in retried.items():  # the failed runs alone were run again
        assert (created != first[key][2]) == (status == "failed"), key


def test_a_run_in_a_child_process_is_the_run_in_this_process(plugins, tmp_path, monkeypatch):
    """The untrusted walk runs in a child, the same walk registered as trusted here: their
    stored records are the same numbers, bit for bit."""
    pids = tmp_path / "pids.txt"
    monkeypatch.setenv("FLEXID_TEST_PIDS", str(pids))
    opts = (OptimiserSpec("test-walk"), OptimiserSpec("test-trusted-walk"))
    result = compare(tiny_spec("walks", optimisers=opts, budget=120), store=tmp_path / "r.sqlite")
    where = {tuple(line.split()) for line in pids.read_text().splitlines()}
    here = str(os.getpid())
    assert {(name, pid == here) for name, pid in where} == {
        ("test-walk", False),
        ("test-trusted-walk", True),
    }
    child, own = result.records["test-walk"], result.records["test-trusted-walk"]
    assert [r["status"] for r in child + own] == ["ok"] * 4
    same = ("run", "seed", "cost", "nfev", "nit", "stop", "x", "history", "validation")
    for a, b in zip(child, own, strict=True):
        assert {k: a[k] for k in same} == {k: b[k] for k in same}


def test_which_optimisers_are_trusted(plugins):
    """Built-ins, their variants and the caller's own optimisers are; an entry-point plugin
    is not unless registered with ``trusted=True``; a variant is as trusted as its base."""
    is_trusted, describe = registry.is_trusted, registry.describe
    builtins = [n for n in registry.available() if describe(n)["source"].startswith("flexid")]
    assert builtins and all(is_trusted(n) for n in builtins)
    assert is_trusted("sda") and describe("sda")["trusted"] is True
    assert not is_trusted("test-walk") and describe("test-walk")["trusted"] is False
    assert is_trusted("test-trusted-walk")

    class Own(Optimiser):
        name = "test-own"

        def search(self, space, rng):
            while True:
                yield space.initial_population(2)

    try:
        register(Own)
        assert is_trusted("test-own")
        unregister("test-own")
        register(Own, trusted=False)
        assert not is_trusted("test-own")
        register_variant("test-walk-slow", "test-walk")
        assert not is_trusted("test-walk-slow")
        register_variant("test-sda-few", "sda", points=3)
        assert is_trusted("test-sda-few")
    finally:
        for name in ("test-own", "test-walk-slow", "test-sda-few"):
            unregister(name)


def test_a_script_without_the_main_guard_is_told_what_to_do(plugins, tmp_path):
    """The child process imports the calling script again: one that starts its comparison at
    import ends the child before it starts, and the error says how to write the script."""
    script = tmp_path / "unguarded.py"
    script.write_text(
        "from flexid import compare\n"
        "from flexid.config import OptimiserSpec\n"
        "from helpers import tiny_spec\n"
        "compare(tiny_spec('s', optimisers=(OptimiserSpec('test-walk'),), runs=1, budget=50))\n"
    )
    env = _env(plugins)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).parent), env["PYTHONPATH"]])
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=120, env=env)  # fmt: skip
    assert done.returncode == 1
    told = done.stderr[done.stderr.rindex("RuntimeError: a flexid worker process") :]
    assert 'if __name__ == "__main__":' in told, done.stderr
    assert max(map(len, told.splitlines())) <= 100
