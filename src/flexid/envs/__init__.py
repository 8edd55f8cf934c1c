"""Gymnasium environments for the simulated flexible plants.

``flexid/FlexibleManipulator-v0``
    Single-link flexible manipulator: finite-difference Euler-Bernoulli beam on a motor hub
    (:mod:`flexid.envs.beam`, :mod:`flexid.envs.manipulator`).
``flexid/TwinRotor-v0``
    Twin rotor MIMO system, Feedback 33-949S phenomenological model
    (:mod:`flexid.envs.twin_rotor`).

Importing this module registers both (and imports Gymnasium).  ``import flexid`` does not
import Gymnasium: it arranges for this module to be imported as soon as Gymnasium is (or at
once if Gymnasium already is), so ``import flexid; import gymnasium; gymnasium.make(ID)``
works in either import order.  Gymnasium 1.x reads no plugin entry points, so without
importing flexid use the ``module:id`` form, ``gymnasium.make("flexid.envs:" + ID)``, which
imports this module first.  The entry points are strings, so the physics modules are imported
only when an environment is made.
"""

from __future__ import annotations

import gymnasium

MANIPULATOR_ID = "flexid/FlexibleManipulator-v0"
TWIN_ROTOR_ID = "flexid/TwinRotor-v0"

__all__ = ["MANIPULATOR_ID", "TWIN_ROTOR_ID", "register_environments"]


def register_environments() -> None:
    """Register the flexid environments with Gymnasium (idempotent)."""
    registry = gymnasium.envs.registration.registry
    if MANIPULATOR_ID not in registry:
        gymnasium.register(
            id=MANIPULATOR_ID,
            entry_point="flexid.envs.manipulator:FlexibleManipulatorEnv",
            vector_entry_point="flexid.envs.manipulator:FlexibleManipulatorVectorEnv",
            max_episode_steps=2000,
        )
    if TWIN_ROTOR_ID not in registry:
        gymnasium.register(
            id=TWIN_ROTOR_ID,
            entry_point="flexid.envs.twin_rotor:TwinRotorEnv",
            vector_entry_point="flexid.envs.twin_rotor:TwinRotorVectorEnv",
            max_episode_steps=600,
        )


register_environments()
