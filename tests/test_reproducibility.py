"""A seeded result is a pure function of its arguments, whatever ran before it.

Each result computed here, after other work in this process, must equal bit for bit the same
computation done first thing in a fresh interpreter.  Rounding in the simulators depends on
the route a value takes (e.g. the shapes of the BLAS products), so a cache that changes the
route with the call history would show here as a difference in the last bits.

The fresh results come from one subprocess per recipe (:data:`RECIPES`), all started at once;
the subprocesses inherit this process's environment (BLAS threads and kernels, see
``conftest.py``), so both sides run on the same machine and library set.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import flexid
from flexid.envs import beam
from flexid.envs.manipulator import FlexibleManipulatorEnv, FlexibleManipulatorVectorEnv
from flexid.envs.twin_rotor import TwinRotorEnv, TwinRotorVectorEnv

Arrays = dict[str, np.ndarray]

PRBS = {
    "signal": "prbs",
    "n_samples": 4000,
    "seed": 1,
    "noise_std": 1e-3,
    "signal_options": {"amplitude": 0.2, "order": 10, "clock": 5},
}
"""The PRBS record of ``examples/generate_dataset.py``: longer than the paper preset."""


def _record(data) -> Arrays:
    """Inputs, outputs and the metadata (as JSON bytes) of a generated record."""
    meta = json.dumps(data.metadata, sort_keys=True).encode()
    return {"u": data.u, "y": data.y, "metadata": np.frombuffer(meta, dtype=np.uint8)}


def _paper() -> Arrays:
    return _record(flexid.generate("manipulator", preset="paper-manipulator", seed=0))


def _prbs() -> Arrays:
    return _record(flexid.generate("manipulator", **PRBS))


def _twin() -> Arrays:
    return _record(flexid.generate("twin-rotor", preset="paper-twin-rotor", n_samples=300, seed=2))


def _rollout(env, seed: int, actions: np.ndarray, prefix: str) -> Arrays:
    """Observations and rewards of ``env`` after ``reset(seed=seed)`` under ``actions``."""
    obs, _ = env.reset(seed=seed)
    observations, rewards = [obs], []
    for action in actions:
        obs, reward, *_ = env.step(action)
        observations.append(obs)
        rewards.append(reward)
    return {f"{prefix}_obs": np.array(observations), f"{prefix}_reward": np.array(rewards)}


def _actions(shape: tuple[int, ...], high: float) -> np.ndarray:
    return np.random.default_rng(5).uniform(-high, high, shape)


def _vector_envs():
    # episodes shorter than the rollout: the autoreset is part of what is compared
    manipulator = FlexibleManipulatorVectorEnv(3, noise_std=1e-4, max_episode_steps=100)
    twin = TwinRotorVectorEnv(2, noise_std=1e-3, max_episode_steps=20)
    return manipulator, twin


def _vector_rollouts(manipulator, twin) -> Arrays:
    return {
        **_rollout(manipulator, 11, _actions((250, 3, 1), 0.3), "manipulator"),
        **_rollout(twin, 11, _actions((30, 2, 2), 1.0), "twin"),
    }


def _single_envs():
    return FlexibleManipulatorEnv(noise_std=1e-4), TwinRotorEnv(noise_std=1e-3)


def _single_rollouts(manipulator, twin) -> Arrays:
    return {
        **_rollout(manipulator, 7, _actions((80, 1), 0.3), "manipulator"),
        **_rollout(twin, 7, _actions((20, 2), 1.0), "twin"),
    }


RECIPES: dict[str, Callable[[], Arrays]] = {
    "paper": _paper,
    "prbs": _prbs,
    "twin": _twin,
    "vector": lambda: _vector_rollouts(*_vector_envs()),
    "single": lambda: _single_rollouts(*_single_envs()),
}
"""Computations whose fresh-process results the tests compare with."""

_CHILD = """
import sys
sys.path.insert(0, {tests!r})
import numpy as np
from test_reproducibility import RECIPES
np.savez({out!r}, **RECIPES[{name!r}]())
"""


@pytest.fixture(scope="module")
def fresh(tmp_path_factory) -> dict[str, Arrays]:
    """Each recipe's result computed first thing in its own interpreter."""
    folder = tmp_path_factory.mktemp("fresh")
    tests = str(Path(__file__).resolve().parent)
    children = {}
    for name in RECIPES:  # started together: the machine's cores share the import time
        code = _CHILD.format(tests=tests, out=str(folder / f"{name}.npz"), name=name)
        children[name] = subprocess.Popen(
            [sys.executable, "-c", code],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=dict(os.environ),
        )
    results = {}
    for name, child in children.items():
        _, err = child.communicate(timeout=120)
        assert child.returncode == 0, f"fresh {name!r} failed:\n{err}"
        with np.load(folder / f"{name}.npz") as saved:
            results[name] = {key: saved[key] for key in saved.files}
    return results


def _assert_same_bits(got: Arrays, ref: Arrays) -> None:
    assert sorted(got) == sorted(ref)
    for key, want in ref.items():
        have = np.asarray(got[key])
        assert have.dtype == want.dtype and have.shape == want.shape, key
        if have.tobytes() != want.tobytes():
            differ = np.count_nonzero(have != want)
            detail = (
                f"{have.tobytes().decode()!r} != {want.tobytes().decode()!r}"
                if key == "metadata"
                else f"largest difference {np.max(np.abs(have - want)):.3g}"
            )
            pytest.fail(f"{key}: {differ} entries differ from a fresh process; {detail}")


@pytest.mark.parametrize(
    "order",
    [("paper", "prbs", "twin", "paper"), ("prbs", "paper", "prbs")],
    ids=["after-a-longer-record", "call-order"],
)
def test_record_independent_of_earlier_records(fresh, order):
    """Recipes run one after another in this process, ``order``, each as in a fresh one."""
    results = [RECIPES[name]() for name in order]  # all run before any is compared
    for name, got in zip(order, results, strict=True):
        _assert_same_bits(got, fresh[name])


def test_vector_envs_after_long_generate(fresh):
    flexid.generate("manipulator", signal="prbs", n_samples=30_000, seed=4)
    flexid.generate("twin-rotor", n_samples=200, seed=4)
    manipulator, twin = _vector_envs()
    # earlier episodes on the same instances, with another seed and other actions
    manipulator.reset(seed=3)
    for action in _actions((150, 3, 1), 0.2)[::-1]:
        manipulator.step(action)
    twin.reset(seed=3)
    for action in _actions((25, 2, 2), 0.5)[::-1]:
        twin.step(action)
    _assert_same_bits(_vector_rollouts(manipulator, twin), fresh["vector"])
    _assert_same_bits(_vector_rollouts(*_vector_envs()), fresh["vector"])


def test_env_reset_with_seed_after_other_work(fresh):
    manipulator, twin = _single_envs()
    _rollout(manipulator, 1, _actions((300, 1), 0.1), "m")
    _rollout(twin, 1, _actions((15, 2), 0.7), "t")
    flexid.generate("manipulator", preset="paper-manipulator", n_samples=6000, seed=9)
    _assert_same_bits(_single_rollouts(manipulator, twin), fresh["single"])
    _assert_same_bits(_single_rollouts(*_single_envs()), fresh["single"])


def test_impulse_response_prefix_does_not_depend_on_requests():
    p = beam.BeamParameters(n_sections=10)
    reference = beam.BeamModel(p, 1e-3).markov_parameters(3000)
    model = beam.BeamModel(p, 1e-3)
    for n in (1, 700, 5, 2000, 513, 3000, 2999):
        got = model.markov_parameters(n)
        assert got.shape == (n, 4) and not got.flags.writeable
        assert np.array_equal(got, reference[:n]), n
        assert np.array_equal(beam.BeamModel(p, 1e-3).markov_parameters(n), reference[:n]), n
    clone = pickle.loads(pickle.dumps(model))  # the cache stays behind; the values do not
    assert np.array_equal(clone.markov_parameters(3000), reference)
