"""The native vector environment: N platforms stepped by one compiled rollout call per step."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import logger, spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from stewart_env.envs.core import BatchAttributes, PlatformBatch, check_action
from stewart_env.envs.stewart_platform import term_key

__all__ = ["StewartPlatformVectorEnv"]


def _autoreset_mode(value: Any) -> AutoresetMode:
    if isinstance(value, AutoresetMode):
        return value
    for mode in AutoresetMode:
        # "NextStep" (the enum's value), "next_step", "NEXT_STEP" (its name) all name NEXT_STEP.
        if isinstance(value, str) and value.lower().replace("_", "") == mode.value.lower():
            return mode
    raise ValueError(f"autoreset_mode: expected an AutoresetMode or one of "
                     f"{', '.join(m.value for m in AutoresetMode)}, got {value!r}")


def _masked(value: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``value`` where ``mask``, else the empty value of its dtype (0 or None)."""
    out = np.full(value.shape, None, dtype=object) if value.dtype == object else np.zeros_like(value)
    out[mask] = value[mask]
    return out


class StewartPlatformVectorEnv(BatchAttributes, VectorEnv):
    """``num_envs`` Stewart platforms in one batch (see :class:`StewartPlatformEnv` for the card).

    Keyword arguments are those of the single environment, plus:
        num_envs: number of platforms N.
        max_episode_steps: truncation after this many steps of a row (``gymnasium.make_vec``
            passes the registered 500); None never truncates.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (default, Gymnasium's), ``SAME_STEP`` or
            ``DISABLED`` (reset rows with ``reset(options={"reset_mask": mask})``), as in
            Gymnasium's vector API; also ``metadata["autoreset_mode"]``.

    Seeding follows Gymnasium's SyncVectorEnv: ``reset(seed=s)`` seeds row i with s + i (a list
    seeds row by row), so row i reproduces ``gymnasium.make("StewartPlatform-v0")`` reset with
    seed s + i, step for step, across autoresets.  Every step is one call of the compiled rollout
    for all rows; with domain randomisation each row has its own parameter set.

    Infos are Gymnasium vector infos: every key holds an (N,) array with a boolean mask under
    ``"_" + key``; step keys are those of the single environment (``reward_<term>``,
    ``termination``, ``time``).  ``render()`` draws row 0 only.
    """

    _rows = slice(None)  # BatchAttributes: every row
    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 100.0,
                "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None, render_mode: str | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, **kwargs: Any):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs: expected a positive integer, got {num_envs!r}")
        if max_episode_steps is not None and (isinstance(max_episode_steps, bool)
                                              or not isinstance(max_episode_steps, (int, np.integer))
                                              or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps: expected a positive integer or None, got {max_episode_steps!r}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode: expected one of {self.metadata['render_modes']} or None, "
                             f"got {render_mode!r}")
        self.num_envs = int(num_envs)
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self.render_mode = render_mode
        self.autoreset_mode = _autoreset_mode(autoreset_mode)
        self._core = core = PlatformBatch(self.num_envs, **kwargs)
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
        n = self.num_envs
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if options:
            raise ValueError(f"reset: unknown option(s) {', '.join(map(repr, options))}; only 'reset_mask'")
        if mask is None:
            mask = np.ones(n, dtype=bool)
        elif not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (n,)):
            raise ValueError(f"reset: options['reset_mask'] must be a bool array of shape ({n},), got {mask!r}")
        if seed is None:
            seeds = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
            self._np_random, self._np_random_seed = seeding.np_random(int(seed))
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"reset: a list of seeds must have num_envs={n} entries, got {len(seeds)}")
        rows = np.flatnonzero(mask)
        for i in rows:
            if seeds[i] is not None or self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(seeds[i])[0]
        infos = self._reset_infos({}, rows, self._core.reset_rows(rows, [self._rngs[i] for i in rows]))
        self._elapsed[rows] = 0
        self._autoreset[rows] = False
        if self.render_mode == "human":
            self.render()
        return self._core.observation.astype(np.float32), infos

    def step(self, actions):
        core, n = self._core, self.num_envs
        a = check_action(actions, (n, 6))
        mode = self.autoreset_mode
        resetting = self._autoreset if mode == AutoresetMode.NEXT_STEP and self._autoreset.any() else None
        if mode == AutoresetMode.DISABLED and self._autoreset.any():
            rows = np.flatnonzero(self._autoreset).tolist()
            raise ValueError(f"step: rows {rows} ended; with autoreset_mode DISABLED reset them first with "
                             "reset(options={'reset_mask': mask})")
        reward, code, terms = core.step(a, self._rngs, skip=resetting)
        self._elapsed += 1
        terminated = code > 0
        truncated = (self._elapsed >= self.max_episode_steps if self.max_episode_steps is not None
                     else np.zeros(n, dtype=bool))
        stepped = np.ones(n, dtype=bool) if resetting is None else ~resetting
        infos = self._step_infos(terms, code, stepped)

        if resetting is not None:
            rows = np.flatnonzero(resetting)
            reward[rows] = 0.0
            terminated[rows] = False
            truncated[rows] = False
            self._reset_rows(rows, infos)
        elif mode == AutoresetMode.SAME_STEP:
            done = terminated | truncated
            if done.any():
                rows = np.flatnonzero(done)
                final_obs = np.full(n, None, dtype=object)
                for i in rows:
                    final_obs[i] = core.observation[i].astype(np.float32)
                # As Gymnasium's vector envs: a finished row's step info moves to final_info, and
                # the top level holds its reset info instead.
                step_infos = infos
                infos = {k: (v & ~done) if k.startswith("_") else _masked(v, ~done)
                         for k, v in step_infos.items()}
                infos["final_obs"], infos["_final_obs"] = final_obs, done.copy()
                infos["final_info"] = {k: (v & done) if k.startswith("_") else _masked(v, done)
                                       for k, v in step_infos.items()}
                infos["_final_info"] = done.copy()
                self._reset_rows(rows, infos)
        self._autoreset = terminated | truncated
        if self.render_mode == "human":
            self.render()
        return core.observation.astype(np.float32), reward, terminated, truncated, infos

    def _reset_rows(self, rows: np.ndarray, infos: dict[str, Any]) -> None:
        row_infos = self._core.reset_rows(rows, [self._rngs[i] for i in rows])
        self._elapsed[rows] = 0
        self._reset_infos(infos, rows, row_infos)

    def _step_infos(self, terms: dict[str, np.ndarray], code: np.ndarray, stepped: np.ndarray) -> dict[str, Any]:
        core = self._core
        values = {term_key(k): v for k, v in terms.items()}
        values["termination"] = core.reasons(code)
        values["time"] = core.time.copy()
        all_rows = bool(stepped.all())
        infos: dict[str, Any] = {}
        for key, value in values.items():
            infos[key] = value if all_rows else _masked(value, stepped)
            infos["_" + key] = stepped.copy()
        return infos

    def _reset_infos(self, infos: dict[str, Any], rows: np.ndarray,
                     row_infos: list[dict[str, Any]]) -> dict[str, Any]:
        """Add per-row reset infos to vector infos, as Gymnasium's vector envs do."""
        for i, info in zip(rows, row_infos):
            for key, value in info.items():
                if key not in infos:
                    if isinstance(value, dict):
                        infos[key] = {k: np.zeros(self.num_envs) for k in value}
                        for k in value:
                            infos[key]["_" + k] = np.zeros(self.num_envs, dtype=bool)
                    else:
                        infos[key] = np.full(self.num_envs, None, dtype=object)
                    infos["_" + key] = np.zeros(self.num_envs, dtype=bool)
                if isinstance(value, dict):
                    for k, v in value.items():
                        infos[key][k][i] = v
                        infos[key]["_" + k][i] = True
                else:
                    infos[key][i] = value
                infos["_" + key][i] = True
        return infos

    def render(self):
        if self.render_mode is None:
            logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        frame = self._draw("row 0, ")
        return None if frame is None else (frame,)

    def close_extras(self, **kwargs: Any) -> None:
        self._close_renderer()
