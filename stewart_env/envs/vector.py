"""The native vector environment: N platforms stepped by one compiled rollout call per step."""

from __future__ import annotations

import inspect
import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import logger, spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from stewart_env.envs.attributes import BatchAttributes
from stewart_env.envs.config import RENDER_MODES, EnvConfig
from stewart_env.envs.core import PlatformBatch
from stewart_env.envs.infos import step_values
from stewart_env.envs.keywords import check_arguments, with_signature
from stewart_env.errors import UsageError
from stewart_env.validation import check_action, integer, reset_options

__all__ = ["BYTES_PER_PLATFORM", "MAX_NUM_ENVS", "StewartPlatformVectorEnv", "available_memory", "check_batch_memory"]

#: Memory one platform of a batch takes, bytes, rounded up: 2.4-3.3 KiB a row measured after a
#: seeded reset and a few steps of each task (state, observation buffers, each row's generator).
BYTES_PER_PLATFORM = 4096
#: Largest batch: row indices are 32-bit in the compiled core.
MAX_NUM_ENVS = 2**31 - 1


def available_memory() -> int | None:
    """Bytes this machine can still allocate, or None where it cannot tell.

    Returns:
        ``MemAvailable`` of ``/proc/meminfo`` (Linux), else the physical memory
        (``os.sysconf``), else None.
    """
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        pages, size = os.sysconf("SC_PHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):  # no sysconf (Windows) or no such name
        return None
    return pages * size if pages > 0 and size > 0 else None


def _size(nbytes: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if nbytes >= scale:
            return f"{nbytes / scale:.3g} {unit}"
    return f"{nbytes / 1e3:.3g} kB"


def check_batch_memory(name: str, num_envs: int, bytes_per_platform: float = BYTES_PER_PLATFORM) -> None:
    """Refuse, before anything is allocated, a batch that does not fit in the memory this machine
    has available (:func:`available_memory`; no check where it cannot tell).

    Args:
        name: the argument that sets the batch's size, which the message names.
        num_envs: platforms in the batch.
        bytes_per_platform: memory one platform takes (default :data:`BYTES_PER_PLATFORM`; a
            caller that keeps more per platform, e.g. a record of every step, adds it).

    Raises:
        UsageError: the estimate exceeds the available memory (both in the message), about ``name``.
    """
    available = available_memory()
    need = float(num_envs) * float(bytes_per_platform)
    if available is not None and need > available:
        raise UsageError.about(
            name,
            f"{num_envs} platforms do not fit in this machine's memory: they need about "
            f"{_size(need)}, {_size(available)} is available",
        )


def _autoreset_mode(value: Any) -> AutoresetMode:
    if isinstance(value, AutoresetMode):
        return value
    for mode in AutoresetMode:
        # "NextStep" (the enum's value), "next_step", "NEXT_STEP" (its name) all name NEXT_STEP.
        if isinstance(value, str) and value.lower().replace("_", "") == mode.value.lower():
            return mode
    raise ValueError(
        f"autoreset_mode: expected an AutoresetMode or one of "
        f"{', '.join(m.value for m in AutoresetMode)}, got {value!r}"
    )


def _masked(value: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``value`` (a step info array (n, ...): float or int codes) where ``mask`` (n,), else 0 (of its dtype)."""
    return np.where(mask.reshape(mask.shape + (1,) * (value.ndim - 1)), value, np.zeros((), dtype=value.dtype))


def _same(a: Any, b: Any) -> bool:
    """Whether two values given to set_attr are equal (arrays compared entrywise)."""
    try:
        return a is b or bool(np.array_equal(a, b))
    except (TypeError, ValueError):
        return False


class _Row(BatchAttributes):
    """Sub-environment ``index`` of a vector environment, as ``call``, ``get_attr`` and
    ``set_attr`` see it: the row's state, target, forces, episode parameters, Generator
    (``np_random``, settable) and frame (``render()``); every other name is the vector
    environment's own, shared by all rows."""

    def __init__(self, venv: StewartPlatformVectorEnv, index: int):
        self._venv, self._core, self._rows = venv, venv._core, index

    @classmethod
    def settable(cls, name: str) -> bool:
        """Whether ``name`` is an attribute that each row sets for itself."""
        own = getattr(cls, name, None)
        return isinstance(own, property) and own.fset is not None

    @property
    def np_random(self) -> np.random.Generator | None:
        """The row's Generator (None before its first reset)."""
        return self._venv._rngs[self._rows]

    @np_random.setter
    def np_random(self, value: np.random.Generator) -> None:
        if not isinstance(value, np.random.Generator):
            raise ValueError(f"np_random: expected a numpy Generator, got {value!r}")
        self._venv._rngs[self._rows] = value

    @property
    def observation_space(self) -> spaces.Box:
        return self._venv.single_observation_space

    @property
    def action_space(self) -> spaces.Box:
        return self._venv.single_action_space

    def render(self):
        """The row's frame now, as the single environment renders it."""
        venv = self._venv
        if venv.render_mode is None:
            return venv.render()
        return venv._draw(self._rows)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):  # the row's own members are set in __init__
            raise AttributeError(name)
        if name in ("reset", "step"):
            raise AttributeError(
                f"{name}: a row does not {name} alone; call the vector environment's {name}() "
                "(reset(options={'reset_mask': mask}) resets some rows)"
            )
        return getattr(self._venv, name)


class _Frames(Sequence):
    """One rgb_array frame per row, of the rows as they were when made, each as the single
    environment draws it; a row is drawn on first access, so recording row 0 of a large batch
    draws one frame per step, not N."""

    def __init__(self, venv: StewartPlatformVectorEnv):
        self._venv = venv
        self._scene = tuple(x.copy() for x in venv._scene())
        self._frames: dict[int, np.ndarray] = {}

    def __len__(self) -> int:
        return self._venv.num_envs

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(len(self))[index]]
        i = range(len(self))[index]  # IndexError beyond the rows, as a list
        if i not in self._frames:
            self._frames[i] = self._venv._draw(i, scene=self._scene)
        return self._frames[i]


class StewartPlatformVectorEnv(BatchAttributes, VectorEnv):
    """``num_envs`` Stewart platforms in one batch (see :class:`StewartPlatformEnv` for the card).

    Seeding follows Gymnasium's SyncVectorEnv: ``reset(seed=s)`` seeds row i with s + i (a list
    seeds row by row), so row i reproduces ``gymnasium.make("StewartPlatform-v1")`` reset with
    seed s + i, step for step, across autoresets.  Every step is one call of the compiled rollout
    for all rows; with domain randomisation each row has its own parameter set.

    Infos are Gymnasium vector infos: every key holds an (N,) array with a boolean mask under
    ``"_" + key``; step keys are those of the single environment (``reward_<term>``,
    ``termination`` an int64 array of codes, 0 for rows that go on, ``time``, ``position_error``,
    ``orientation_error``, ``is_success`` a bool array); a row reset at the step (next-step
    autoreset) has no step info (its mask False, its values 0 and False).

    A row is a sub-environment to ``call``, ``get_attr`` and ``set_attr`` (Gymnasium's
    semantics: a tuple of one result per row), e.g. ``get_attr("state")`` or ``call("render")``;
    ``render()`` gives one frame per row in ``rgb_array`` mode (each drawn when first indexed),
    and draws row 0 in ``human`` mode.

    Args:
        num_envs: number of platforms N.
        max_episode_steps: truncation after this many steps of a row (``gymnasium.make_vec``
            passes the registered 500); None never truncates.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (default, Gymnasium's), ``SAME_STEP`` or
            ``DISABLED`` (reset rows with ``reset(options={"reset_mask": mask})``), as in
            Gymnasium's vector API; also ``metadata["autoreset_mode"]``.
        **arguments: the keyword arguments of the single environment (the same signature, see
            :class:`StewartPlatformEnv`).

    Raises:
        ValueError: an argument out of its range or of the wrong kind (the message names it).

    Examples:
        >>> import numpy as np
        >>> from stewart_env.envs import StewartPlatformVectorEnv
        >>> envs = StewartPlatformVectorEnv(num_envs=4, task="setpoint")
        >>> observations, infos = envs.reset(seed=0)
        >>> observations.shape
        (4, 21)
        >>> observations, rewards, terminated, truncated, infos = envs.step(np.zeros((4, 6), np.float32))
        >>> rewards.shape, terminated.tolist()
        ((4,), [False, False, False, False])
        >>> envs.close()
    """

    _rows = slice(None)  # BatchAttributes: every row
    metadata = {"render_modes": list(RENDER_MODES), "render_fps": 100.0, "autoreset_mode": AutoresetMode.NEXT_STEP}

    @with_signature(
        *(
            inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=default)
            for name, default in (
                ("num_envs", 1),
                ("max_episode_steps", None),
                ("autoreset_mode", AutoresetMode.NEXT_STEP),
            )
        )
    )
    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **arguments: Any,
    ):
        check_arguments(type(self).__name__, arguments, ("num_envs", "max_episode_steps", "autoreset_mode"))
        self.num_envs = integer("num_envs", num_envs, 1, MAX_NUM_ENVS)
        check_batch_memory("num_envs", self.num_envs)
        self.max_episode_steps = (
            None if max_episode_steps is None else integer("max_episode_steps", max_episode_steps, 1, 2**62)
        )
        self.autoreset_mode = _autoreset_mode(autoreset_mode)
        config = EnvConfig.of(**arguments)
        self.render_mode = config.render.render_mode
        try:
            self._core = core = PlatformBatch(self.num_envs, config)
        except MemoryError:
            raise ValueError(f"num_envs: {self.num_envs} platforms do not fit in this machine's memory") from None
        self.metadata = {**type(self).metadata, "render_fps": core.render_fps, "autoreset_mode": self.autoreset_mode}
        self.single_action_space = spaces.Box(-1.0, 1.0, (6,), np.float32)
        self.single_observation_space = spaces.Box(-np.inf, np.inf, (core.obs_dim,), np.float32)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)

    # -- the Gymnasium vector API --------------------------------------------------------------------

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None):
        """Start new episodes (Gymnasium's ``VectorEnv.reset``), in every row or in the rows of a mask.

        Args:
            seed: one seed (row i seeded with ``seed + i``), a list of num_envs seeds (None: the
                row goes on with its generator), or None.
            options: None, or ``{"reset_mask": mask}`` with ``mask`` a (num_envs,) bool array of
                the rows to reset.

        Returns:
            The observations (num_envs, D) float32 and the rows' infos, one dict of arrays.

        Raises:
            TypeError: ``options`` not a mapping, or a seed not an integer (an ``ArgumentError``, a ``UsageError``).
            ValueError: an unknown option, a mask of another dtype or shape, a list of seeds not
                of num_envs entries, or a seed out of range.
        """
        n = self.num_envs
        mask = reset_options(options, ("reset_mask",)).get("reset_mask")
        if mask is None:
            mask = np.ones(n, dtype=bool)
        elif not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (n,)):
            raise ValueError(f"reset: options['reset_mask'] must be a bool array of shape ({n},), got {mask!r}")
        if seed is None:
            seeds = [None] * n
        elif isinstance(seed, (list, tuple, np.ndarray)):
            if len(seed) != n:
                raise ValueError(f"reset: a list of seeds must have num_envs={n} entries, got {len(seed)}")
            seeds = [None if s is None else integer(f"seed[{i}]", s, 0, 2**63) for i, s in enumerate(seed)]
        else:
            seed = integer("seed", seed, 0, 2**63 - n)
            seeds = [seed + i for i in range(n)]
            self._np_random, self._np_random_seed = seeding.np_random(seed)
        rows = np.flatnonzero(mask)
        for i in rows.tolist():
            if seeds[i] is not None or self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(seeds[i])[0]
        infos = self._reset_infos({}, rows, self._core.reset_rows(rows, self._rngs_of(rows), True))
        self._reset_done = all(rng is not None for rng in self._rngs)
        self._elapsed[rows] = 0
        self._autoreset[rows] = False
        if self.render_mode == "human":
            self.render()
        return self._core.observation.astype(np.float32), infos

    def step(self, actions):
        """One control step of every row (Gymnasium's ``VectorEnv.step``), ended rows reset as
        ``autoreset_mode`` says.

        Args:
            actions: (num_envs, 6) the leg forces scaled to [-1, 1] (clipped there), finite.

        Returns:
            The tuple (observations (num_envs, D) float32, rewards, terminated, truncated, infos),
            each of num_envs rows, infos one dict of arrays.

        Raises:
            TypeError: actions that are not real numbers (an ``ArgumentError``, a ``UsageError``).
            ValueError: actions of another shape or not finite, or, with autoreset_mode DISABLED, a
                step of rows that ended and were not reset.
            gymnasium.error.ResetNeeded: a step before every row's first reset.
        """
        self._check_reset()
        core, n = self._core, self.num_envs
        a = check_action(actions, (n, 6))
        mode = self.autoreset_mode
        resetting = self._autoreset if mode == AutoresetMode.NEXT_STEP and self._autoreset.any() else None
        if mode == AutoresetMode.DISABLED and self._autoreset.any():
            rows = np.flatnonzero(self._autoreset).tolist()
            raise ValueError(
                f"step: rows {rows} ended; with autoreset_mode DISABLED reset them first with "
                "reset(options={'reset_mask': mask})"
            )
        reward, code, terms, observation = core.step(a, self._rngs, skip=resetting)
        self._elapsed += 1
        terminated = code > 0
        truncated = (
            self._elapsed >= self.max_episode_steps if self.max_episode_steps is not None else np.zeros(n, dtype=bool)
        )
        stepped = np.ones(n, dtype=bool) if resetting is None else ~resetting
        infos = self._step_infos(terms, code, stepped)

        if resetting is not None:
            rows = np.flatnonzero(resetting)
            reward[rows] = 0.0
            terminated[rows] = False
            truncated[rows] = False
            self._reset_rows(rows, infos)
            observation[rows] = core.observation[rows]
        elif mode == AutoresetMode.SAME_STEP:
            done = terminated | truncated
            if done.any():
                rows = np.flatnonzero(done)
                final_obs = np.full(n, None, dtype=object)
                for i in rows:
                    final_obs[i] = observation[i].copy()
                # As Gymnasium's vector envs: a finished row's step info moves to final_info, and
                # the top level holds its reset info instead.
                step_infos = infos
                infos = {k: (v & ~done) if k.startswith("_") else _masked(v, ~done) for k, v in step_infos.items()}
                infos["final_obs"], infos["_final_obs"] = final_obs, done.copy()
                infos["final_info"] = {
                    k: (v & done) if k.startswith("_") else _masked(v, done) for k, v in step_infos.items()
                }
                infos["_final_info"] = done.copy()
                self._reset_rows(rows, infos)
                observation[rows] = core.observation[rows]
        self._autoreset = terminated | truncated
        if self.render_mode == "human":
            self.render()
        return observation, reward, terminated, truncated, infos

    def _reset_rows(self, rows: np.ndarray, infos: dict[str, Any]) -> None:
        row_infos = self._core.reset_rows(rows, self._rngs_of(rows), True)
        self._elapsed[rows] = 0
        self._reset_infos(infos, rows, row_infos)

    def _rngs_of(self, rows: np.ndarray) -> list[np.random.Generator]:
        """The Generators of ``rows`` (an int array), in their order."""
        rngs = self._rngs
        return [rngs[i] for i in rows.tolist()]

    def _step_infos(self, terms: dict[str, np.ndarray], code: np.ndarray, stepped: np.ndarray) -> dict[str, Any]:
        core = self._core
        values = step_values(
            terms,
            code,
            core.time,
            core.plant.closure_error,
            core.track_success(code),
            core.costs.info(),
            core.task.step_info(),
        )
        # each value is an array of its own (step_values): the rows not stepped are zeroed in place,
        # the numbers of _masked(value, stepped)
        idle = None if stepped.all() else np.flatnonzero(~stepped)
        infos: dict[str, Any] = {}
        for key, value in values.items():
            if idle is not None:
                value[idle] = 0
            infos[key] = value
            infos["_" + key] = stepped.copy()
        return infos

    def _reset_infos(
        self, infos: dict[str, Any], rows: np.ndarray, row_infos: dict[str, Any], rows_mask: np.ndarray | None = None
    ) -> dict[str, Any]:
        """Add the reset infos of ``rows`` (a dict of (m,) arrays, or nested dicts of them, in the
        order of ``rows``) to vector infos, with the result of Gymnasium's own rule row by row
        (``VectorEnv._add_info``): an (N,) array per key, of the values' type, and its mask under
        ``"_" + key``.  ``rows_mask``: the (N,) mask of ``rows``, made here when None (a new key's
        mask is a copy of it)."""
        n = self.num_envs
        if not row_infos:
            return infos
        if rows_mask is None:
            rows_mask = np.zeros(n, dtype=np.bool_)
            rows_mask[rows] = True
        for key, value in row_infos.items():
            if isinstance(value, dict):
                array = self._reset_infos(infos.get(key, {}), rows, value, rows_mask)
            else:
                array = infos.get(key)
                if array is None:
                    array = np.zeros((n, *value.shape[1:]), dtype=value.dtype)
                array[rows] = value
            mask = infos.get("_" + key)
            if mask is None:
                mask = rows_mask.copy()
            else:
                mask[rows] = True
            infos[key], infos["_" + key] = array, mask
        return infos

    def render(self):
        """``rgb_array``: one frame per row (a sequence of N, each row drawn when first indexed,
        as the rows are now); ``human``: draws row 0 in the window and returns None."""
        if self.render_mode is None:
            logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self.render_mode == "human":
            self._draw(0, "row 0, ")
            return None
        return _Frames(self)

    def _row(self, index: int) -> _Row:
        return _Row(self, index)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Gymnasium's vector ``call``: ``name`` of every row (see :class:`_Row`), called with the
        arguments if callable.

        Args:
            name: the attribute's name.
            *args: the positional arguments of the call.
            **kwargs: its keyword arguments.

        Returns:
            A tuple of one result per row.
        """
        results = []
        for i in range(self.num_envs):
            value = getattr(self._row(i), name)
            results.append(value(*args, **kwargs) if callable(value) else value)
        return tuple(results)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """Gymnasium's vector ``get_attr``: the attribute ``name`` of every row, a tuple.

        Args:
            name: the attribute's name.
        """
        return self.call(name)

    def set_attr(self, name: str, values: Any) -> None:
        """Gymnasium's vector ``set_attr``: one value for every row, or a list or tuple of one per
        row.  A row's own settable attribute (``np_random``) is set row by row; any other
        attribute is shared by the whole batch and takes one value.

        Args:
            name: the attribute's name.
            values: one value, or a list or tuple of num_envs values.

        Raises:
            ValueError: not one value or num_envs values, or different values of a shared attribute.
        """
        n = self.num_envs
        if not isinstance(values, (list, tuple)):
            values = [values] * n
        if len(values) != n:
            raise ValueError(f"set_attr: expected one value or num_envs={n} values for {name!r}, got {len(values)}")
        if _Row.settable(name):
            for i, value in enumerate(values):
                setattr(self._row(i), name, value)
        elif all(_same(v, values[0]) for v in values):
            setattr(self, name, values[0])
        else:
            raise ValueError(f"set_attr: {name!r} is shared by all rows of the batch; give one value for all")

    def close_extras(self, **kwargs: Any) -> None:
        """Close the renderer's window, if any (Gymnasium's ``VectorEnv.close`` calls it).

        Args:
            **kwargs: Gymnasium's arguments of ``close``, unused.
        """
        self._close_renderer()
