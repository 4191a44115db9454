"""Fuzzing the environment's keyword arguments, task options and actions (hypothesis).

Whatever it is given, the environment either refuses at once with a ValueError or TypeError whose
message names the offending argument, or runs: every observation and reward of a few steps and
of a second reset is finite.
"""

import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from stewart_env.envs import StewartPlatformEnv, StewartPlatformVectorEnv

# Values of every kind a caller might pass by mistake, at every scale.
ANY = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**400), max_value=10**400),
    st.booleans(),
    st.none(),
    st.text(max_size=4),
    st.lists(st.floats(-10.0, 10.0), max_size=4),
)
SMALL = st.floats(0.0, 2.0)
# control_dt is drawn first; physics_dt mostly divides it into a few substeps, so that an
# accepted environment steps quickly.
DT = st.one_of(st.floats(1e-4, 0.05), ANY)

ENV_KEYWORDS = {
    "actuator_tau": st.one_of(st.floats(0.0, 200.0), ANY),
    "observation_mode": st.one_of(st.sampled_from(["pose", "sensors", "camera"]), ANY),
    "normalize_observation": st.one_of(st.booleans(), ANY),
    "observation_noise": st.one_of(
        st.floats(0.0, 200.0),
        ANY,
        st.dictionaries(st.sampled_from(["position", "velocity", "altitude"]), ANY, max_size=2),
    ),
    "observation_delay": st.one_of(st.integers(0, 5), ANY),
    "error_integral": st.one_of(st.booleans(), ANY),
    "error_integral_limit": st.one_of(st.floats(1e-9, 10.0), ANY),
    "error_integral_band": st.one_of(SMALL, ANY),
    "position_reward_weight": st.one_of(SMALL, ANY),
    "position_reward_scale": st.one_of(SMALL, ANY),
    "velocity_cost_scale": st.one_of(SMALL, ANY),
    "ctrl_cost_weight": st.one_of(SMALL, ANY),
    "termination_cost": st.one_of(st.floats(0.0, 1e7), ANY),
    "width": st.one_of(st.integers(-5, 5000), ANY),
}
TASK_OPTIONS = {
    "setpoint": {
        "randomize": st.one_of(st.booleans(), ANY),
        "position_range": st.one_of(st.floats(0.0, 0.3), ANY),
        "angle_range": st.one_of(st.floats(0.0, 0.6), ANY),
        "target_position": st.one_of(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3), ANY),
    },
    "tracking": {
        "position_amplitude": st.one_of(st.floats(0.0, 0.3), ANY),
        "angle_amplitude": st.one_of(st.floats(0.0, 0.6), ANY),
        "frequency_range": st.one_of(st.tuples(st.floats(0.0, 2000.0), st.floats(0.0, 2000.0)), ANY),
        "preview": st.one_of(st.integers(0, 5), ANY),
        "preview_interval": st.one_of(SMALL, ANY),
    },
    "disturbance": {
        "sine_force": st.one_of(st.floats(0.0, 5e4), ANY),
        "frequency_range": st.one_of(st.tuples(st.floats(0.0, 2000.0), st.floats(0.0, 2000.0)), ANY),
        "n_impulses": st.one_of(st.integers(0, 5), ANY),
        "impulse_force": st.one_of(st.floats(0.0, 5e4), ANY),
        "impulse_duration": st.one_of(SMALL, ANY),
        "horizon": st.one_of(st.floats(0.0, 10.0), ANY),
    },
}
ACTION = st.one_of(
    st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=6, max_size=6),
    st.lists(st.floats(-1.5, 1.5), min_size=6, max_size=6),
    st.lists(st.integers(-(10**30), 10**30), min_size=6, max_size=6),
    st.lists(ANY, min_size=5, max_size=7),
    ANY,
)


@st.composite
def configurations(draw):
    task = draw(st.sampled_from(sorted(TASK_OPTIONS)))
    kwargs = draw(st.fixed_dictionaries({}, optional=ENV_KEYWORDS))
    options = draw(st.fixed_dictionaries({}, optional=TASK_OPTIONS[task]))
    control_dt = draw(DT)
    kwargs["control_dt"] = control_dt
    if isinstance(control_dt, float) and math.isfinite(control_dt) and control_dt > 0:
        kwargs["physics_dt"] = control_dt / draw(st.integers(1, 10))
    return {"task": task, "task_options": options, **kwargs}


def _names(kwargs) -> list[str]:
    return [k for k in kwargs if k != "task_options"] + list(kwargs["task_options"])


def _finite(obs, reward) -> None:
    assert np.all(np.isfinite(obs)), obs
    assert np.all(np.isfinite(reward)), reward


# No shrinking: a failing example is reported as drawn, at once (shrinking takes minutes here).
FUZZ = settings(
    deadline=None,
    database=None,
    derandomize=True,
    phases=[Phase.explicit, Phase.generate],
    suppress_health_check=[HealthCheck.too_slow],
)


@settings(FUZZ, max_examples=80)
@given(kwargs=configurations(), actions=st.lists(ACTION, min_size=1, max_size=4), vector=st.booleans())
def test_the_environment_refuses_clearly_or_stays_finite(kwargs, actions, vector):
    try:
        env = StewartPlatformVectorEnv(num_envs=2, **kwargs) if vector else StewartPlatformEnv(**kwargs)
    except (ValueError, TypeError) as error:
        message = str(error)
        assert any(re.search(rf"\b{re.escape(name)}\b", message) for name in _names(kwargs)), message
        return
    obs, _ = env.reset(seed=0)
    _finite(obs, 0.0)
    for action in actions:
        a = np.asarray(action, dtype=object)
        if vector and a.ndim == 1:
            action = [action, action]
        try:
            obs, reward, terminated, truncated, _ = env.step(action)
        except (ValueError, TypeError) as error:
            assert str(error).startswith("action: "), str(error)
            continue
        _finite(obs, reward)
        if not vector and (terminated or truncated):
            obs, _ = env.reset()
            _finite(obs, 0.0)
    obs, _ = env.reset(seed=1)
    _finite(obs, 0.0)
    env.close()


def test_the_fuzzer_reaches_both_outcomes():
    """The strategies are not so wild that every configuration is refused, nor so tame that none is."""
    outcomes = set()

    @settings(FUZZ, max_examples=40)
    @given(kwargs=configurations())
    def probe(kwargs):
        try:
            StewartPlatformEnv(**kwargs)
            outcomes.add("built")
        except (ValueError, TypeError):
            outcomes.add("refused")

    probe()
    assert outcomes == {"built", "refused"}


if __name__ == "__main__":
    pytest.main([__file__, "-q"])
