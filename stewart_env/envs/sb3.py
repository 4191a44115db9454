"""A stable-baselines3 ``VecEnv`` on the native batch, so SB3 trains on one rollout call per step.

Importing this module imports stable-baselines3 (and torch); ``stewart_env.envs`` imports it only
when ``StewartPlatformSB3VecEnv`` is first used.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv

from stewart_env.envs.keywords import check_arguments
from stewart_env.envs.vector import StewartPlatformVectorEnv
from stewart_env.registration import MAX_EPISODE_STEPS
from stewart_env.validation import ArgumentError, reset_options

__all__ = ["StewartPlatformSB3VecEnv"]


class StewartPlatformSB3VecEnv(VecEnv):
    """``num_envs`` platforms behind stable-baselines3's VecEnv API.

    SB3 semantics: a
    row that ends is reset in the same step, its last observation in
    ``infos[i]["terminal_observation"]``, ``infos[i]["TimeLimit.truncated"]`` True when the time
    limit (and not a termination) ended it, ``infos[i]["termination"]`` the reason's code, as
    the environment's (an index into ``termination_reasons``; 0 when truncated), and
    ``infos[i]["is_success"]`` whether the episode met the task's success criterion, as the
    environment's ``info["is_success"]`` (what SB3's ``EvalCallback`` and ``Monitor`` read at an
    episode's end).  Every row's info holds the step's constraint costs, ``cost`` and
    ``cost_<constraint>``, and the errors of the success criterion, ``position_error`` (m) and
    ``orientation_error`` (rad) (floats), as the environment's.  ``seed(s)`` seeds row i with s + i at the next ``reset()``, as SB3's own VecEnvs
    do, so row i reproduces ``gymnasium.make("StewartPlatform-v1")`` reset with seed s + i.
    Wrap in ``VecMonitor`` for episode statistics.

    ``get_attr``, ``set_attr`` and ``env_method`` reach the rows as sub-environments, as the
    vector environment's ``get_attr``, ``set_attr`` and ``call`` do (a row's state, target,
    ``np_random``...; other names are the batch's, shared by every row, and set only for all rows
    at once); ``render()``/``get_images()`` draw row 0.

    Args:
        num_envs: number of platforms N.
        max_episode_steps: truncation after this many steps of a row (default 500, as
            registered; None never truncates).
        render_mode: as the environment's.
        **kwargs: the environment's keyword arguments (see :class:`StewartPlatformEnv`; passed
            on to :class:`StewartPlatformVectorEnv`).

    Raises:
        ValueError: an argument out of its range or of the wrong kind (the message names it).

    Examples:
        >>> import numpy as np
        >>> from stewart_env.envs import StewartPlatformSB3VecEnv
        >>> venv = StewartPlatformSB3VecEnv(num_envs=2, task="hold")
        >>> venv.seed(0)
        [0, 1]
        >>> observations = venv.reset()
        >>> observations.shape
        (2, 21)
        >>> observations, rewards, dones, infos = venv.step(np.zeros((2, 6), np.float32))
        >>> dones.tolist()
        [False, False]
    """

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = MAX_EPISODE_STEPS,
        render_mode: str | None = None,
        **kwargs: Any,
    ):
        check_arguments(type(self).__name__, kwargs)
        self.venv = StewartPlatformVectorEnv(
            num_envs=num_envs,
            max_episode_steps=max_episode_steps,
            render_mode=render_mode,
            autoreset_mode=AutoresetMode.SAME_STEP,
            **kwargs,
        )
        super().__init__(num_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> np.ndarray:
        """SB3's ``reset``: every row starts an episode, with the seeds and options set before it.

        Returns:
            The observations (N, obs_dim); the rows' reset infos are in ``reset_infos``.
        """
        seed = None if all(s is None for s in self._seeds) else list(self._seeds)
        for options in self._options:
            reset_options(options)  # takes none: set_options refused here, naming options
        obs, infos = self.venv.reset(seed=seed)
        self.reset_infos = self._row_infos(infos, range(self.num_envs))
        self._reset_seeds()
        self._reset_options()
        return obs

    def set_options(self, options: dict | Sequence[dict | None] | None = None) -> None:
        """SB3's ``set_options``: one dict for every row or a list of one per row (this
        environment takes none, so only empty ones pass the next ``reset()``); anything else is
        refused now, naming ``options``.

        Args:
            options: one dict (or None) for every row, or a list of one per row.

        Raises:
            ValueError: a list of another length than the rows, or a row's options not a dict.
        """
        rows = options if isinstance(options, (list, tuple)) else [options] * self.num_envs
        if len(rows) != self.num_envs:
            raise ArgumentError(
                f"set_options: options: expected one dict for every row or a list of {self.num_envs}, "
                f"got a list of {len(rows)}"
            )
        for row in rows:
            if row is not None and not isinstance(row, Mapping):
                raise ArgumentError(
                    f"set_options: options: expected a dict (or None) per row, got {type(row).__name__}"
                )
        super().set_options(options)

    def step_async(self, actions: np.ndarray) -> None:
        """SB3's ``step_async``: hold the actions for :meth:`step_wait`.

        Args:
            actions: the rows' actions (N, 6).
        """
        self._actions = actions

    def step_wait(self):
        """SB3's ``step_wait``: step every row with the held actions, resetting the rows whose episode ended.

        Returns:
            (observations, rewards (float32), dones, infos), a done row's info holding its
            ``terminal_observation``, ``termination`` code and ``TimeLimit.truncated``.

        Raises:
            RuntimeError: no :meth:`step_async` before it.
        """
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async()")
        obs, reward, terminated, truncated, infos = self.venv.step(self._actions)
        self._actions = None
        done = terminated | truncated
        time_limit = truncated & ~terminated
        row_infos = [{"TimeLimit.truncated": bool(time_limit[i])} for i in range(self.num_envs)]
        self._add_step_values(row_infos, infos, done)
        if done.any():
            rows = np.flatnonzero(done)
            codes, success = infos["final_info"]["termination"], infos["final_info"]["is_success"]
            for i, info in zip(rows, self._row_infos(infos, rows)):
                row_infos[i]["terminal_observation"] = infos["final_obs"][i]
                row_infos[i]["termination"] = codes[i]
                row_infos[i]["is_success"] = success[i]
                self.reset_infos[i] = info
        return obs, reward.astype(np.float32), done, row_infos

    def _add_step_values(self, row_infos: list[dict[str, Any]], infos: dict[str, Any], done: np.ndarray) -> None:
        """Each row's constraint costs of the step (``cost``, ``cost_<constraint>``) and its errors
        (``position_error``, ``orientation_error``), floats, read from the vector infos: a done
        row's from its final info."""
        final = infos.get("final_info", {})
        for key in (*self.venv._core.costs.info_keys, "position_error", "orientation_error"):
            values = infos[key].tolist()
            if done.any():
                for i, value in zip(np.flatnonzero(done).tolist(), final[key][done].tolist()):
                    values[i] = value
            for info, value in zip(row_infos, values):
                info[key] = value

    @staticmethod
    def _row_infos(infos: dict[str, Any], rows: Iterable[int]) -> list[dict[str, Any]]:
        """Per-row reset infos (the domain randomisation factors) from vector infos."""
        out = []
        for i in rows:
            info = {}
            if "randomization" in infos and infos["_randomization"][i]:
                r = infos["randomization"]
                info["randomization"] = {k: v[i] for k, v in r.items() if not k.startswith("_")}
            out.append(info)
        return out

    def close(self) -> None:
        """Close the batch underneath (its renderer)."""
        self.venv.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """SB3's ``get_attr``: an attribute of each row's environment.

        Args:
            attr_name: the attribute's name.
            indices: the rows (an index, a sequence of them or None for all).
        """
        return [getattr(self.venv._row(i), attr_name) for i in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        """SB3's ``set_attr``: set an attribute of each row's environment.

        Args:
            attr_name: the attribute's name.
            value: its new value, the same for each row.
            indices: the rows (an index, a sequence of them or None for all).

        Raises:
            ValueError: an attribute the rows share, set for some rows only.
        """
        rows = self._indices(indices)
        if len(rows) == self.num_envs:
            self.venv.set_attr(attr_name, [value] * self.num_envs)  # SB3: one value for every index
            return
        if not self.venv._row(0).settable(attr_name):
            raise ValueError(f"set_attr: {attr_name!r} is shared by all rows of the batch; set it for every index")
        for i in rows:
            setattr(self.venv._row(i), attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        """SB3's ``env_method``: call a method of each row's environment.

        Args:
            method_name: the method's name.
            *method_args: its positional arguments.
            indices: the rows (an index, a sequence of them or None for all).
            **method_kwargs: its keyword arguments.

        Returns:
            Each row's return value.
        """
        return [getattr(self.venv._row(i), method_name)(*method_args, **method_kwargs) for i in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        """SB3's ``env_is_wrapped``: False for every row (the rows are no wrapped environments).

        Args:
            wrapper_class: the wrapper asked about.
            indices: the rows (an index, a sequence of them or None for all).
        """
        return [False] * len(self._indices(indices))

    def get_images(self) -> Sequence[np.ndarray | None]:
        """SB3's ``get_images``: the batch's frame with ``render_mode="rgb_array"``, else None."""
        frames = self.venv.render() if self.render_mode == "rgb_array" else None
        return [frames[0]] if frames is not None else [None]

    def _indices(self, indices) -> list[int]:
        return list(self._get_indices(indices))
