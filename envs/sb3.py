"""stable-baselines3's ``VecEnv`` over the native vector environment (``hgo_mj.envs.sb3``).

stable-baselines3 trains on its own ``VecEnv`` interface, whose autoreset is the *same* step
(a member that ended returns the next episode's first observation, the last one in
``info["terminal_observation"]``), where Gymnasium 1.x's vector environments reset on the
*next* step. :func:`sb3_vec_env` gives one over :class:`~hgo_mj.envs.vector.HgoVectorEnv` (the
one loop at B = N, one process), without copying it into N single environments::

    from stable_baselines3 import PPO
    from hgo_mj.envs.sb3 import sb3_vec_env

    venv = sb3_vec_env("hgo_mj/CartPoleBalance-v0", num_envs=8, observation="true")
    PPO("MlpPolicy", venv).learn(100_000)

Importing this module does not import stable-baselines3 (it is the ``rl`` extra):
``Sb3VecEnvAdapter`` implements the interface by itself (its methods are stable-baselines3's
``VecEnv`` methods, documented there), and :func:`sb3_vec_env` makes it a subclass of
stable-baselines3's ``VecEnv`` (which its algorithms check with ``isinstance``) when it is
called.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from numpy.typing import NDArray

from hgo_mj.exceptions import DesignError

from .vector import HgoVectorEnv


def same_step(venv: HgoVectorEnv, actions: Any
              ) -> tuple[NDArray[np.float64], NDArray[np.float32], NDArray[np.bool_],
                         list[dict[str, Any]]]:
    """One step of an hgo_mj vector environment with stable-baselines3's autoreset.

    A member that terminated or was truncated is reset at once (``reset_mask``): its
    observation is the new episode's first, ``info["terminal_observation"]`` the last one and
    ``info["TimeLimit.truncated"]`` says whether the time limit (and not the task) ended it.

    Parameters
    ----------
    venv : HgoVectorEnv
        The vector environment (Gymnasium's ``NEXT_STEP`` autoreset, never reached here).
    actions : (N, m) array
        One action per member.

    Returns
    -------
    observations : (N, d) array
    rewards : (N,) float32 array
    dones : (N,) bool array
    infos : list of N dicts

    Examples
    --------
    >>> import gymnasium, numpy as np
    >>> import hgo_mj.envs
    >>> from hgo_mj.envs.sb3 import same_step
    >>> venv = gymnasium.make_vec("hgo_mj/CartPoleBalance-v0", num_envs=2, max_episode_steps=1)
    >>> _ = venv.reset(seed=0)
    >>> obs, rewards, dones, infos = same_step(venv, np.zeros((2, 1), np.float32))
    >>> dones.tolist(), infos[0]["TimeLimit.truncated"], infos[0]["terminal_observation"].shape
    ([True, True], True, (5,))
    """
    obs, rewards, terminated, truncated, _ = venv.step(actions)
    dones = terminated | truncated
    infos: list[dict[str, Any]] = [{} for _ in range(venv.num_envs)]
    if dones.any():
        for i in np.flatnonzero(dones).tolist():
            infos[i] = {"terminal_observation": obs[i].copy(),
                        "TimeLimit.truncated": bool(truncated[i] and not terminated[i])}
        fresh, _ = venv.reset(options={"reset_mask": dones})
        obs = obs.copy()
        obs[dones] = fresh[dones]
    return obs, rewards.astype(np.float32), dones, infos


class Sb3VecEnvAdapter:
    """stable-baselines3's ``VecEnv`` interface over an :class:`HgoVectorEnv` (duck-typed:
    no stable-baselines3 import; :func:`sb3_vec_env` gives the ``VecEnv`` subclass).

    ``seed(s)`` then ``reset()`` seeds member ``i`` with ``s + i``, as stable-baselines3's
    ``DummyVecEnv`` seeds its environments, so that member ``i`` is the single environment
    reset with that seed. The members share one configuration: ``get_attr`` reads the
    environment's, ``set_attr`` and ``env_method`` raise.

    Parameters
    ----------
    venv : HgoVectorEnv
        The native vector environment (``gymnasium.make_vec(id, num_envs=N)``).

    Raises
    ------
    DesignError
        ``venv`` is not an :class:`HgoVectorEnv`.

    Examples
    --------
    >>> import gymnasium, numpy as np
    >>> import hgo_mj.envs
    >>> from hgo_mj.envs.sb3 import Sb3VecEnvAdapter
    >>> venv = Sb3VecEnvAdapter(gymnasium.make_vec("hgo_mj/CartPoleBalance-v0", num_envs=4))
    >>> _ = venv.seed(0)
    >>> venv.reset().shape
    (4, 5)
    >>> obs, rewards, dones, infos = venv.step(np.zeros((4, 1), np.float32))
    >>> rewards.tolist(), dones.tolist()
    ([1.0, 1.0, 1.0, 1.0], [False, False, False, False])
    >>> venv.close()
    """

    def __init__(self, venv: HgoVectorEnv) -> None:
        if not isinstance(venv, HgoVectorEnv):
            raise DesignError(f"venv must be an HgoVectorEnv (gymnasium.make_vec(id, "
                              f"num_envs=N)); found {type(venv).__name__}")
        self.venv = venv
        self.num_envs = venv.num_envs
        self.observation_space = venv.single_observation_space
        self.action_space = venv.single_action_space
        self.render_mode = None
        self.metadata: dict[str, Any] = {"render_modes": []}
        self.reset_infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        self._seeds: list[int | None] = [None] * self.num_envs
        self._options: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        self._actions: Any = None

    # ------------------------------------------------------------- stepping
    def reset(self) -> NDArray[np.float64]:
        """Reset every member (with the seeds of :meth:`seed`, used once)."""
        seeds = self._seeds
        obs, _ = self.venv.reset(seed=None if all(s is None for s in seeds) else list(seeds))
        self._seeds = [None] * self.num_envs
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    def step_async(self, actions: Any) -> None:
        """Keep the actions for :meth:`step_wait`."""
        self._actions = actions

    def step_wait(self) -> tuple[Any, ...]:
        """Step every member (:func:`same_step`)."""
        return same_step(self.venv, self._actions)

    def step(self, actions: Any) -> tuple[Any, ...]:
        """:meth:`step_async` then :meth:`step_wait`."""
        self.step_async(actions)
        return self.step_wait()

    def seed(self, seed: int | None = None) -> Sequence[None | int]:
        """Seed member ``i`` with ``seed + i`` at the next :meth:`reset` (``None``: a fresh
        seed from the operating system's entropy, as stable-baselines3 draws one)."""
        if seed is None:
            seed = int(np.random.default_rng().integers(0, np.iinfo(np.uint32).max))
        self._seeds = [seed + i for i in range(self.num_envs)]
        return self._seeds

    def set_options(self, options: list[dict[str, Any]] | dict[str, Any] | None = None) -> None:
        """Refused unless empty: the members take no reset options here."""
        if options:
            raise DesignError(f"the hgo_mj vector environment takes no reset options through "
                              f"stable-baselines3; found {options!r}")

    def close(self) -> None:
        """Close the vector environment."""
        self.venv.close()

    # ------------------------------------------------------------- attributes
    def _indices(self, indices: Any) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        return [indices] if isinstance(indices, int) else list(indices)

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        """The environment's attribute, once per member (they share one configuration)."""
        return [getattr(self.venv.env, attr_name)] * len(self._indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        """Refused: the members share one configuration."""
        raise DesignError(f"the members of an hgo_mj vector environment share one "
                          f"configuration: cannot set {attr_name!r} per member")

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None,
                   **method_kwargs: Any) -> list[Any]:
        """Refused: the members are rows of one batch, not objects with methods."""
        raise DesignError(f"an hgo_mj vector environment has no per-member methods; "
                          f"found a call of {method_name!r}")

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        """False for every member: the native vector environment has no per-member wrapper."""
        return [False] * len(self._indices(indices))

    def get_images(self) -> Sequence[Any]:
        """The members' frames (``render_mode="rgb_array"`` at ``make_vec``), else Nones."""
        if self.venv.render_mode is None:
            return [None] * self.num_envs
        return list(self.venv.render() or ())

    def render(self, mode: str | None = None) -> None:
        """Not shown on screen: use :meth:`get_images`."""
        return None

    def getattr_depth_check(self, name: str, already_found: bool) -> str | None:
        """stable-baselines3's wrapper-depth check: this is the innermost ``VecEnv``."""
        return type(self).__name__ if hasattr(self, name) and already_found else None

    @property
    def unwrapped(self) -> Sb3VecEnvAdapter:
        """This adapter (the innermost ``VecEnv``)."""
        return self

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.venv!r})"


_SB3_CLASS: list[type] = []


def sb3_vec_env(env: str | HgoVectorEnv, num_envs: int | None = None, **kwargs: Any) -> Any:
    """A stable-baselines3 ``VecEnv`` over the native vector environment.

    Parameters
    ----------
    env : str or HgoVectorEnv
        A registered id (made with ``gymnasium.make_vec(env, num_envs, **kwargs)``) or a
        vector environment.
    num_envs : int, optional
        Members, with an id (required then).
    **kwargs
        The environment's arguments, with an id.

    Returns
    -------
    stable_baselines3.common.vec_env.VecEnv
        An :class:`Sb3VecEnvAdapter` that is also a ``VecEnv`` subclass.

    Raises
    ------
    ImportError
        stable-baselines3 is not installed (``pip install "hgo_mj[rl]"``).
    DesignError
        An id without ``num_envs``, or arguments with a vector environment.

    Examples
    --------
    The lines that need stable-baselines3 are skipped here (the test suite runs them where
    it is installed: ``tests/envs/test_sb3_rl.py``).

    >>> from hgo_mj.envs.sb3 import sb3_vec_env
    >>> venv = sb3_vec_env("hgo_mj/CartPoleBalance-v0", num_envs=8)  # doctest: +SKIP
    >>> type(venv).__mro__[1:3]  # doctest: +SKIP
    (<class 'hgo_mj.envs.sb3.Sb3VecEnvAdapter'>, <class '...VecEnv'>)
    >>> sb3_vec_env("hgo_mj/CartPoleBalance-v0")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: sb3_vec_env('hgo_mj/CartPoleBalance-v0') needs num_envs
    """
    if isinstance(env, str):
        if num_envs is None:
            raise DesignError(f"sb3_vec_env({env!r}) needs num_envs")
        venv: Any = gymnasium.make_vec(env, num_envs=num_envs, **kwargs)
    elif num_envs is not None or kwargs:
        raise DesignError(f"num_envs and the environment's arguments go with an id; found "
                          f"them with {type(env).__name__}")
    else:
        venv = env
    if not _SB3_CLASS:
        from stable_baselines3.common.vec_env import VecEnv

        _SB3_CLASS.append(type("HgoSb3VecEnv", (Sb3VecEnvAdapter, VecEnv), {
            "__doc__": "stable-baselines3's VecEnv over an HgoVectorEnv "
                       "(:class:`Sb3VecEnvAdapter`)."}))
    return _SB3_CLASS[0](venv)


#: the public names (``Sb3VecEnvAdapter``'s methods are stable-baselines3's interface)
__all__ = ["same_step", "sb3_vec_env"]
