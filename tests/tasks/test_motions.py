"""The cueing task's vehicle motions: the generators (seeded, held-out seeds, physically sane),
the motion file (round trip, every hostile file named by file, row and column) and the JSBSim
references (reproducible to the byte)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stewart_env.errors import UsageError
from stewart_env.files import FileError, WriteError
from stewart_env.tasks.cueing.motion import STANDARD_GRAVITY, VehicleMotion
from stewart_env.tasks.cueing.motions import (
    EVALUATION_MOTIONS,
    EVALUATION_SEEDS,
    MOTIONS,
    TRAINING_MOTIONS,
    TRAINING_SEED_BOUND,
    MotionFileError,
    driving,
    flight,
    make_motion,
    motion_file,
    read_motion,
    sweeps,
    write_motion,
)

CONTRACT_NAMES = (
    "double_lane_change", "braking", "acceleration", "slalom", "coordinated_turn", "takeoff_roll", "turbulence",
    "sweep_x", "sweep_y", "sweep_z", "sweep_roll", "sweep_pitch", "sweep_yaw",
)  # fmt: skip


# -- the generators -------------------------------------------------------------------------------


def test_every_motion_of_the_contract_is_made():
    assert set(CONTRACT_NAMES) <= set(MOTIONS)
    assert set(TRAINING_MOTIONS) <= set(EVALUATION_MOTIONS) == set(MOTIONS)
    assert not set(TRAINING_MOTIONS) & set(sweeps.SWEEP_CHANNELS)


@pytest.mark.parametrize("name", list(MOTIONS))
def test_a_motion_is_the_same_for_the_same_seed_and_differs_between_seeds(name):
    first, again, other = make_motion(name, 7), make_motion(name, 7), make_motion(name, 8)
    assert isinstance(first, VehicleMotion) and first.name == name and first.source == f"{name} seed 7"
    assert first.specific_force.tobytes() == again.specific_force.tobytes()
    assert first.angular_velocity.tobytes() == again.angular_velocity.tobytes()
    assert first.meta == again.meta
    assert first.meta != other.meta


def test_evaluation_seeds_are_held_out_of_training():
    assert TRAINING_SEED_BOUND == 2**30
    assert len(set(EVALUATION_SEEDS)) == len(EVALUATION_SEEDS) >= 5
    assert min(EVALUATION_SEEDS) >= TRAINING_SEED_BOUND
    # an evaluation seed draws another motion than the training seed of the same low bits
    held_out, trained = make_motion("double_lane_change", EVALUATION_SEEDS[0]), make_motion("double_lane_change", 0)
    assert held_out.meta["speed"] != trained.meta["speed"]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"name": "lane_change", "seed": 0}, "name: unknown motion 'lane_change'; the motions are double_lane_change"),
        ({"name": "braking", "seed": -1}, "seed: must be an integer in [0, 2**63), got -1"),
        ({"name": "braking", "seed": 1.5}, "seed: must be an integer in [0, 2**63), got 1.5"),
        ({"name": "braking", "seed": True}, "seed: must be an integer in [0, 2**63), got True"),
        ({"name": "braking", "seed": 0, "dt": 0.0}, "dt: must be a number of seconds in (0, 0.1], got 0.0"),
        ({"name": "braking", "seed": 0, "dt": math.nan}, "dt: must be a number of seconds in (0, 0.1], got nan"),
        ({"name": "braking", "seed": 0, "dt": 0.5}, "dt: must be a number of seconds in (0, 0.1], got 0.5"),
    ],
)
def test_make_motion_refuses_a_bad_argument_by_name(kwargs, message):
    with pytest.raises(UsageError) as caught:
        make_motion(**kwargs)
    assert str(caught.value).startswith(message)


def test_a_car_at_a_steady_speed_on_a_straight_feels_plus_g():
    motion = make_motion("braking", 3)
    before = motion.time < motion.meta["onset"] - 2 * motion.dt  # the rates' central differences look a sample ahead
    assert before.sum() >= 100
    np.testing.assert_array_equal(motion.specific_force[before], [[0.0, 0.0, STANDARD_GRAVITY]] * before.sum())
    np.testing.assert_array_equal(motion.angular_velocity[before], 0.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_steady_braking_gives_f_x_of_minus_the_deceleration(seed):
    motion = make_motion("braking", seed)
    decel, onset, build = motion.meta["deceleration"], motion.meta["onset"], motion.meta["build_up"]
    speed = motion.meta["speed"]
    # after the pitch has settled (1.5 s) and while the car is faster than the release's 1 m/s
    steady = (motion.time > onset + build + 1.5) & (motion.time < onset + build / 2 + (speed - 1.5) / decel)
    assert steady.sum() >= 50
    f_x = motion.specific_force[steady, 0]
    # the body's steady nose-down pitch (CAR.pitch_gradient, 2.5 % of g per g) tilts gravity into x
    tilt = driving.CAR.pitch_gradient * decel * STANDARD_GRAVITY
    np.testing.assert_allclose(f_x, -decel - tilt, rtol=0, atol=0.005 * decel)
    assert 0.0 < tilt < 0.03 * decel


@pytest.mark.parametrize("seed", [0, 1, 2, EVALUATION_SEEDS[0]])
def test_a_coordinated_turn_has_no_lateral_specific_force_while_the_bank_is_held(seed):
    motion = make_motion("coordinated_turn", seed)
    m = motion.meta
    start = m["before"] + m["roll_in"]
    held = (motion.time > start + 0.05) & (motion.time < start + m["hold"] - 0.05)
    turn_rate = STANDARD_GRAVITY * math.tan(abs(m["bank"])) / m["airspeed"]
    # at the head, off the centre of mass, the steady rotation adds omega x (omega x r): at most
    # turn_rate² |r|
    bound = turn_rate**2 * float(np.linalg.norm(flight.PILOT_HEAD)) + 1e-9
    assert np.abs(motion.specific_force[held, 1]).max() <= bound
    np.testing.assert_allclose(
        motion.specific_force[held, 2], STANDARD_GRAVITY / math.cos(m["bank"]), rtol=0, atol=bound
    )
    np.testing.assert_allclose(np.linalg.norm(motion.angular_velocity[held], axis=1), turn_rate, rtol=1e-9)
    # a bank to the right (roll > 0, y left) turns clockwise seen from above: yaw rate < 0
    assert np.sign(motion.angular_velocity[held, 2]).tolist() == [-np.sign(m["bank"])] * held.sum()


@pytest.mark.parametrize("seed", [0, 1, 2, 3, EVALUATION_SEEDS[0]])
def test_the_double_lane_change_moves_the_car_by_the_iso_offset_and_back(seed):
    motion = make_motion("double_lane_change", seed)
    m = motion.meta
    run = driving.simulate(
        lambda x: driving.ISO_3888_1_OFFSET
        * (
            driving.smoothstep(x, m["lead"] + 15.0, 30.0)
            - driving.smoothstep(x, m["lead"] + 70.0, 25.0)
        ),
        m["speed"], np.zeros(motion.n_samples), motion.dt, m["preview"],
    )  # fmt: skip
    # the pure-pursuit driver reaches the offset lane, overshooting it by less than 1 m (a driver
    # through the track's geometry, not a path-tracking controller), and comes back to within 0.5 m
    assert 0.0 < run["y"].max() - driving.ISO_3888_1_OFFSET < 1.0
    assert abs(run["y"][-1]) < 0.5
    # a left lane change first: the lateral specific force is first positive
    f_y = motion.specific_force[:, 1]
    assert f_y[np.argmax(np.abs(f_y) > 1.0)] > 0.0


def test_a_sweep_moves_one_channel_at_the_documented_frequencies():
    motion = make_motion("sweep_pitch", 5)
    amplitude = motion.meta["amplitude"]
    assert 0.075 <= amplitude <= 0.125
    np.testing.assert_array_equal(motion.specific_force, [[0.0, 0.0, STANDARD_GRAVITY]] * motion.n_samples)
    np.testing.assert_array_equal(motion.angular_velocity[:, [0, 2]], 0.0)
    assert np.abs(motion.angular_velocity[:, 1]).max() <= amplitude
    # the number of cycles is the integral of the frequency: f0 T (f1 / f0 - 1) / ln(f1 / f0)
    f0, f1, duration = sweeps.SWEEP_START_HZ, sweeps.SWEEP_END_HZ, sweeps.SWEEP_DURATION
    cycles = f0 * duration * (f1 / f0 - 1.0) / math.log(f1 / f0)
    signal = motion.angular_velocity[:, 1]
    crossings = np.count_nonzero(np.signbit(signal[1:]) != np.signbit(signal[:-1]))
    assert abs(crossings - 2 * cycles) <= 3  # the faded ends lose or add a crossing each


def test_the_dryden_gusts_have_the_mil_f_8785c_intensities():
    airspeed, altitude, wind20 = 55.0, 200.0, 7.7
    gusts = flight.dryden_gusts(np.random.default_rng(0), 200_000, 0.01, airspeed, altitude, wind20, 11.0)[10_000:]
    h_ft = altitude / 0.3048
    sigma_w = 0.1 * wind20
    sigma_uv = sigma_w / (0.177 + 0.000823 * h_ft) ** 0.4
    # 1900 s of gusts whose correlation times are 4 to 11 s: a few hundred independent samples,
    # the standard deviations within 10 %
    np.testing.assert_allclose(gusts[:, :3].std(axis=0), [sigma_uv, sigma_uv, sigma_w], rtol=0.1)


@pytest.mark.parametrize("name", list(TRAINING_MOTIONS))
def test_every_manoeuvre_stays_within_a_vehicle_s_range(name):
    for seed in (0, 1, EVALUATION_SEEDS[0]):
        motion = make_motion(name, seed)
        # a car within its tyres' grip and a light aircraft in light turbulence: below 2 g
        # horizontally and 0..2.5 g vertically, rates below 2 rad/s
        assert np.abs(motion.specific_force[:, :2]).max() < 2.0 * STANDARD_GRAVITY, (name, seed)
        assert 0.0 < motion.specific_force[:, 2].min() and motion.specific_force[:, 2].max() < 2.5 * STANDARD_GRAVITY
        assert np.abs(motion.angular_velocity).max() < 2.0, (name, seed)
        assert 5.0 <= motion.duration <= 40.0, (name, seed)


@pytest.mark.parametrize("name", list(TRAINING_MOTIONS))
def test_no_manoeuvre_steps_between_samples(name):
    for seed in (0, 1, 2):
        motion = make_motion(name, seed)
        jerk = np.abs(np.diff(motion.specific_force, axis=0)).max() / motion.dt
        # a car's or an aircraft's jerk stays within tens of m/s³ (the take-off's runway roughness,
        # seen 1 m ahead of the pitch axis, is the roughest at about 90); a step of a sample is 1/dt
        assert jerk < 150.0, (name, seed, jerk)


# -- the motion file ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(MOTIONS))
def test_every_generated_motion_reads_back_as_written(tmp_path, name):
    motion = make_motion(name, 11)
    path = write_motion(motion, tmp_path / f"{name}.csv")
    back = read_motion(path)
    assert back.name == name and back.source == str(path) and back.meta["source"] == f"{name} seed 11"
    np.testing.assert_array_equal(back.specific_force, motion.specific_force)
    np.testing.assert_array_equal(back.angular_velocity, motion.angular_velocity)
    assert back.dt == pytest.approx(motion.dt, rel=1e-12)  # (t_last - t_0) / (T - 1) of repr-exact times
    again = write_motion(motion, tmp_path / "again.csv")
    assert again.read_bytes() == path.read_bytes()


def _rows(n=20, dt=0.01):
    """The text rows of a motion at rest, n samples."""
    return [f"{k * dt!r},0.0,0.0,9.80665,0.0,0.0,0.0" for k in range(n)]


def _file(tmp_path, body, header="time_s,f_x,f_y,f_z,omega_x,omega_y,omega_z\ns,m/s^2,m/s^2,m/s^2,rad/s,rad/s,rad/s"):
    path = tmp_path / "log.csv"
    path.write_text("# format: stewart-env motion 1\n" + header + "\n" + "\n".join(body) + "\n")
    return path


def _with(rows, index, text):
    rows = list(rows)
    rows[index] = text
    return rows


# rows of the file: 1 the comment, 2 the names, 3 the units, 4 the first sample
HOSTILE = {
    "nan": (
        None,
        _with(_rows(), 5, "0.05,0.0,nan,9.80665,0.0,0.0,0.0"),
        "row 9, column f_y: 'nan' is not a finite number",
    ),
    "empty cell": (
        None,
        _with(_rows(), 2, "0.02,0.0,0.0,9.80665,,0.0,0.0"),
        "row 6, column omega_x: '' is not a number",
    ),
    "text": (None, _with(_rows(), 0, "0.0,zero,0.0,9.80665,0.0,0.0,0.0"), "row 4, column f_x: 'zero' is not a number"),
    "short row": (None, _with(_rows(), 3, "0.03,0.0,0.0"), "row 7: 3 values for 7 columns"),
    "time backwards": (
        None,
        _with(_rows(), 4, "0.02,0.0,0.0,9.80665,0.0,0.0,0.0"),
        "row 8, column time_s: the time stamp 0.02 s is before the previous row's 0.03 s",
    ),
    "time repeated": (
        None,
        _with(_rows(), 4, "0.03,0.0,0.0,9.80665,0.0,0.0,0.0"),
        "row 8, column time_s: the time stamp 0.03 s repeats the previous row's 0.03 s",
    ),
    "gap": (
        None,
        [r for k, r in enumerate(_rows()) if k not in (7, 8)],
        "row 11, column time_s: a gap: 0.03 s after the previous row, the file's step being 0.01 s",
    ),
    "missing column": (
        "time_s,f_x,f_y,f_z,omega_x,omega_y\ns,m/s^2,m/s^2,m/s^2,rad/s,rad/s",
        [r[: r.rfind(",")] for r in _rows()],
        "row 2, column omega_z: missing (every column of the format is needed)",
    ),
    "unknown column": (
        "time_s,f_x,f_y,f_z,omega_x,omega_y,omega_z,roll\ns,m/s^2,m/s^2,m/s^2,rad/s,rad/s,rad/s,rad",
        _rows(),
        "row 2, column roll: unknown column (the format's columns: time_s,f_x,f_y,f_z,omega_x,omega_y,omega_z)",
    ),
    "column twice": (
        "time_s,f_x,f_x,f_z,omega_x,omega_y,omega_z\ns,m/s^2,m/s^2,m/s^2,rad/s,rad/s,rad/s",
        _rows(),
        "row 2, column f_x: the column appears twice",
    ),
    "unit g": (
        "time_s,f_x,f_y,f_z,omega_x,omega_y,omega_z\ns,g,g,g,rad/s,rad/s,rad/s",
        _rows(),
        "row 3, column f_x: the unit is 'g'; the format's is 'm/s^2'",
    ),
    "unit deg/s": (
        "time_s,f_x,f_y,f_z,omega_x,omega_y,omega_z\ns,m/s^2,m/s^2,m/s^2,rad/s,deg/s,rad/s",
        _rows(),
        "row 3, column omega_y: the unit is 'deg/s'; the format's is 'rad/s'",
    ),
    "no units row": ("time_s,f_x,f_y,f_z,omega_x,omega_y,omega_z", [], "row 3: no units row after the column names"),
    "values in g": (
        None,
        [r.replace("9.80665", "1.0") for r in _rows()],
        "row 4, column f_z: the specific force's mean magnitude is 1 m/s², not near g0 = 9.80665 m/s²",
    ),
    "z down": (
        None,
        [r.replace("9.80665", "-9.80665") for r in _rows()],
        "row 4, column f_z: f_z is negative on average: the head frame's z points up",
    ),
    "values in deg/s": (
        None,
        _with(_rows(), 6, "0.06,0.0,0.0,9.80665,0.0,0.0,25.0"),
        "row 10, column omega_z: 25 rad/s is beyond 10 rad/s (values in deg/s rather than rad/s?)",
    ),
    "one sample": (None, _rows(1), "row 5: 1 samples; a motion needs at least 2"),
}


@pytest.mark.parametrize("case", list(HOSTILE))
def test_a_hostile_motion_file_is_refused_naming_the_file_row_and_column(tmp_path, case):
    header, body, message = HOSTILE[case]
    path = _file(tmp_path, body, *(() if header is None else (header,)))
    with pytest.raises(MotionFileError) as caught:
        read_motion(path)
    assert str(caught.value).startswith(f"{path}: {message}")
    assert isinstance(caught.value, UsageError) and "\n" not in str(caught.value)


def test_columns_in_another_order_and_other_spellings_of_the_units_are_read(tmp_path):
    rows = [f"0.0,{k * 0.02!r},9.80665,0.0,0.5,0.0,0.0" for k in range(10)]
    path = _file(tmp_path, rows, "f_x,time_s,f_z,f_y,omega_z,omega_x,omega_y\nm/s2,s,m/s²,m/s^2,rad/s,rad/s,rad/s")
    path.write_text(path.read_text().replace("\n", "\r\n") + "\r\n\n")  # Windows line ends, blank lines at the end
    motion = read_motion(path)
    assert motion.dt == pytest.approx(0.02, rel=1e-12) and motion.name == "log"  # the times' sum rounds
    np.testing.assert_array_equal(motion.specific_force[0], [0.0, 0.0, 9.80665])
    np.testing.assert_array_equal(motion.angular_velocity[0], [0.0, 0.0, 0.5])


def test_a_motion_file_too_large_not_regular_or_not_text_is_refused(tmp_path, monkeypatch):
    with pytest.raises(FileError, match="a directory, not a motion file"):
        read_motion(tmp_path)
    path = _file(tmp_path, _rows())
    monkeypatch.setattr(motion_file, "MAX_MOTION_BYTES", 100)
    with pytest.raises(FileError) as caught:
        read_motion(path)
    assert str(caught.value) == f"{path}: larger than 100 bytes ({path.stat().st_size} bytes)"
    monkeypatch.undo()
    path.write_bytes(b"time_s\xff\n")
    with pytest.raises(MotionFileError) as caught:
        read_motion(path)
    assert str(caught.value) == f"{path}: not UTF-8 text (invalid byte at offset 6)"


def test_writing_a_motion_where_no_file_can_be_made_is_one_error_naming_it(tmp_path):
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file\n")
    target = blocker / "motion.csv"
    with pytest.raises(WriteError) as caught:
        write_motion(make_motion("braking", 0), target)
    assert str(caught.value) == f"cannot write {target}: Not a directory"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["not-a-folder"]


def test_a_write_failing_midway_leaves_the_old_file_whole(tmp_path, monkeypatch):
    target = tmp_path / "motion.csv"
    target.write_text("the old file\n")

    def fail(path, data):
        raise WriteError(path, "No space left on device")

    monkeypatch.setattr(motion_file.files, "publish", fail)
    with pytest.raises(WriteError, match="No space left on device"):
        write_motion(make_motion("braking", 0), target)
    assert target.read_text() == "the old file\n"


# -- the JSBSim references ------------------------------------------------------------------------


@pytest.mark.extra("jsbsim")
def test_a_jsbsim_reference_is_the_same_file_twice(tmp_path):
    from stewart_env.tasks.cueing.motions.jsbsim_reference import write_jsbsim_reference

    first = write_jsbsim_reference(tmp_path / "a.csv", "aileron_doublet", duration=6.0)
    second = write_jsbsim_reference(tmp_path / "b.csv", "aileron_doublet", duration=6.0)
    assert first.read_bytes() == second.read_bytes()
    motion = read_motion(first)
    assert motion.name == "jsbsim_c172x_aileron_doublet" and motion.n_samples == 601
    # trimmed level flight before the doublet at 1 s: about 1 g along z up, little rotation
    calm = motion.time < 0.9
    np.testing.assert_allclose(motion.specific_force[calm, 2], STANDARD_GRAVITY, rtol=0.03)  # the trim's residual
    assert np.abs(motion.angular_velocity[calm]).max() < 0.01
    # the doublet's right aileron first (positive command) rolls the aircraft: |p| rises well above the trim's
    assert np.abs(motion.angular_velocity[:, 0]).max() > 0.2


@pytest.mark.extra("jsbsim")
@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"manoeuvre": "loop"}, "manoeuvre: unknown manoeuvre 'loop'"),
        ({"aircraft": "c999"}, "aircraft: JSBSim ships no aircraft 'c999'"),
        ({"duration": -1.0}, "duration: must be a number of seconds in (0, 600], got -1.0"),
        ({"dt": 0.0}, "dt: must be a number of seconds in (0, 0.1], got 0.0"),
    ],
)
def test_a_jsbsim_reference_refuses_a_bad_argument_by_name(kwargs, message):
    from stewart_env.tasks.cueing.motions.jsbsim_reference import jsbsim_motion

    with pytest.raises(UsageError) as caught:
        jsbsim_motion(**kwargs)
    assert str(caught.value).startswith(message)


def test_a_jsbsim_reference_without_the_extra_is_one_line_naming_it(monkeypatch, capsys, tmp_path):
    import stewart_env.extras as extras
    from stewart_env.tasks.cueing.motions import jsbsim_reference

    monkeypatch.setattr(extras, "missing", lambda extra: ["jsbsim"] if extra == "jsbsim" else [])
    assert jsbsim_reference.main([str(tmp_path / "a.csv")]) == 2
    err = capsys.readouterr().err
    assert err == (
        "error: a JSBSim flight reference needs jsbsim, which is not installed; "
        "install the extra 'jsbsim': pip install -e \".[jsbsim]\"\n"
    )
    assert not (tmp_path / "a.csv").exists()
