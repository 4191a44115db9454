"""Registers the environment with Gymnasium, one id per version: ``gymnasium.make(ENV_ID, ...)``
and ``gymnasium.make_vec(ENV_ID, num_envs=N, vectorization_mode="vector_entry_point")``, with
``ENV_ID`` the current version's id, ``"StewartPlatform-v1"``.

As Gymnasium does, a change of the environment's behaviour gets a new version, and the earlier ids
stay registered with their earlier behaviour.  Every id makes the same classes, with the
environment argument ``version`` set by the id (as Gymnasium's ids of one class with different
arguments are registered, e.g. ``FrozenLake8x8-v1``); the environment's card lists what each
version changed.  Imported by ``stewart_env``; the entry points are strings, so nothing heavy is
imported here.
"""

import gymnasium

#: The family name of the ids, ``StewartPlatform-v<version>``.
ENV_NAME = "StewartPlatform"
#: The current version: the one the environment classes give when not told otherwise.
CURRENT_VERSION = 1
#: Every registered id, by version.
ENV_IDS = {version: f"{ENV_NAME}-v{version}" for version in range(CURRENT_VERSION + 1)}
#: The current version's id.
ENV_ID = ENV_IDS[CURRENT_VERSION]
#: 500 control steps: 5 s at the default control_dt of 10 ms.
MAX_EPISODE_STEPS = 500

for _version, _env_id in ENV_IDS.items():
    if _env_id not in gymnasium.registry:
        gymnasium.register(
            id=_env_id,
            entry_point="stewart_env.envs.stewart_platform:StewartPlatformEnv",
            vector_entry_point="stewart_env.envs.vector:StewartPlatformVectorEnv",
            max_episode_steps=MAX_EPISODE_STEPS,
            kwargs={"version": _version},
        )
