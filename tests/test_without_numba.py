"""The package runs without numba: numba is only the optional extra for a user's own control laws
(``laws``), so ``import stewart_env``, the environments and rollout with the built-in PD law
work in an installation that lacks it."""

from __future__ import annotations

import json
import subprocess
import sys

# numba blocked before anything imports it: `import numba` then raises ImportError.
SCRIPT = r"""
import sys
sys.modules["numba"] = None

import json
import gymnasium as gym
import numpy as np

import stewart_env as se
from stewart_env.agents import pd_control_law, pd_control_params
from stewart_env.state import Reference

out = {}
env = gym.make("StewartPlatform-v0", task="tracking", max_episode_steps=50)
obs, _ = env.reset(seed=0)
steps, total = 0, 0.0
while True:
    obs, reward, terminated, truncated, _ = env.step(np.zeros(6))
    steps, total = steps + 1, total + reward
    if terminated or truncated:
        break
out["single"] = [steps, float(total), bool(np.isfinite(obs).all())]

envs = gym.make_vec("StewartPlatform-v0", num_envs=4, vectorization_mode="vector_entry_point", max_episode_steps=20)
obs, _ = envs.reset(seed=0)
total = np.zeros(4)
for _ in range(25):  # past the time limit: the autoreset too
    obs, reward, terminated, truncated, _ = envs.step(np.zeros((4, 6)))
    total += reward
out["vector"] = [bool(np.isfinite(total).all()), bool(np.isfinite(obs).all())]

params = se.load_platform("dasgupta1998")
model = se.make_dynamics("improved", params)
home = params.home_position
target = Reference(home + [0.0, 0.0, 0.01], np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
row = pd_control_params(params, target, gravity_compensation=True)
t, R, v, w = se.rollout(model, home, np.eye(3), np.zeros(3), np.zeros(3), dt=1e-3, steps=2000,
                        control_law=pd_control_law, control_params=row)
out["rollout"] = float(np.abs(t - target.position).max())
out["numba"] = "numba" in sys.modules and sys.modules["numba"] is not None
print("RESULT", json.dumps(out))
"""


def test_an_episode_of_each_env_and_a_pd_rollout_run_without_numba():
    done = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    line = next(x for x in done.stdout.splitlines() if x.startswith("RESULT "))
    out = json.loads(line[len("RESULT ") :])
    assert out["numba"] is False
    steps, total, finite = out["single"]
    assert 1 <= steps <= 50 and finite and abs(total) < 1e6
    assert out["vector"] == [True, True]
    # the PD law with gravity compensation brings the platform to a target 1 cm above home within
    # 2 s (its steady-state error is float rounding; 1e-6 m leaves room for the settling tail)
    assert out["rollout"] < 1e-6
