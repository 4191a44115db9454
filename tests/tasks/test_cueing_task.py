"""The cueing task through the environments: observation, perception, reward, episodes, copies, options."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import stewart_env.registration  # noqa: F401  (registers StewartPlatform-v1)
from stewart_env.errors import UsageError
from stewart_env.rotations import rpy_to_matrix
from stewart_env.tasks import TASKS, make_task
from stewart_env.tasks.cueing.head import head_motion
from stewart_env.tasks.cueing.motions import EVALUATION_SEEDS, TRAINING_SEED_BOUND, make_motion, write_motion
from stewart_env.tasks.cueing.task import CueingTask
from stewart_env.tasks.cueing.vestibular import Otolith, SemicircularCanal

pytestmark = pytest.mark.env

ENV_ID = "StewartPlatform-v1"
# long enough for any motion: the task ends the episode at the motion's end
STEPS = 100_000
MODES = ["force", "leg_length", "pose"]


def make(**kwargs):
    kwargs.setdefault("task", "cueing")
    return gym.make(ENV_ID, max_episode_steps=STEPS, **kwargs)


def holding_pose_action():
    """In pose mode the action 0 commands the workspace box's centre, home for the shipped platforms."""
    return np.zeros(6, dtype=np.float32)


def test_the_task_is_registered():
    assert TASKS["cueing"] is CueingTask


@pytest.mark.parametrize("mode", MODES)
def test_every_action_mode_runs_and_reports_the_signals(mode):
    env = make(action_mode=mode)
    obs, _ = env.reset(seed=3)
    layout = env.unwrapped.observation_layout
    for name in ("vehicle_specific_force", "vehicle_angular_velocity", "motion_time_left"):
        assert name in layout
    task = env.unwrapped.task
    motion = task.motion_of(int(task_episode(env)["motion"]), int(task_episode(env)["seed"]))
    decoded = env.unwrapped.decode_observation(obs)
    # the observation holds the vehicle's first sample (normalised by |g| and 1 rad/s, float32)
    np.testing.assert_allclose(decoded["vehicle_specific_force"], motion[0, :3], rtol=1e-6)
    action = holding_pose_action() if mode == "pose" else np.full(6, 0.1, dtype=np.float32)
    for _ in range(5):
        obs, reward, terminated, truncated, info = env.step(action)
    assert not terminated
    for key in ("vehicle_specific_force", "vehicle_angular_velocity", "head_specific_force", "head_angular_velocity"):
        assert info[key].shape == (3,)
    np.testing.assert_array_equal(info["vehicle_specific_force"], motion[5, :3])
    assert info["perceived_specific_force_error"] >= 0.0
    terms = {k: v for k, v in info.items() if k.startswith("reward_")}
    assert set(terms) == {
        "reward_specific_force",
        "reward_angular_velocity",
        "reward_workspace",
        "reward_stroke",
        "reward_control",
        "reward_false_cues",
        "reward_termination",
    }
    assert reward == pytest.approx(sum(terms.values()), rel=1e-12)  # the reward is its terms' sum


def task_episode(env):
    return {k: v[0] for k, v in env.unwrapped._core.episode.items()}


def test_the_platform_held_at_home_feels_gravity_and_the_reward_is_the_perceived_error():
    env = make(action_mode="pose")
    env.reset(seed=0)
    u = env.unwrapped
    for _ in range(3):
        _, reward, _, _, info = env.step(holding_pose_action())
    # held at home by the pose loop: at rest to well below a perception threshold (0.17 m/s²)
    np.testing.assert_allclose(info["head_specific_force"], [0.0, 0.0, 9.81], atol=0.05)
    np.testing.assert_allclose(info["head_angular_velocity"], 0.0, atol=0.01)
    # the reward's perception term is the vehicle's and the platform's perceptions compared
    error = np.linalg.norm(info["perceived_head_specific_force"] - info["perceived_vehicle_specific_force"])
    assert info["perceived_specific_force_error"] == pytest.approx(error, rel=1e-12)
    assert info["reward_specific_force"] == pytest.approx(np.exp(-(error**2)), rel=1e-12)
    assert u.task.name == "cueing"


def test_perception_is_the_vestibular_models_on_the_episodes_signals():
    """Recorded step by step, the perceived signals are the models' perceptions of the whole recorded signals."""
    env = make(action_mode="pose")
    env.reset(seed=1)
    rng = np.random.default_rng(0)
    vehicle_f, head_f, vehicle_w, head_w, seen_f, seen_w = [], [], [], [], [], []
    for _ in range(60):
        _, _, terminated, _, info = env.step(rng.uniform(-0.05, 0.05, 6).astype(np.float32))
        assert not terminated
        vehicle_f.append(info["vehicle_specific_force"])
        head_f.append(info["head_specific_force"])
        vehicle_w.append(info["vehicle_angular_velocity"])
        head_w.append(info["head_angular_velocity"])
        seen_f.append([info["perceived_vehicle_specific_force"], info["perceived_head_specific_force"]])
        seen_w.append([info["perceived_vehicle_angular_velocity"], info["perceived_head_angular_velocity"]])
    task = env.unwrapped.task
    motion = task.motion_of(int(task_episode(env)["motion"]), int(task_episode(env)["seed"]))
    dt = env.unwrapped._core.control_dt
    # the filters start adapted: the vehicle at its sample 0, the platform at rest (-g)
    vehicle = Otolith().perceive(np.vstack([motion[:1, :3], vehicle_f]), dt)[1:]
    platform = Otolith().perceive(np.vstack([[[0.0, 0.0, 9.81]], head_f]), dt)[1:]
    canal_vehicle = SemicircularCanal().perceive(np.vstack([motion[:1, 3:], vehicle_w]), dt)[1:]
    canal_platform = SemicircularCanal().perceive(np.vstack([np.zeros((1, 3)), head_w]), dt)[1:]
    # 1e-12: the same arithmetic on one row and on a batch of two (vehicle, platform)
    np.testing.assert_allclose(np.array(seen_f)[:, 0], vehicle, atol=1e-12)
    np.testing.assert_allclose(np.array(seen_f)[:, 1], platform, atol=1e-12)
    np.testing.assert_allclose(np.array(seen_w)[:, 0], canal_vehicle, atol=1e-12)
    np.testing.assert_allclose(np.array(seen_w)[:, 1], canal_platform, atol=1e-12)


def test_head_motion_hand_cases():
    gravity = np.array([0.0, 0.0, -9.81])
    home = np.eye(3)
    # a yaw rate of 1 rad/s, steady, head 0.5 m forward: centripetal 0.5 m/s² towards the axis (-x)
    rotation = np.eye(3)[None]
    w = np.array([[0.0, 0.0, 1.0]])
    f, omega = head_motion(
        rotation, np.zeros((1, 3)), w, np.zeros((1, 3)), w, 0.01, np.array([0.5, 0, 0]), gravity, home
    )
    np.testing.assert_allclose(f, [[-0.5, 0.0, 9.81]], atol=1e-15)
    np.testing.assert_allclose(omega, w, atol=0)
    # pitched up by 0.1 rad at rest: gravity seen in {H} tilts: f = (-g sin 0.1, 0, g cos 0.1)
    pitched = rpy_to_matrix([0.0, 0.1, 0.0])[None]
    f, _ = head_motion(
        pitched,
        np.zeros((1, 3)),
        np.zeros((1, 3)),
        np.zeros((1, 3)),
        np.zeros((1, 3)),
        0.01,
        np.zeros(3),
        gravity,
        home,
    )
    np.testing.assert_allclose(f, [[-9.81 * np.sin(0.1), 0.0, 9.81 * np.cos(0.1)]], atol=1e-14)
    # a surge from 0 to 0.02 m/s over 0.01 s: 2 m/s² forward, felt as a specific force of +2 on x
    f, _ = head_motion(
        np.eye(3)[None],
        np.array([[0.02, 0, 0]]),
        np.zeros((1, 3)),
        np.zeros((1, 3)),
        np.zeros((1, 3)),
        0.01,
        np.zeros(3),
        gravity,
        home,
    )
    np.testing.assert_allclose(f, [[2.0, 0.0, 9.81]], atol=1e-13)


def run(env, seed, steps, actions):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for k in range(steps):
        obs, reward, terminated, truncated, info = env.step(actions[k])
        out += [obs, np.array([reward]), np.array([info["perceived_specific_force_error"]])]
        if terminated or truncated:
            break
    return np.concatenate([x.ravel() for x in out])


def test_same_seed_same_episode_and_another_seed_another():
    actions = np.random.default_rng(2).uniform(-0.05, 0.05, (40, 6)).astype(np.float32)
    a = run(make(action_mode="pose"), 7, 40, actions)
    b = run(make(action_mode="pose"), 7, 40, actions)
    c = run(make(action_mode="pose"), 8, 40, actions)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_the_episode_ends_at_the_motions_end_with_a_success():
    env = make(action_mode="pose")
    env.reset(seed=4)
    steps = int(task_episode(env)["motion_steps"])
    taken, terminated = 0, False
    while not terminated and taken <= steps:
        _, _, terminated, truncated, info = env.step(holding_pose_action())
        taken += 1
    assert taken == steps and terminated and not truncated
    assert env.unwrapped.termination_reasons[info["termination"]] == "motion_end"
    assert info["reward_termination"] == 0.0  # a success pays no termination cost
    assert bool(info["is_success"])


def test_evaluation_split_draws_held_out_seeds():
    task = make_task("cueing", stewart_env_platform(), 0.01, {"split": "evaluation"})
    rng = np.random.default_rng(0)
    seeds = {int(task.initialize_episode(rng)[1]["seed"]) for _ in range(20)}
    assert seeds <= set(EVALUATION_SEEDS) and min(seeds) >= TRAINING_SEED_BOUND
    train = make_task("cueing", stewart_env_platform(), 0.01, {})
    assert all(train.initialize_episode(rng)[1]["seed"] < TRAINING_SEED_BOUND for _ in range(20))
    pool = make_task("cueing", stewart_env_platform(), 0.01, {"training_seeds": 3})
    assert {int(pool.initialize_episode(rng)[1]["seed"]) for _ in range(40)} == {0, 1, 2}


def stewart_env_platform():
    import stewart_env as se

    return se.load_platform("dasgupta1998")


def test_preview_holds_the_next_samples():
    env = make(action_mode="pose", task_options={"preview": 3})
    obs, _ = env.reset(seed=5)
    u = env.unwrapped
    motion = u.task.motion_of(int(task_episode(env)["motion"]), int(task_episode(env)["seed"]))
    preview = u.decode_observation(obs)["preview"].reshape(3, 6)
    np.testing.assert_allclose(preview, motion[1:4], rtol=1e-6, atol=1e-7)  # float32 observation


def test_checkers_pass():
    check_env(make(action_mode="pose").unwrapped)
    sb3 = pytest.importorskip("stable_baselines3", reason="needs the rl extra")
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    sb3_check_env(make(action_mode="force"), warn=True)
    assert sb3 is not None


def test_native_vector_rows_equal_single_envs_across_a_reset():
    n, seed = 3, 11
    kwargs = {"task": "cueing", "action_mode": "pose", "max_episode_steps": 30}
    envs = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    singles = [gym.make(ENV_ID, **kwargs) for _ in range(n)]
    v_obs, _ = envs.reset(seed=seed)
    s_obs = [env.reset(seed=seed + i)[0] for i, env in enumerate(singles)]
    actions = np.random.default_rng(1).uniform(-0.1, 0.1, (45, n, 6)).astype(np.float32)
    # row 0 commands the box's lowest corner and a full roll: it leaves the workspace early, so
    # that some steps reset it while the other rows step (their infos then masked row by row)
    actions[:, 0] = [0.0, 0.0, -1.0, 1.0, 0.0, 0.0]
    pending = [False] * n
    mixed = 0
    for k in range(45):
        np.testing.assert_array_equal(v_obs, np.array(s_obs))
        v_obs, v_rew, v_term, v_trunc, v_info = envs.step(actions[k])
        mixed += 0 < sum(pending) < n
        for i, env in enumerate(singles):
            if pending[i]:
                s_obs[i], _ = env.reset()
                rew, term, trunc = 0.0, False, False
            else:
                s_obs[i], rew, term, trunc, info = env.step(actions[k, i])
                np.testing.assert_array_equal(v_info["head_specific_force"][i], info["head_specific_force"])
                np.testing.assert_array_equal(
                    v_info["perceived_head_specific_force"][i], info["perceived_head_specific_force"]
                )
            assert v_rew[i] == rew and v_term[i] == term and v_trunc[i] == trunc, (k, i)
            pending[i] = term or trunc
    assert mixed, "some step should reset a row while others step"


@pytest.mark.parametrize("copier", [copy.deepcopy, lambda env: pickle.loads(pickle.dumps(env))])
def test_a_copy_mid_episode_goes_on_as_the_original(copier):
    env = make(action_mode="pose")
    env.reset(seed=9)
    actions = np.random.default_rng(3).uniform(-0.05, 0.05, (30, 6)).astype(np.float32)
    for a in actions[:10]:
        env.step(a)
    twin = copier(env)
    for a in actions[10:]:
        one, two = env.step(a), twin.step(a)
        np.testing.assert_array_equal(one[0], two[0])
        assert one[1] == two[1]
        np.testing.assert_array_equal(one[4]["perceived_head_specific_force"], two[4]["perceived_head_specific_force"])


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"preview": -1}, r"task_options\['preview'\]"),
        ({"preview": 101}, r"task_options\['preview'\]"),
        ({"preview": 1.5}, r"task_options\['preview'\]"),
        ({"split": "test"}, r"task_options\['split'\]"),
        ({"training_seeds": 0}, r"task_options\['training_seeds'\]"),
        ({"training_seeds": 2**31}, r"task_options\['training_seeds'\]"),
        ({"head": [0.0, 0.0]}, r"task_options\['head'\]"),
        ({"head": [0.0, 0.0, float("nan")]}, r"task_options\['head'\]"),
        ({"head": [0.0, 0.0, 1e9]}, r"task_options\['head'\]"),
        ({"motions": ("nope",)}, r"task_options\['motions'\]: unknown motion"),
        ({"motions": ()}, r"task_options\['motions'\]"),
        ({"motions": 3}, r"task_options\['motions'\]"),
        ({"specific_force_scale": 0.0}, r"task_options\['specific_force_scale'\]"),
        ({"angular_velocity_weight": -1.0}, r"task_options\['angular_velocity_weight'\]"),
        ({"workspace_weight": float("inf")}, r"task_options\['workspace_weight'\]"),
        ({"termination_cost": -1.0}, r"task_options\['termination_cost'\]"),
        ({"position_reward_weight": 1.0}, r"task_options: unknown option"),
    ],
)
def test_hostile_options_are_refused_naming_the_option(options, message):
    with pytest.raises(ValueError, match=message):
        make(task_options=options)


def test_a_motion_file_is_the_episode(tmp_path):
    path = tmp_path / "braking.csv"
    write_motion(make_motion("braking", 3), path)
    env = make(action_mode="pose", task_options={"motions": str(path)})
    obs, _ = env.reset(seed=0)
    u = env.unwrapped
    assert u.task.motion_names == ("braking",)  # the name the file records
    expected = make_motion("braking", 3)
    np.testing.assert_allclose(
        u.decode_observation(obs)["vehicle_specific_force"], expected.specific_force[0], rtol=1e-6
    )
    bad = tmp_path / "bad.csv"
    bad.write_text("not a motion\n")
    with pytest.raises(UsageError, match="bad.csv"):
        make(task_options={"motions": str(bad)})


def test_options_error_is_a_usage_error():
    with pytest.raises(UsageError):
        make_task("cueing", stewart_env_platform(), 0.01, {"split": "x"})


def test_false_cue_samples_by_hand():
    from stewart_env.tasks.cueing.vestibular import false_cue_samples

    thresholds = np.array([0.17, 0.17, 0.28])
    vehicle = np.array([[1.0, -1.0, 0.5], [0.0, 0.2, -0.1]])
    platform = np.array([[-0.3, -0.5, 0.1], [0.2, -0.16, 0.29]])
    # x: wrong sign above 0.17; y: same sign; z: below 0.28 | x: the vehicle still, platform above;
    # y: wrong sign but below 0.17; z: wrong sign above 0.28
    expected = np.array([[True, False, False], [True, False, True]])
    np.testing.assert_array_equal(false_cue_samples(vehicle, platform, thresholds), expected)


def test_the_false_cue_penalty_counts_the_samples_the_evaluation_counts():
    from stewart_env.agents.evaluation.cueing import perceive
    from stewart_env.tasks.cueing.vestibular import THRESHOLDS, false_cue_samples

    env = make(action_mode="pose", task_options={"false_cue_weight": 0.5, "motions": ("braking",)})
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    keys = ("vehicle_specific_force", "vehicle_angular_velocity", "head_specific_force", "head_angular_velocity")
    trace = {k: [] for k in (*keys, "reward_false_cues")}
    action = holding_pose_action()
    for step in range(320):
        if step >= 20:  # held at home first: the evaluation's perception starts adapted to its first sample
            action = np.clip(action + 0.01 * rng.standard_normal(6), -0.5, 0.5).astype(np.float32)
        _, _, terminated, truncated, info = env.step(action)
        assert not (terminated or truncated)
        for k in trace:
            trace[k].append(np.array(info[k]))
    t = {k: np.array(v) for k, v in trace.items()}
    vf, vw = perceive(t["vehicle_specific_force"], t["vehicle_angular_velocity"], 0.01)
    hf, hw = perceive(t["head_specific_force"], t["head_angular_velocity"], 0.01)
    counted = false_cue_samples(vf, hf, THRESHOLDS["specific_force"]).sum(axis=1)
    counted += false_cue_samples(vw, hw, THRESHOLDS["angular_velocity"]).sum(axis=1)
    assert counted.sum() > 100  # the wandering pose makes false cues to count
    np.testing.assert_array_equal(-t["reward_false_cues"] / 0.5, counted)  # step by step, the same samples


def test_the_false_cue_penalty_is_off_by_default():
    env = make(action_mode="pose")
    env.reset(seed=3)
    for _ in range(30):
        _, _, _, _, info = env.step(np.full(6, 0.3, dtype=np.float32))
    assert info["reward_false_cues"] == 0.0
