"""Tests for the headless platform renderer (stewart_env.render)."""

import sys

import numpy as np
import pytest

from stewart_env.render import PlatformRenderer

# The project's example platform: joints in metres, b_i in {B}, p_i in {P}.
BASE_JOINTS = np.array(
    [(-0.62, 1.374, -0.6), (-0.88, 1.224, -0.6), (-0.88, -1.224, -0.6),
     (-0.62, -1.374, -0.6), (1.5, -0.15, -0.6), (1.5, 0.15, -0.6)]
)
PLATFORM_JOINTS = np.array(
    [(0.17, 0.595, -0.4), (-0.6, 0.15, -0.4), (-0.6, -0.15, -0.4),
     (0.17, -0.595, -0.4), (0.43, -0.445, -0.4), (0.43, 0.445, -0.4)]
)
HOME = np.array([0.0, 0.0, 0.4])
FORCE_RANGE = (-2000.0, 2000.0)
WIDTH, HEIGHT = 320, 240


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@pytest.fixture(scope="module")
def renderer():
    r = PlatformRenderer(BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, width=WIDTH, height=HEIGHT)
    yield r
    r.close()


def test_frame_shape_dtype_and_content(renderer):
    frame = renderer.render(HOME, np.eye(3), np.zeros(6), text="t = 1.23 s")
    assert frame.shape == (HEIGHT, WIDTH, 3)
    assert frame.dtype == np.uint8
    colours = np.unique(frame.reshape(-1, 3), axis=0)
    assert len(colours) > 20, "frame looks blank"


def test_leg_colour_follows_force(renderer):
    at_max = renderer.render(HOME, np.eye(3), np.full(6, FORCE_RANGE[1])).astype(float)
    at_min = renderer.render(HOME, np.eye(3), np.full(6, FORCE_RANGE[0])).astype(float)
    red, blue = 0, 2
    assert at_max[..., red].mean() > at_min[..., red].mean() + 1.0
    assert at_max[..., blue].mean() < at_min[..., blue].mean() - 1.0


def test_min_and_max_legs_differ_within_one_frame(renderer):
    # Pixels that change when leg 2 goes to min force and leg 4 to max force belong to
    # those two legs: some must be clearly blue, others clearly red. Legs 2 and 4 face
    # the camera; legs 0 and 1 are seen through the translucent plate, which tints them.
    neutral = renderer.render(HOME, np.eye(3), np.zeros(6)).astype(int)
    forces = np.array([0.0, 0.0, FORCE_RANGE[0], 0.0, FORCE_RANGE[1], 0.0])
    mixed = renderer.render(HOME, np.eye(3), forces).astype(int)
    changed = mixed[np.any(mixed != neutral, axis=-1)]
    assert len(changed) > 0
    red, blue = changed[:, 0], changed[:, 2]
    assert np.sum(blue > red + 60) > 100
    assert np.sum(red > blue + 60) > 100


def test_target_ghost_changes_frame(renderer):
    position = HOME + np.array([0.05, 0.0, 0.02])
    without = renderer.render(position, np.eye(3), np.zeros(6))
    with_target = renderer.render(
        position, np.eye(3), np.zeros(6), target_position=HOME + np.array([0.0, 0.1, 0.1]), target_rotation=_rot_z(0.3)
    )
    assert not np.array_equal(without, with_target)
    # The ghost is dropped again when no target is given.
    assert np.array_equal(without, renderer.render(position, np.eye(3), np.zeros(6)))


def test_pose_changes_frame(renderer):
    home = renderer.render(HOME, np.eye(3), np.zeros(6))
    moved = renderer.render(HOME + np.array([0.0, 0.0, 0.2]), _rot_z(0.4), np.zeros(6))
    assert not np.array_equal(home, moved)


def test_render_is_deterministic(renderer):
    args = (HOME + np.array([0.1, -0.05, 0.03]), _rot_z(0.2), np.linspace(-1500.0, 1800.0, 6))
    kwargs = dict(target_position=HOME, text="t = 0.50 s")
    first = renderer.render(*args, **kwargs)
    renderer.render(HOME, np.eye(3), np.zeros(6))  # an unrelated frame in between
    assert np.array_equal(first, renderer.render(*args, **kwargs))


@pytest.mark.parametrize(
    "name, kwargs",
    [
        ("position", dict(position=np.zeros(2))),
        ("rotation", dict(rotation=np.eye(4))),
        ("leg_forces", dict(leg_forces=np.zeros(5))),
        ("target_position", dict(target_position=np.zeros((3, 1)))),
        ("target_rotation", dict(target_position=HOME, target_rotation=np.eye(3)[:2])),
        ("position", dict(position=np.array([0.0, np.nan, 0.4]))),
    ],
)
def test_render_rejects_bad_input(renderer, name, kwargs):
    call = dict(position=HOME, rotation=np.eye(3), leg_forces=np.zeros(6)) | kwargs
    with pytest.raises(ValueError, match=name):
        renderer.render(**call)


@pytest.mark.parametrize(
    "name, kwargs",
    [
        ("base_joints", dict(base_joints=BASE_JOINTS[:5])),
        ("platform_joints", dict(platform_joints=PLATFORM_JOINTS.T)),
        ("home_position", dict(home_position=np.zeros(4))),
        ("force_range", dict(force_range=(1.0, 2.0, 3.0))),
        ("force_range", dict(force_range=(2000.0, -2000.0))),
        ("width", dict(width=0)),
        ("height", dict(height=2.5)),
        ("render_mode", dict(render_mode="ansi")),
    ],
)
def test_constructor_rejects_bad_input(name, kwargs):
    call = dict(
        base_joints=BASE_JOINTS, platform_joints=PLATFORM_JOINTS, home_position=HOME, force_range=FORCE_RANGE
    ) | kwargs
    with pytest.raises(ValueError, match=name):
        PlatformRenderer(**call)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="display detection differs off Linux")
def test_human_mode_without_display_raises(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RuntimeError, match="rgb_array"):
        PlatformRenderer(BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, render_mode="human")


def test_render_after_close_raises():
    r = PlatformRenderer(BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, width=64, height=64)
    r.close()
    r.close()  # closing twice is harmless
    with pytest.raises(RuntimeError, match="close"):
        r.render(HOME, np.eye(3), np.zeros(6))
