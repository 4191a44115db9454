"""Registers the environment with Gymnasium: ``gymnasium.make("StewartPlatform-v0", ...)`` and
``gymnasium.make_vec("StewartPlatform-v0", num_envs=N, vectorization_mode="vector_entry_point")``.

Imported by ``stewart_env``; the entry points are strings, so nothing heavy is imported here.
"""

import gymnasium

ENV_ID = "StewartPlatform-v0"
#: 500 control steps: 5 s at the default control_dt of 10 ms.
MAX_EPISODE_STEPS = 500

if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        id=ENV_ID,
        entry_point="stewart_env.envs.stewart_platform:StewartPlatformEnv",
        vector_entry_point="stewart_env.envs.vector:StewartPlatformVectorEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
    )
