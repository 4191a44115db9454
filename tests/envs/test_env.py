"""Tests of the single environment StewartPlatform-v1 (stewart_env.envs.stewart_platform)."""

import dataclasses
import inspect
import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.envs import DEFAULTS, EnvConfig, StewartPlatformEnv, StewartPlatformVectorEnv, holding_action
from stewart_env.envs.config import arguments_table
from stewart_env.params import Limits, load_platform
from stewart_env.rotations import rotation_error, rpy_to_matrix

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
MODELS = ("improved", "classical", "improved_centroidal")
TASKS = ("setpoint", "tracking", "disturbance")
ROOT = Path(__file__).resolve().parents[2]


def make(**kwargs):
    return gym.make(ENV_ID, **kwargs)


def computed_torque_action(env, kp=100.0, kd=20.0):
    """A computed-torque controller on the true model: drives the errors to zero."""
    u = env.unwrapped
    s, tg = u.state, u.target
    eo = rotation_error(tg.rotation[None], s.rotation[None])[0][0]
    acc = kp * (tg.position - s.position) + kd * (tg.velocity - s.velocity)
    alpha = kp * eo + kd * (tg.angular_velocity - s.angular_velocity)
    forces = u.model.inverse(s.position, s.rotation, s.velocity, s.angular_velocity, acc, alpha)
    lo, hi = u.platform.limits.leg_force
    return (forces - 0.5 * (lo + hi)) / (0.5 * (hi - lo))


def rollout(env, actions, seed):
    """Observations, rewards, terminations and infos of a run with fixed actions (resets on end)."""
    obs, _ = env.reset(seed=seed)
    out = [obs]
    rewards, terms = [], []
    for a in actions:
        obs, r, terminated, truncated, _ = env.step(a)
        out.append(obs)
        rewards.append(r)
        terms.append(terminated)
        if terminated or truncated:
            out.append(env.reset()[0])
    return np.array(out), np.array(rewards), np.array(terms)


# -- conformance ----------------------------------------------------------------------------------


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("task", TASKS)
def test_gymnasium_check_env(model, task):
    env = make(model=model, task=task)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # Unbounded observation boxes are intended (as in Gymnasium's MuJoCo environments).
        warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value is")
        # skip_render_check: it would open a "human" window; rendering is checked below.
        gym_check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.extra("rl")
@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("task", TASKS)
def test_sb3_check_env(model, task):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = make(model=model, task=task)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_check_env(env.unwrapped, warn=True)


@pytest.mark.extra("rl")
@pytest.mark.parametrize(
    "kwargs",
    [
        {
            "task": "tracking",
            "randomization": {"mass": (0.9, 1.1)},
            "observation_noise": 0.01,
            "observation_delay": 2,
            "actuator_tau": 0.02,
        },
        {"task": "disturbance", "observation_mode": "sensors", "normalize_observation": False},
    ],
)
def test_check_env_with_the_options_on(kwargs):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = make(**kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value is")
        gym_check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(env.unwrapped, warn=True)


def test_render_rgb_array_passes_checker_and_gives_frames():
    env = StewartPlatformEnv(render_mode="rgb_array", width=160, height=120)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.filterwarnings("ignore", message=".*Box observation space (minimum|maximum) value is")
        warnings.filterwarnings("ignore", message=".*Not able to test alternative render modes")
        gym_check_env(env)
    env.reset(seed=0)
    first = env.render()
    assert first.shape == (120, 160, 3) and first.dtype == np.uint8
    env.step(-np.ones(6))
    for _ in range(5):
        env.step(-np.ones(6))
    assert not np.array_equal(first, env.render()), "the frame does not follow the state"
    assert env.metadata["render_fps"] == pytest.approx(100.0)  # 1 / 0.01 in floating point
    env.close()


def test_render_fps_follows_control_dt():
    env = make(control_dt=0.02, physics_dt=0.002)
    assert env.metadata["render_fps"] == pytest.approx(50.0)  # 1 / 0.02 in floating point


@pytest.mark.extra("rl")
def test_record_video(tmp_path):
    env = make(render_mode="rgb_array", width=96, height=96, max_episode_steps=8)
    folder = tmp_path / "videos"
    env = gym.wrappers.RecordVideo(env, str(folder), episode_trigger=lambda e: True, disable_logger=True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(holding_action(env))
        done = terminated or truncated
    env.close()
    videos = list(folder.glob("*.mp4"))
    assert videos and videos[0].stat().st_size > 0


# -- registration and documentation -------------------------------------------------------------------


def test_registration_spec():
    spec = gym.spec(ENV_ID)
    assert spec.max_episode_steps == 500
    assert spec.entry_point == "stewart_env.envs.stewart_platform:StewartPlatformEnv"
    assert spec.vector_entry_point == "stewart_env.envs.vector:StewartPlatformVectorEnv"
    env = make()
    assert isinstance(env.unwrapped, StewartPlatformEnv)
    limits, wrapper = [], env
    while isinstance(wrapper, gym.Wrapper):
        if isinstance(wrapper, gym.wrappers.TimeLimit):
            limits.append(wrapper._max_episode_steps)
        wrapper = wrapper.env
    assert limits == [500]  # exactly one TimeLimit, at the registered 500 steps


def test_import_stewart_env_registers():
    code = "import gymnasium, stewart_env; assert 'StewartPlatform-v1' in gymnasium.registry"
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_env_card_arguments_table_is_the_configuration_records():
    # the site's environment page is this docstring (tests/docs/test_site.py checks that it shows it)
    card = inspect.cleandoc(StewartPlatformEnv.__doc__)
    assert arguments_table() in card
    for name, default in DEFAULTS.items():
        shown = f'"{default}"' if isinstance(default, str) else repr(default)
        assert f"| `{name}` | `{shown}` |" in card, name


@pytest.mark.parametrize(
    "cls, own",
    [(StewartPlatformEnv, ()), (StewartPlatformVectorEnv, ("num_envs", "max_episode_steps", "autoreset_mode"))],
)
def test_signature_shows_every_argument_of_the_records_with_its_default(cls, own):
    params = inspect.signature(cls).parameters
    assert [name for name in params if name not in own] == list(DEFAULTS)
    for name, default in DEFAULTS.items():
        assert params[name].default == default and params[name].kind == params[name].KEYWORD_ONLY, name


def test_the_closed_form_plant_integrates_the_model_and_names_itself():
    from stewart_env.envs.plant import ClosedFormPlant, Plant

    env = make(model="classical+c1")
    plant = env.unwrapped.plant
    assert isinstance(plant, ClosedFormPlant) and isinstance(plant, Plant)
    assert plant.name == "closed_form" and plant.closure_error is None
    # classical has every switch on: the spelling with +c1 is the same model, named canonically
    assert plant.model is env.unwrapped.model and plant.model.name == "classical"
    env.reset(seed=0)
    assert "closure_error" not in env.step(np.zeros(6))[4]


@pytest.mark.parametrize(
    "plant, message",
    [
        ("bullet", r"^plant: expected one of 'closed_form', 'mujoco', got 'bullet'"),
        (3, r"^plant: expected one of .*got 3"),
    ],
)
def test_an_unknown_plant_is_refused_naming_the_argument(plant, message):
    with pytest.raises(ValueError, match=message):
        make(plant=plant)


def test_a_copy_keeps_the_generated_signature_and_steps_as_the_original():
    import copy
    import pickle

    env = make(actuator_tau=0.05, observation_noise=0.01, observation_delay=2, error_integral=True)
    env.reset(seed=1)
    copies = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    a = np.full(6, 0.1)
    steps = [e.step(a) for e in (env, *copies)]
    for obs, reward, *_ in steps[1:]:
        np.testing.assert_array_equal(obs, steps[0][0])
        assert reward == steps[0][1]
    assert inspect.signature(type(copies[1].unwrapped)) == inspect.signature(StewartPlatformEnv)


def test_configuration_records_are_frozen_and_checked_once():
    config = EnvConfig.of(control_dt=0.02, physics_dt=0.004, observation_noise={"position": 1})
    assert (config.physics.control_dt, config.physics.substeps) == (0.02, 5)
    assert config.observation.observation_noise == {"position": 1.0}
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.physics.control_dt = 0.1
    with pytest.raises(ValueError, match=r"^observation_delay: expected an integer in \[0, 1000\], got 2.5"):
        EnvConfig.of(observation_delay=2.5)
    with pytest.raises(ValueError, match=r"^EnvConfig.of\(\) got an unexpected keyword argument 'frameskip'"):
        EnvConfig.of(frameskip=4)


# -- actions ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "action, message",
    [
        (np.array([np.nan, 0, 0, 0, 0, 0]), "NaN"),
        (np.array([0, 0, np.inf, 0, 0, 0]), "inf"),
        (np.array([0, 0, 0, 0, 0, -np.inf]), "inf"),
        (np.zeros(5), "shape"),
        (np.zeros((1, 6)), "shape"),
        (np.zeros(7), "shape"),
        ("push", "action"),
    ],
)
def test_bad_action_raises(action, message):
    env = make()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(action)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("task", ["setpoint", "tracking"])
def test_a_refused_action_changes_nothing(dtype, task):
    """An action that is not finite, of either float width, raises check_action's error and leaves
    the episode as it was: the next steps are those of an env that never saw it."""
    env, twin = make(task=task), make(task=task)
    for e in (env, twin):
        e.reset(seed=3)
    a = np.full(6, 0.1, dtype=dtype)
    bad = a.copy()
    bad[4] = np.nan
    with pytest.raises(ValueError, match=r"^action: contains NaN at index \(4,\) \(1 non-finite value\(s\)\)"):
        env.step(bad)
    for _ in range(3):
        np.testing.assert_array_equal(env.step(a)[0], twin.step(a)[0])
    assert env.unwrapped.target.position.tobytes() == twin.unwrapped.target.position.tobytes()


def test_float32_float64_strided_and_listed_actions_step_alike():
    """The compiled step reads a float32 or float64 array as it is (float32 widened exactly); any
    other form is converted first: the same numbers give the same step."""
    a64 = np.linspace(-0.4, 0.6, 6)
    forms = [
        a64.astype(np.float32).astype(np.float64),
        a64.astype(np.float32),
        np.repeat(a64.astype(np.float32).astype(np.float64), 2)[::2],
        a64.astype(np.float32).tolist(),
    ]
    runs = []
    for form in forms:
        env = make()
        env.reset(seed=5)
        runs.append([env.step(form) for _ in range(3)])
    for run in runs[1:]:
        for (o, r, *_, info), (o0, r0, *_, info0) in zip(run, runs[0]):
            assert o.dtype == np.float32 and o.tobytes() == o0.tobytes() and r == r0
            assert {k: v.tobytes() for k, v in info.items()} == {k: v.tobytes() for k, v in info0.items()}


def test_action_maps_affinely_onto_force_range_and_clips():
    env = make()
    env.reset(seed=0)
    a = np.array([-1.0, -0.5, 0.0, 0.25, 1.0, 3.0])
    env.step(a)
    lo, hi = env.unwrapped.platform.limits.leg_force
    expected = 0.5 * (lo + hi) + np.clip(a, -1, 1) * 0.5 * (hi - lo)
    # Exact: the mapping is one multiply and one add in float64.
    np.testing.assert_array_equal(env.unwrapped.leg_forces, expected)
    assert env.unwrapped.leg_forces[5] == hi


def test_actuator_lag_is_the_exact_first_order_discretisation():
    tau, dt = 0.05, 0.01
    env = make(actuator_tau=tau, control_dt=dt)
    env.reset(seed=0)
    u = env.unwrapped
    start = u.leg_forces
    # At reset the actuators hold the start state: the inverse dynamics at zero acceleration.
    s = u.state
    z = np.zeros(3)
    np.testing.assert_allclose(
        start, u.model.inverse(s.position, s.rotation, s.velocity, s.angular_velocity, z, z), rtol=1e-12, atol=1e-9
    )  # same computation, rounding only
    command = np.full(6, 0.5)
    env.step(command)
    lo, hi = u.platform.limits.leg_force
    f_cmd = 0.5 * (lo + hi) + command * 0.5 * (hi - lo)
    expected = start + (1 - np.exp(-dt / tau)) * (f_cmd - start)
    np.testing.assert_allclose(u.leg_forces, expected, rtol=1e-12)  # rounding of exp only
    assert "leg_forces" in u.observation_layout


def test_control_dt_must_be_a_multiple_of_physics_dt():
    with pytest.raises(ValueError, match="control_dt.*whole multiple of physics_dt"):
        make(control_dt=0.01, physics_dt=0.003)
    make(control_dt=0.03, physics_dt=0.001)  # 30 substeps despite decimal rounding


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"model": "newtonian"}, "model"),
        ({"model": "improved+c9"}, "switch"),
        ({"platform": "no_such_platform"}, "unknown platform"),
        ({"platform": 3}, "platform"),
        ({"task": "juggling"}, "task"),
        ({"task_options": {"speed": 1}}, "task_options.*speed"),
        ({"task_options": {"position_range": [0.1, 0.1]}}, "position_range"),
        ({"control_dt": -0.01}, "control_dt"),
        ({"physics_dt": 0.0}, "physics_dt"),
        ({"actuator_tau": -1.0}, "actuator_tau"),
        ({"observation_mode": "camera"}, "observation_mode"),
        ({"observation_noise": -0.1}, "observation_noise"),
        ({"observation_noise": {"altitude": 0.1}}, "observation_noise.*altitude"),
        ({"observation_delay": 1.5}, "observation_delay"),
        ({"ctrl_cost_weight": -1.0}, "ctrl_cost_weight"),
        ({"position_reward_scale": 0.0}, "position_reward_scale"),
        ({"randomization": {"colour": (0.9, 1.1)}}, "randomization.*colour"),
        ({"randomization": {"platform.mass": (1.2, 0.8)}}, "platform.mass"),
        ({"width": 0}, "width"),
        ({"gravity": 1.0}, "gravity"),
    ],
)
def test_bad_arguments_name_the_argument(kwargs, message):
    with pytest.raises(ValueError, match=message):
        make(**kwargs)


def test_bad_render_mode_is_refused():
    with pytest.raises(ValueError, match="render_mode"):
        StewartPlatformEnv(render_mode="video")


# -- observation -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"task": "tracking"},
        {"task": "disturbance"},
        {"observation_mode": "sensors"},
        {"task": "tracking", "observation_mode": "sensors", "actuator_tau": 0.02},
        {"task": "tracking", "task_options": {"preview": 0}},
    ],
)
def test_observation_layout_covers_the_observation(kwargs):
    env = make(**kwargs)
    obs, _ = env.reset(seed=0)
    slices = sorted(env.unwrapped.observation_layout.values(), key=lambda s: s.start)
    assert slices[0].start == 0
    for a, b in zip(slices, slices[1:]):
        assert a.stop == b.start, "gap or overlap in the layout"
    assert slices[-1].stop == obs.shape[0] == env.observation_space.shape[0]
    assert obs.dtype == np.float32


def test_decoded_observation_is_the_state_and_the_errors():
    env = make(task="tracking")
    env.reset(seed=3)
    for _ in range(5):
        obs, *_ = env.step(holding_action(env))
    u = env.unwrapped
    d = u.decode_observation(obs)
    s, tg = u.state, u.target
    tol = dict(rtol=1e-6, atol=1e-6)  # float32 observation
    np.testing.assert_allclose(d["position"], s.position, **tol)
    np.testing.assert_allclose(d["orientation"], np.concatenate([s.rotation[:, 0], s.rotation[:, 1]]), **tol)
    np.testing.assert_allclose(d["velocity"], s.velocity, **tol)
    np.testing.assert_allclose(d["angular_velocity"], s.angular_velocity, **tol)
    np.testing.assert_allclose(d["position_error"], tg.position - s.position, **tol)
    np.testing.assert_allclose(d["orientation_error"], rotation_error(tg.rotation[None], s.rotation[None])[0][0], **tol)
    np.testing.assert_allclose(d["velocity_error"], tg.velocity - s.velocity, **tol)


def test_normalised_observation_is_order_one_inside_the_limits():
    env = make()
    p = env.unwrapped.platform
    env.reset(seed=0)
    env.unwrapped.set_state(p.limits.position_max, np.eye(3))
    obs, *_ = env.step(holding_action(env, p.limits.position_max))
    position = obs[env.unwrapped.observation_layout["position"]]
    # At the workspace corner the normalised position is +1 on every axis, up to one step's motion.
    np.testing.assert_allclose(position, 1.0, atol=0.05)
    raw = make(normalize_observation=False)
    raw.reset(seed=0)
    raw_obs, *_ = raw.step(holding_action(raw))
    np.testing.assert_allclose(raw_obs[:3], raw.unwrapped.state.position, rtol=1e-6)  # SI units, float32


def test_sensor_observation_gives_leg_lengths_and_rates():
    env = make(observation_mode="sensors", normalize_observation=False)
    env.reset(seed=0)
    obs, *_ = env.step(holding_action(env))
    layout = env.unwrapped.observation_layout
    assert set(layout) == {"leg_lengths", "leg_rates", "position_error", "orientation_error"}
    np.testing.assert_allclose(obs[layout["leg_lengths"]], env.unwrapped.leg_lengths, rtol=1e-6)  # float32


def test_observation_noise_has_the_requested_std_and_uses_np_random():
    clean, noisy = make(), make(observation_noise={"velocity": 0.1})
    layout = clean.unwrapped.observation_layout
    diffs = []
    for seed in range(40):
        clean.reset(seed=seed)
        noisy.reset(seed=seed)
        a = holding_action(clean)
        for _ in range(5):
            c, *_ = clean.step(a)
            n, *_ = noisy.step(a)
            diffs.append(n - c)
    diffs = np.array(diffs)
    # Noise only where asked (the clean and noisy runs share the seed, so the states are equal).
    assert np.all(diffs[:, layout["position"]] == 0)
    # 600 samples: the sample std of N(0, 0.1) lies within 10 % with probability > 0.99.
    assert np.std(diffs[:, layout["velocity"]]) == pytest.approx(0.1, rel=0.1)
    a1, _ = noisy.reset(seed=7)
    a2, _ = noisy.reset(seed=7)
    np.testing.assert_array_equal(a1, a2)


def test_observation_delay_returns_the_observation_k_steps_ago():
    k = 3
    direct, delayed = make(), make(observation_delay=k)
    o_direct = [direct.reset(seed=5)[0]]
    o_delayed = [delayed.reset(seed=5)[0]]
    a = holding_action(direct)
    for _ in range(10):
        o_direct.append(direct.step(a)[0])
        o_delayed.append(delayed.step(a)[0])
    for n in range(len(o_delayed)):
        np.testing.assert_array_equal(o_delayed[n], o_direct[max(n - k, 0)])


# -- determinism --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"task": "tracking", "observation_noise": 0.01, "randomization": {"mass": (0.8, 1.2), "damping": (0.5, 2.0)}},
        {"task": "disturbance", "actuator_tau": 0.03, "observation_delay": 2},
    ],
)
def test_same_seed_gives_bit_identical_trajectories(kwargs):
    actions = np.random.default_rng(0).uniform(-0.2, 0.4, (80, 6))
    a = rollout(make(**kwargs), actions, seed=11)
    b = rollout(make(**kwargs), actions, seed=11)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    c = rollout(make(**kwargs), actions, seed=12)
    assert not np.array_equal(a[0][:10], c[0][:10]), "another seed gives the same episode"


# -- reward -----------------------------------------------------------------------------------------------------


def test_reward_is_the_sum_of_its_terms_and_matches_the_formula():
    weights = dict(
        position_reward_weight=0.7,
        position_reward_scale=0.02,
        orientation_reward_weight=0.3,
        orientation_reward_scale=0.2,
        velocity_cost_weight=0.2,
        velocity_cost_scale=0.4,
        angular_velocity_cost_scale=2.0,
        ctrl_cost_weight=0.3,
        termination_cost=5.0,
    )
    env = make(task="tracking", task_options=weights)
    env.reset(seed=2)
    rng = np.random.default_rng(1)
    for _ in range(20):
        a = holding_action(env) + rng.uniform(-0.05, 0.05, 6)
        _, reward, terminated, _, info = env.step(a)
        terms = {k: v for k, v in info.items() if k.startswith("reward_")}
        assert set(terms) == {
            "reward_position",
            "reward_orientation",
            "reward_velocity",
            "reward_control",
            "reward_termination",
        }
        assert reward == pytest.approx(sum(terms.values()), abs=1e-12)  # the same five floats, summed
        s, tg = env.unwrapped.state, env.unwrapped.target
        ep = np.linalg.norm(tg.position - s.position)
        eo = np.linalg.norm(rotation_error(tg.rotation[None], s.rotation[None])[0])
        ev = np.linalg.norm(tg.velocity - s.velocity)
        ew = np.linalg.norm(tg.angular_velocity - s.angular_velocity)
        expected = (
            0.7 * np.exp(-ep / 0.02)
            + 0.3 * np.exp(-eo / 0.2)
            - 0.2 * (1 - np.exp(-(ev / 0.4 + ew / 2.0)))
            - 0.3 * np.mean(np.clip(a, -1, 1) ** 2)
            - 5.0 * terminated
        )
        assert reward == pytest.approx(expected, abs=1e-9)  # same formula, other rounding order
        if terminated:
            break


@pytest.mark.parametrize(
    "task, position_scale, orientation_scale",
    [("setpoint", 0.05, 0.1), ("hold", 0.05, 0.1), ("tracking", 0.01, 0.02), ("disturbance", 0.01, 0.02)],
)
def test_reward_scales_default_per_task_and_give_way_to_options(task, position_scale, orientation_scale):
    env = make(task=task)
    env.reset(seed=3)
    u = env.unwrapped
    offset = np.array([0.002, 0.0, 0.0])  # the default 2 mm success band
    u.set_state(u.target.position - offset, u.target.rotation)
    _, _, _, _, info = env.step(holding_action(env))
    error = np.linalg.norm(u.target.position - u.state.position)
    # The position term is 0.5 exp(-|e_p| / scale), of the error after the step.
    # the same formula on the same floats, up to the order of the norm's sum
    assert info["reward_position"] == pytest.approx(0.5 * np.exp(-error / position_scale), rel=1e-12)
    assert env.unwrapped.task.weights.orientation_reward_scale == orientation_scale
    mine = make(task=task, task_options={"position_reward_scale": 0.2, "orientation_reward_scale": 0.3}).unwrapped
    assert (mine.task.weights.position_reward_scale, mine.task.weights.orientation_reward_scale) == (0.2, 0.3)


def test_reward_weights_given_as_environment_arguments_are_refused_pointing_to_task_options():
    with pytest.raises(
        TypeError,
        match=r"unexpected keyword argument 'termination_cost'; the reward weights are "
        r"options of the task: pass task_options=\{'termination_cost': \.\.\.\}",
    ):
        make(termination_cost=50.0)


def test_reward_is_bounded_and_best_on_target():
    env = make(task="setpoint", task_options={"randomize": False})
    env.reset(seed=0)
    u = env.unwrapped
    tg = u.target
    u.set_state(tg.position, tg.rotation)
    a = holding_action(env, tg.position, tg.rotation)
    _, reward, terminated, _, info = env.step(a)
    assert not terminated
    # Holding forces keep the platform on target to within ~1e-9 m over one step.
    assert info["reward_position"] == pytest.approx(0.5, abs=1e-6)
    assert info["reward_orientation"] == pytest.approx(0.5, abs=1e-6)
    assert reward == pytest.approx(1.0 - 0.1 * np.mean(a**2), abs=1e-5)
    rng = np.random.default_rng(0)
    for _ in range(3):
        env.reset(seed=int(rng.integers(1 << 30)))
        done = False
        while not done:
            _, reward, terminated, truncated, _ = env.step(rng.uniform(-3, 3, 6))
            assert -10.2 <= reward <= 1.0
            done = terminated or truncated


def test_computed_torque_control_earns_near_maximal_return():
    env = make(task="setpoint", model="classical")
    env.reset(seed=4)
    total, steps = 0.0, 0
    while True:
        _, reward, terminated, truncated, info = env.step(computed_torque_action(env))
        total += reward
        steps += 1
        if terminated or truncated:
            break
    assert truncated and not terminated and steps == 500
    assert info["termination"] == 0
    # Settles within ~0.5 s; afterwards every step earns ~1 (at most 1 by construction).
    assert total > 400


# -- termination ------------------------------------------------------------------------------------------------


def _step_from(env, position, rpy=(0.0, 0.0, 0.0), action=None):
    env.reset(seed=0)
    R = rpy_to_matrix(np.array(rpy))
    env.unwrapped.set_state(np.array(position, dtype=float), R)
    a = holding_action(env, np.array(position, dtype=float), R) if action is None else action
    return env.step(a)


def test_termination_workspace_box_and_angle():
    env = make()
    p = env.unwrapped.platform
    _, _, terminated, _, info = _step_from(env, [0.0, 0.0, 0.245])  # 5 mm below the box, legs in stroke
    assert terminated and env.unwrapped.termination_reasons[info["termination"]] == "workspace"
    _, _, terminated, _, info = _step_from(env, p.home_position, rpy=(0.0, 0.0, 0.52))  # yaw past 0.5 rad
    assert terminated and env.unwrapped.termination_reasons[info["termination"]] == "workspace"
    _, _, terminated, _, info = _step_from(env, p.home_position, rpy=(0.0, 0.0, 0.45))
    assert not terminated and info["termination"] == 0


def test_termination_leg_stroke():
    nominal = load_platform("dasgupta1998")
    lim = nominal.limits
    narrow = Limits(
        leg_length=(1.25, 1.27),
        leg_force=lim.leg_force,
        position_min=lim.position_min,
        position_max=lim.position_max,
        max_angle=lim.max_angle,
        max_condition=lim.max_condition,
    )
    env = make(platform=nominal.replace(limits=narrow), task="disturbance")  # starts at home
    # 3 cm below home (inside the box): the legs, 28 deg above the horizontal, get ~14 mm shorter.
    _, _, terminated, _, info = _step_from(env, [0.0, 0.0, 0.37])
    assert terminated and env.unwrapped.termination_reasons[info["termination"]] == "leg_stroke"


def test_termination_singularity():
    nominal = load_platform("dasgupta1998")
    lim = nominal.limits
    # The home pose's condition number is 3.62 and the paper's case pose's 3.81: a bound between
    # them makes the case pose "singular".
    strict = Limits(
        leg_length=lim.leg_length,
        leg_force=lim.leg_force,
        position_min=lim.position_min,
        position_max=lim.position_max,
        max_angle=lim.max_angle,
        max_condition=3.7,
    )
    env = make(platform=nominal.replace(limits=strict), task="disturbance")  # starts at home
    _, _, terminated, _, info = _step_from(env, [0.1, 0.0, 0.4], rpy=(0.0, 0.0, -0.2))
    assert terminated and env.unwrapped.termination_reasons[info["termination"]] == "singularity"


def test_termination_non_finite_keeps_the_last_finite_state():
    env = make()
    p = env.unwrapped.platform
    # Leg 0 vertical, i.e. along its Hooke axis: the U-joint frame is undefined there.
    position = p.base_joints[0] - p.platform_joints[0] + np.array([0.0, 0.0, 1.2])
    obs, reward, terminated, _, info = _step_from(env, position, action=np.zeros(6))
    assert terminated and env.unwrapped.termination_reasons[info["termination"]] == "non_finite"
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)
    np.testing.assert_array_equal(env.unwrapped.state.position, position)


def test_set_state_checks_its_arguments():
    env = make()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="position"):
        env.unwrapped.set_state(np.zeros(2), np.eye(3))
    with pytest.raises(ValueError, match="rotation"):
        env.unwrapped.set_state(np.zeros(3), 2 * np.eye(3))
    with pytest.raises(ValueError, match="velocity"):
        env.unwrapped.set_state(np.zeros(3), np.eye(3), velocity=[np.nan, 0, 0])


def test_truncation_only_by_the_time_limit():
    env = make(max_episode_steps=5)
    env.reset(seed=0)
    for n in range(5):
        _, _, terminated, truncated, _ = env.step(computed_torque_action(env))
        assert not terminated
        assert truncated == (n == 4)


def test_reset_rejects_unknown_options():
    env = make()
    with pytest.raises(ValueError, match="option"):
        env.reset(seed=0, options={"start": 1})


def test_bench_env_reports_rates():
    from stewart_env.benchmarks import bench_env

    result = bench_env(n_vector=4, seconds=0.05)
    # one vector step is n_vector platform steps: the two rates of one run agree exactly
    assert result["vector_platform_steps_per_s"] == pytest.approx(4 * result["vector_steps_per_s"], rel=1e-12)
    # the settings measured are the defaults
    assert (result["n_vector"], result["control_dt"], result["model"], result["task"]) == (
        4,
        0.01,
        "improved",
        "setpoint",
    )


@pytest.mark.parametrize("task", TASKS)
def test_motion_simulator_from_its_yaml_path(task):
    path = ROOT / "configs" / "platforms" / "motion_simulator.yaml"
    env = make(platform=str(path), task=task, max_episode_steps=100)
    assert env.unwrapped.platform.name == "motion_simulator"
    env.reset(seed=0)
    for _ in range(100):
        obs, reward, terminated, truncated, _ = env.step(computed_torque_action(env))
        assert not terminated
    assert truncated
    # The controller does not see the disturbance (up to the platform's weight): within 5 cm of
    # a +-0.6 m workspace is control, not luck; the scaled observation stays of order one.
    d = env.unwrapped.decode_observation(obs)
    assert np.linalg.norm(d["position_error"]) < 0.05
    assert np.all(np.abs(obs) < 5)
