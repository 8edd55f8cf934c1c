"""What the plants' batched vector environments share: their arguments, seeding and autoreset.

Each plant has a single environment and a vector environment that steps ``num_envs`` copies
of it together.  The vector environment takes the single environment's keyword arguments, so
their defaults are read from the single environment's signature, stated once.  Autoreset is
Gymnasium's ``NEXT_STEP`` mode, and ``reset(seed=s)`` seeds sub-environment ``i`` with
``s + i``, as ``SyncVectorEnv`` does.
"""

from __future__ import annotations

import inspect
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector.utils import batch_space

from flexid._validate import integer, positive_int
from flexid.data.plants import Plant
from flexid.errors import PlantParameterError


class BatchedVectorEnv(gymnasium.vector.VectorEnv):
    """Base of a vector environment that steps its sub-environments as one batch.

    A subclass names its single environment and the validated settings of both as class
    keywords, ``class V(BatchedVectorEnv, single_env=Env, config_type=Config)``; it takes
    the single environment's ``plant`` and ``metadata`` (with Gymnasium's ``NEXT_STEP``
    autoreset mode added).  ``config_type``, called with the single environment's keyword
    arguments (``**physics`` as one dict ``physics``), returns an object with the attributes
    ``params`` and ``dt`` and the method ``spaces()`` (the single action and observation
    spaces).  The subclass's ``__init__`` states the signature and calls this one first;
    its ``step`` ends with :meth:`_end_step`.

    Parameters
    ----------
    num_envs : int
        Number of sub-environments, >= 1.
    render_mode : str or None
        Passed to :attr:`config_type`, which checks it.
    max_episode_steps : int or None
        Steps after which a sub-environment is truncated, >= 1; None: never.
    kwargs : dict
        The single environment's keyword arguments; the missing ones take its defaults.
    """

    single_env: ClassVar[type[gymnasium.Env]]
    config_type: ClassVar[type]
    plant: ClassVar[Plant]

    def __init_subclass__(cls, *, single_env: type[gymnasium.Env], config_type: type) -> None:
        super().__init_subclass__()
        cls.single_env = single_env
        cls.config_type = config_type
        cls.plant = single_env.plant
        cls.metadata = {
            **single_env.metadata,
            "autoreset_mode": gymnasium.vector.AutoresetMode.NEXT_STEP,
        }

    def __init__(
        self,
        num_envs: Any,
        render_mode: str | None,
        max_episode_steps: Any,
        kwargs: dict[str, Any],
    ) -> None:
        self.num_envs = positive_int(num_envs, "'num_envs'", error=PlantParameterError)
        self.max_episode_steps = integer(
            max_episode_steps, "'max_episode_steps'", error=PlantParameterError, minimum=1,
            none_ok=True,
        )
        signature = inspect.signature(self.single_env.__init__)
        keywords = signature.bind_partial(render_mode=render_mode, **kwargs)
        keywords.apply_defaults()
        self._cfg = self.config_type(**keywords.arguments)
        self.params = self._cfg.params
        self.dt = self._cfg.dt
        self.render_mode = render_mode
        self.single_action_space, self.single_observation_space = self._cfg.spaces()
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.steps = np.zeros(self.num_envs, dtype=np.int64)
        self.prev_done = np.zeros(self.num_envs, dtype=bool)
        self._rngs = [seeding.np_random(None)[0] for _ in range(self.num_envs)]

    def _seed(self, seed: int | list[int] | None) -> list[int] | None:
        """Give each sub-environment its generator from ``seed``; return the seeds used.

        An int ``s`` seeds sub-environment ``i`` with ``s + i``; a list gives one seed per
        sub-environment; None keeps the generators (and returns None).
        """
        if seed is None:
            return None
        if isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise PlantParameterError(
                f"reset needs one seed per env ({self.num_envs}), got {len(seeds)}"
            )
        self._rngs = [seeding.np_random(s)[0] for s in seeds]
        return seeds

    def _restart(self, seed: int | list[int] | None) -> list[int] | None:
        """Seed the sub-environments (:meth:`_seed`) and start their episodes afresh: no step
        taken, none done.  Returns the seeds used; the subclass resets the states."""
        seeds = self._seed(seed)
        self.steps[:] = 0
        self.prev_done[:] = False
        return seeds

    def _end_step(
        self, done: np.ndarray, reward: np.ndarray, terminated: np.ndarray
    ) -> np.ndarray:
        """Truncation and autoreset bookkeeping at the end of a step.

        ``done`` (num_envs,) marks the sub-environments this step reset; their ``reward`` and
        ``terminated`` are set to 0 and False in place.  Returns ``truncated`` (num_envs,).
        """
        truncated = (
            self.steps >= self.max_episode_steps
            if self.max_episode_steps is not None
            else np.zeros(self.num_envs, dtype=bool)
        )
        if done.any():
            reward[done] = 0.0
            terminated[done] = False
            truncated[done] = False
        self.prev_done = terminated | truncated
        return truncated
