"""Gymnasium environments for the simulated flexible plants.

``flexid/FlexibleManipulator-v0``
    Single-link flexible manipulator: finite-difference Euler-Bernoulli beam on a motor hub
    (:mod:`flexid.envs.beam`, :mod:`flexid.envs.manipulator`).
``flexid/TwinRotor-v0``
    Twin rotor MIMO system, Feedback 33-949S phenomenological model
    (:mod:`flexid.envs.twin_rotor`).

A plant registered without an environment class of its own gets the generic
:class:`~flexid.envs.plant_env.PlantEnv` (and :class:`~flexid.envs.plant_env.PlantVectorEnv`)
built from its pure functions (:class:`flexid.data.plants.PlantFunctions`).

Importing this module registers the environment of every plant in
:data:`flexid.data.plants.PLANTS` (and imports Gymnasium); a plant registered later
(:func:`flexid.data.plants.register_plant`) has its environment registered at once.  ``import
flexid`` does not import Gymnasium: it arranges for this module to be imported as soon as
Gymnasium is (or at once if Gymnasium already is), so ``import flexid; import gymnasium;
gymnasium.make(ID)`` works in either import order.  Gymnasium 1.x reads no plugin entry
points, so without importing flexid use the ``module:id`` form, ``gymnasium.make("flexid.envs:"
+ ID)``, which imports this module first.  The entry points are strings, so the physics
modules are imported only when an environment is made.
"""

from __future__ import annotations

import gymnasium

from ..data.plants import PLANTS, get_plant

MANIPULATOR_ID = get_plant("manipulator").env_id
TWIN_ROTOR_ID = get_plant("twin-rotor").env_id

__all__ = ["MANIPULATOR_ID", "TWIN_ROTOR_ID", "register_environments"]

_GENERIC_ENTRY_POINT = "flexid.envs.plant_env:PlantEnv"
_GENERIC_VECTOR_ENTRY_POINT = "flexid.envs.plant_env:PlantVectorEnv"


def register_environments() -> None:
    """Register the environment of every plant in :data:`flexid.data.plants.PLANTS` (idempotent).

    A plant without an ``env_entry_point`` gets the generic
    :class:`~flexid.envs.plant_env.PlantEnv` when it gives a transition (its name is the
    environment's ``plant`` keyword), else none; an id already registered is left as it is.
    """
    registry = gymnasium.envs.registration.registry
    for plant in list(PLANTS.values()):
        if plant.env_id in registry:
            continue
        if plant.env_entry_point is not None:
            gymnasium.register(
                id=plant.env_id,
                entry_point=plant.env_entry_point,
                vector_entry_point=plant.vector_entry_point,
                max_episode_steps=plant.max_episode_steps,
            )
        elif plant.transition is not None:
            gymnasium.register(
                id=plant.env_id,
                entry_point=_GENERIC_ENTRY_POINT,
                vector_entry_point=plant.vector_entry_point or _GENERIC_VECTOR_ENTRY_POINT,
                max_episode_steps=plant.max_episode_steps,
                kwargs={"plant": plant.name},
            )


register_environments()
