"""The conventions outside RL libraries rely on: exact copies, numeric infos, Python-like keyword
errors, no step before reset, Gymnasium's vector API, headless human mode, and no NaN or inf
leaving the environment (stewart_env.envs, stewart_env.validation)."""

import copy
import datetime
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode

import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.envs import StewartPlatformEnv, StewartPlatformVectorEnv
from stewart_env.tasks import SetpointTask
from stewart_env.validation import ArgumentError

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
# Every option that keeps state between steps: noise Generators, the delay ring, the actuator lag,
# the error integral, per-episode parameters.
STATEFUL = {
    "task": "tracking",
    "observation_noise": 0.02,
    "observation_delay": 2,
    "actuator_tau": 0.02,
    "error_integral": True,
    "randomization": {"platform.mass": (0.8, 1.2)},
}


def actions(n_steps, shape, seed=0):
    """Actions around the holding force (a ~ 0.1): episodes last tens of steps, so runs cross resets."""
    return np.random.default_rng(seed).uniform(-0.3, 0.5, (n_steps, *shape))


def assert_same(a, b, where="info"):
    """Bit-identical nested outputs: arrays (any dtype), dicts, tuples, scalars."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            assert_same(a[k], b[k], f"{where}[{k!r}]")
    elif isinstance(a, (list, tuple)) or (isinstance(a, np.ndarray) and a.dtype == object):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same(x, y, f"{where}[{i}]")
    else:
        np.testing.assert_array_equal(a, b, err_msg=where)
        assert type(a) is type(b), where


def numeric_only(value, where="info"):
    """Every leaf is a numpy number or a numeric numpy array: no None, str or object (torchrl's
    info readers turn each into a tensor)."""
    if isinstance(value, dict):
        for k, v in value.items():
            numeric_only(v, f"{where}[{k!r}]")
    else:
        assert isinstance(value, (np.ndarray, np.generic)) and value.dtype.kind in "biuf", f"{where}: {value!r}"


# -- exact copies ------------------------------------------------------------------------------------------


def _single():
    return gym.make(ENV_ID, **STATEFUL)


def _vector():
    return gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", max_episode_steps=20, **STATEFUL)


def _sb3():
    pytest.importorskip("stable_baselines3")
    from stewart_env.envs import StewartPlatformSB3VecEnv

    return StewartPlatformSB3VecEnv(num_envs=3, max_episode_steps=20, **STATEFUL)


def _run_single(env, acts):
    out = []
    for a in acts:
        step = env.step(a)
        out.append(step)
        if step[2] or step[3]:
            out.append(env.reset())
    return out


def _run_vector(env, acts):
    return [env.step(a) for a in acts]


def _run_sb3(env, acts):
    out = []
    for a in acts:
        env.step_async(a)
        out.append(env.step_wait())
    return out


def _reset(env, kind):
    if kind == "sb3":
        env.seed(3)
        return env.reset()
    return env.reset(seed=3)


KINDS = {
    "single": (_single, _run_single, (6,)),
    "vector": (_vector, _run_vector, (3, 6)),
    "sb3": (_sb3, _run_sb3, (3, 6)),
}
COPIES = {"deepcopy": copy.deepcopy, "pickle": lambda env: pickle.loads(pickle.dumps(env))}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("how", COPIES)
@pytest.mark.parametrize("when", ["fresh", "mid-episode"])
def test_a_copy_continues_bit_identically(kind, how, when):
    make, run, shape = KINDS[kind]
    env = make()
    if when == "fresh":
        twin = COPIES[how](env)
        assert_same(_reset(env, kind), _reset(twin, kind), "reset")
    else:
        _reset(env, kind)
        run(env, actions(13, shape, seed=1))  # crosses at least one reset of some row
        twin = COPIES[how](env)
    acts = actions(60, shape, seed=2)
    assert_same(run(env, acts), run(twin, acts), "steps")


def test_a_copy_renders_with_its_own_renderer():
    env = gym.make(ENV_ID, render_mode="rgb_array", width=64, height=64)
    env.reset(seed=0)
    env.render()
    twin = copy.deepcopy(env)
    assert twin.unwrapped._renderer is None  # rebuilt on first render
    np.testing.assert_array_equal(twin.render(), env.render())
    assert twin.unwrapped._renderer is not env.unwrapped._renderer


# -- infos -----------------------------------------------------------------------------------------------


def test_single_infos_are_plain_numpy_values():
    env = gym.make(ENV_ID, randomization={"platform.mass": (0.8, 1.2)})
    _, info = env.reset(seed=0)
    numeric_only(info)
    assert all(type(v) is np.float64 for v in info["randomization"].values())
    assert env.unwrapped.episode_params == env.unwrapped.model.params[0]
    _, reward, _, _, info = env.step(np.full(6, 0.1))
    numeric_only(info)
    assert type(info["termination"]) is np.int64 and info["termination"] == 0
    assert type(info["is_success"]) is np.bool_
    assert {type(v) for k, v in info.items() if k not in ("termination", "is_success")} == {np.float64}
    assert isinstance(reward, float)


def test_vector_infos_are_numeric_arrays_with_termination_codes():
    envs = gym.make_vec(
        ENV_ID,
        num_envs=3,
        vectorization_mode="vector_entry_point",
        max_episode_steps=50,
        randomization={"platform.mass": (0.8, 1.2)},
    )
    _, infos = envs.reset(seed=0)
    numeric_only(infos)
    assert infos["randomization"]["platform.mass"].dtype == np.float64
    terminations = []
    a = np.full((3, 6), 0.09)  # about the holding force
    a[0] = -1.0  # row 0 falls out of the workspace
    for _ in range(40):
        _, _, terminated, truncated, infos = envs.step(a)
        numeric_only(infos)
        assert infos["termination"].dtype == np.int64
        assert np.all((infos["termination"] != 0) == terminated)
        terminations += [envs.unwrapped.termination_reasons[c] for c in infos["termination"]]
    assert "" in terminations and set(terminations) > {""}  # both kinds of row were seen


# -- construction errors -------------------------------------------------------------------------------------


def _sb3_class():
    pytest.importorskip("stable_baselines3")
    from stewart_env.envs import StewartPlatformSB3VecEnv

    return StewartPlatformSB3VecEnv


@pytest.mark.parametrize(
    "make, owner",
    [
        (lambda **kw: StewartPlatformEnv(**kw), "StewartPlatformEnv"),
        (lambda **kw: gym.make(ENV_ID, **kw), "StewartPlatformEnv"),
        (lambda **kw: StewartPlatformVectorEnv(num_envs=2, **kw), "StewartPlatformVectorEnv"),
        (lambda **kw: _sb3_class()(num_envs=2, **kw), "StewartPlatformSB3VecEnv"),
    ],
)
def test_an_unknown_keyword_is_a_type_error_worded_as_pythons(make, owner):
    with pytest.raises(TypeError) as caught:
        make(frameskip=4)
    assert isinstance(caught.value, ValueError)
    assert str(caught.value).startswith(f"{owner}.__init__() got an unexpected keyword argument 'frameskip'")


def test_step_before_reset_names_reset():
    envs = [StewartPlatformEnv(), gym.make(ENV_ID), StewartPlatformVectorEnv(num_envs=2)]
    for env in envs:
        with pytest.raises(ResetNeeded, match=r"reset\(\)"):
            env.step(np.zeros(env.action_space.shape))
    partial = StewartPlatformVectorEnv(num_envs=2, autoreset_mode=AutoresetMode.DISABLED)
    partial.reset(seed=0, options={"reset_mask": np.array([True, False])})
    with pytest.raises(ResetNeeded, match=r"reset\(\)"):  # row 1 was never reset
        partial.step(np.zeros((2, 6)))


def test_sb3_step_before_reset_names_reset():
    venv = _sb3_class()(num_envs=2)
    with pytest.raises(ResetNeeded, match=r"reset\(\)"):
        venv.step(np.zeros((2, 6)))


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"control_dt": 1e10, "physics_dt": 1e-10}, "control_dt"),
        ({"control_dt": 1.0, "physics_dt": 1e-7}, "physics_dt"),  # 10**7 substeps
        ({"observation_delay": 10**9}, "observation_delay"),
        ({"observation_noise": 1e300}, "observation_noise"),
        ({"observation_noise": {"position": float("nan")}}, "observation_noise"),
        ({"error_integral": True, "error_integral_limit": 1e-320}, "error_integral_limit"),
        ({"error_integral_band": float("inf")}, "error_integral_band"),
        ({"actuator_tau": 1e300}, "actuator_tau"),
        ({"task_options": {"position_reward_weight": 1e300}}, r"task_options\['position_reward_weight'\]"),
        (
            {"task": "tracking", "task_options": {"velocity_cost_scale": float("nan")}},
            r"task_options\['velocity_cost_scale'\]",
        ),
        ({"task": "hold", "task_options": {"max_payload": 1e300}}, "max_payload"),
        ({"width": 10**6}, "width"),
        ({"height": True}, "height"),
        ({"normalize_observation": 1}, "normalize_observation"),
        ({"task": "tracking", "task_options": {"frequency_range": (1e300, 1e300)}}, "frequency_range"),
        ({"task": "tracking", "task_options": {"position_amplitude": 1e300}}, "position_amplitude"),
        ({"task": "tracking", "task_options": {"preview": 10**9}}, "preview"),
        ({"task": "disturbance", "task_options": {"n_impulses": 10**9}}, "n_impulses"),
        ({"task": "disturbance", "task_options": {"sine_force": 1e300}}, "sine_force"),
        ({"task": "disturbance", "task_options": {"horizon": 1e300}}, "horizon"),
        ({"task_options": {"position_range": 10.0}}, "position_range"),
        ({"task_options": {"randomize": "no"}}, "randomize"),
    ],
)
def test_every_argument_has_a_finite_range(kwargs, name):
    with pytest.raises(ValueError, match=name):
        StewartPlatformEnv(**kwargs)


@pytest.mark.parametrize(
    "action",
    [
        np.ones(6, dtype=bool),
        [True] * 6,
        np.zeros(6, dtype=complex),
        np.array(["0.1"] * 6),
        b"012345",
        np.array([datetime.timedelta(seconds=1)] * 6),
        np.array([np.datetime64("2024-01-01")] * 6),
        np.array([0.1] * 6, dtype=object),
        [10**400] * 6,
    ],
)
def test_actions_must_be_real_numbers(action):
    env = StewartPlatformEnv()
    env.reset(seed=0)
    with pytest.raises(ArgumentError, match="^action: "):
        env.step(action)


@pytest.mark.parametrize("velocity", [np.ones(3, dtype=bool), np.ones(3, dtype=complex), ["1", "2", "3"]])
def test_set_state_takes_real_numbers_only(velocity):
    env = StewartPlatformEnv()
    env.reset(seed=0)
    s = env.state
    with pytest.raises(ArgumentError, match="^velocity: "):
        env.set_state(s.position, s.rotation, velocity=velocity)


@pytest.mark.parametrize(
    "action",
    [
        [0, 0, 0, 0, 0, 1],
        np.zeros(6, dtype=np.int8),
        np.zeros(6, dtype=np.uint64),
        np.full(6, 0.1, dtype=np.float16),
        np.full(6, 0.1, dtype=np.longdouble),
    ],
)
def test_integer_and_float_actions_of_any_width_are_accepted(action):
    env = StewartPlatformEnv()
    env.reset(seed=0)
    obs, *_ = env.step(action)
    assert np.all(np.isfinite(obs))


# -- the vector API ------------------------------------------------------------------------------------------


def test_vector_get_attr_call_and_set_attr_follow_sync_vector_env():
    envs = gym.make_vec(
        ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", render_mode="rgb_array", width=48, height=48
    )
    sync = gym.make_vec(ENV_ID, num_envs=3, vectorization_mode="sync", render_mode="rgb_array", width=48, height=48)
    for venv in (envs, sync):
        venv.reset(seed=5)
    for name in ("dt", "render_mode", "observation_space", "action_space"):
        assert envs.get_attr(name) == sync.get_attr(name), name
    states = envs.get_attr("state")
    for i, state in enumerate(sync.get_attr("state")):
        assert_same(tuple(states[i]), tuple(state), f"state of row {i}")
    frames = envs.call("render")
    assert len(frames) == 3
    for frame, reference in zip(frames, sync.call("render")):
        np.testing.assert_array_equal(frame, reference)  # row i draws as sub-environment i
    rendered = envs.render()
    for i in range(3):
        np.testing.assert_array_equal(rendered[i], frames[i])

    gens = [np.random.default_rng(i) for i in range(3)]
    envs.set_attr("np_random", gens)
    assert all(g is h for g, h in zip(envs.get_attr("np_random"), gens))
    envs.set_attr("max_episode_steps", 7)  # one value: shared by the batch
    assert envs.unwrapped.max_episode_steps == 7
    with pytest.raises(ValueError, match="max_episode_steps.*shared"):
        envs.set_attr("max_episode_steps", [7, 8, 9])
    with pytest.raises(ValueError, match="num_envs=3"):
        envs.set_attr("np_random", gens[:2])
    with pytest.raises(AttributeError, match="reset_mask"):  # not N resets of the whole batch
        envs.call("reset")


def test_vector_record_video(tmp_path):
    pytest.importorskip("moviepy")
    envs = gym.make_vec(
        ENV_ID,
        num_envs=2,
        vectorization_mode="vector_entry_point",
        render_mode="rgb_array",
        width=64,
        height=64,
        max_episode_steps=5,
    )
    envs = gym.wrappers.vector.RecordVideo(
        envs, str(tmp_path), step_trigger=lambda step: step == 0, video_length=4, name_prefix="rows"
    )
    envs.reset(seed=0)
    for a in actions(6, (2, 6)):
        envs.step(a)
    envs.close()
    videos = list(tmp_path.glob("rows*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 0


# -- headless human mode ---------------------------------------------------------------------------------


def test_check_env_passes_headless(monkeypatch):
    """check_env makes the human-mode environment too: without a display it warns and draws nothing."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    check_env(gym.make(ENV_ID).unwrapped)
    env = gym.make(ENV_ID, render_mode="human")
    env.reset(seed=0)
    assert env.render() is None
    env.close()


# -- nothing non-finite leaves the environment ---------------------------------------------------------------


def test_an_overflowing_state_ends_the_episode_with_a_finite_observation():
    env = StewartPlatformEnv(actuator_tau=0.02, error_integral=True)
    env.reset(seed=0)
    s = env.state
    env.set_state(s.position, s.rotation, velocity=[1e300, 0.0, 0.0])
    obs, reward, terminated, _, info = env.step(np.zeros(6))
    assert terminated and env.termination_reasons[info["termination"]] == "non_finite"
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)
    assert reward == info["reward_termination"] + sum(
        v for k, v in info.items() if k.startswith("reward_") and k != "reward_termination"
    )


def test_a_vector_row_that_overflows_ends_alone():
    envs = StewartPlatformVectorEnv(num_envs=3)
    envs.reset(seed=0)
    envs.unwrapped._core.velocity[1] = 1e39  # finite in float64, inf in float32
    obs, reward, terminated, _, infos = envs.step(np.full((3, 6), 0.1))
    assert terminated.tolist() == [False, True, False]
    assert [envs.termination_reasons[c] for c in infos["termination"]] == ["", "non_finite", ""]
    assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))


class _RunawayStart(SetpointTask):
    """A start velocity whose normalised observation overflows float32."""

    def initialize_episode(self, rng):
        start, episode = super().initialize_episode(rng)
        return start._replace(velocity=np.array([1e39, 0.0, 0.0])), episode


def test_a_non_finite_start_gives_a_finite_observation_and_ends_at_the_first_step():
    env = StewartPlatformEnv(task=_RunawayStart)
    obs, _ = env.reset(seed=0)
    assert np.all(np.isfinite(obs))
    obs, reward, terminated, _, info = env.step(np.zeros(6))
    assert terminated and env.termination_reasons[info["termination"]] == "non_finite"
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)


def test_set_state_refuses_what_the_physics_api_refuses():
    import stewart_env as se

    env = gym.make("StewartPlatform-v1").unwrapped
    env.reset(seed=0)
    model = env.model
    t, v = np.array([0.0, 0.0, 0.4]), np.zeros(3)
    for R in (2.0 * np.eye(3), np.diag([1.0, 1.0, -1.0])):  # scaled, and a reflection
        with pytest.raises(ValueError, match="rotation: not a rotation matrix"):
            env.set_state(t, R)
        with pytest.raises(ValueError, match="not a rotation matrix"):
            model.forward(t, R, v, v, np.zeros(6))
    env.set_state(t, se.rpy_to_matrix([0.0, 0.0, 0.1]))  # a rotation is accepted by both


@pytest.mark.parametrize(
    "action", [[10**400] * 6, [10**5000] * 6, "abc" * 10_000], ids=["huge-ints", "ints-beyond-repr", "long-string"]
)
def test_errors_quote_a_hostile_value_briefly(action):
    env = gym.make("StewartPlatform-v1")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="^action: ") as err:
        env.step(action)
    assert len(str(err.value)) < 300  # an excerpt of the value, never the whole of it
