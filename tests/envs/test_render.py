"""Tests for the headless platform renderer (stewart_env.envs.render)."""

import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

from stewart_env.envs import render
from stewart_env.envs.render import LEG_FORCE_COLORMAP, PlatformRenderer

# The project's example platform: joints in metres, b_i in {B}, p_i in {P}.
BASE_JOINTS = np.array(
    [
        (-0.62, 1.374, -0.6),
        (-0.88, 1.224, -0.6),
        (-0.88, -1.224, -0.6),
        (-0.62, -1.374, -0.6),
        (1.5, -0.15, -0.6),
        (1.5, 0.15, -0.6),
    ]
)
PLATFORM_JOINTS = np.array(
    [
        (0.17, 0.595, -0.4),
        (-0.6, 0.15, -0.4),
        (-0.6, -0.15, -0.4),
        (0.17, -0.595, -0.4),
        (0.43, -0.445, -0.4),
        (0.43, 0.445, -0.4),
    ]
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
    call = (
        dict(base_joints=BASE_JOINTS, platform_joints=PLATFORM_JOINTS, home_position=HOME, force_range=FORCE_RANGE)
        | kwargs
    )
    with pytest.raises(ValueError, match=name):
        PlatformRenderer(**call)


@pytest.fixture
def no_warning_yet(monkeypatch):
    """Each test sees the once-per-process no-display warning afresh."""
    monkeypatch.setattr(render, "_warned_no_display", False)


def _display_warnings(record) -> list[str]:
    return [str(w.message) for w in record if "no display is available" in str(w.message)]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="display detection differs off Linux")
def test_human_mode_without_display_warns_once_and_draws_nothing(monkeypatch, no_warning_yet):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        first = PlatformRenderer(BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, render_mode="human")
        assert first.render(HOME, np.eye(3), np.zeros(6), target_position=HOME) is None
        second = PlatformRenderer(BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, render_mode="human")
        assert second.render(HOME, np.eye(3), np.zeros(6)) is None
    messages = _display_warnings(record)
    assert len(messages) == 1 and "DISPLAY" in messages[0] and "rgb_array" in messages[0]
    assert not first.draws
    # the inputs are still checked, and close() still ends the renderer
    with pytest.raises(ValueError, match="leg_forces"):
        first.render(HOME, np.eye(3), np.zeros(5))
    first.close()
    with pytest.raises(RuntimeError, match="close"):
        first.render(HOME, np.eye(3), np.zeros(6))


def test_human_mode_when_the_backend_cannot_open_a_window(monkeypatch, no_warning_yet):
    import matplotlib.pyplot as plt

    def refuse(*args, **kwargs):
        raise RuntimeError("couldn't connect to display ':99'")

    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(plt, "get_backend", lambda: "TkAgg")
    monkeypatch.setattr(plt, "figure", refuse)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        r = PlatformRenderer(BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, render_mode="human")
    messages = _display_warnings(record)
    assert len(messages) == 1 and "couldn't connect" in messages[0]
    assert r.render(HOME, np.eye(3), np.zeros(6)) is None


def test_human_mode_with_a_window_draws_and_returns_none(monkeypatch, no_warning_yet):
    """The window path, on pyplot's Agg backend reported as a GUI one (no real display here)."""
    import matplotlib.pyplot as plt

    plt.switch_backend("agg")
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(plt, "get_backend", lambda: "TkAgg")
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        r = PlatformRenderer(
            BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, width=WIDTH, height=HEIGHT, render_mode="human"
        )
        assert r.draws
        assert r.render(HOME, np.eye(3), np.full(6, 150.0), target_position=HOME, text="t = 0.01 s") is None
    assert not _display_warnings(record)
    figure = r._fig
    assert plt.fignum_exists(figure.number)
    r.close()
    assert not plt.fignum_exists(figure.number)


# check_env builds a render_mode="human" environment and resets it: it must pass on headless
# machines, as CI sets them up (MPLBACKEND=Agg), with no backend chosen, and with Agg on a desktop.
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="display detection differs off Linux")
@pytest.mark.parametrize("environ", [{"MPLBACKEND": "Agg"}, {}, {"MPLBACKEND": "Agg", "DISPLAY": ":0"}])
def test_check_env_passes_headless(environ):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "MPLBACKEND")}
    script = (
        "import warnings, gymnasium as gym, stewart_env\n"
        "from gymnasium.utils.env_checker import check_env\n"
        "with warnings.catch_warnings(record=True) as record:\n"
        "    warnings.simplefilter('always')\n"
        "    check_env(gym.make('StewartPlatform-v1').unwrapped)\n"
        "print(sum('no display is available' in str(w.message) for w in record))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], env=env | environ, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "1"  # warned once, though check_env resets the human-mode env


def test_legs_at_holding_force_stand_out_from_the_background(renderer):
    frame = renderer.render(HOME, np.eye(3), np.full(6, 150.0)).astype(float) / 255.0
    luminance = frame @ np.array([0.2126, 0.7152, 0.0722])
    # Six outlined legs at 320 x 240 cover ~7 % of the frame in dark pixels; near-white legs (the
    # former white-centred colour map) left under 1 %, only the plate's edges and the text.
    assert np.mean(luminance < 0.4) > 0.04
    # no colour of the map is near white, whatever the force
    colours = LEG_FORCE_COLORMAP(np.linspace(0.0, 1.0, 256))[:, :3]
    assert np.max(colours @ np.array([0.2126, 0.7152, 0.0722])) < 0.5


def test_scene_fills_the_frame_width(renderer):
    frame = renderer.render(HOME, np.eye(3), np.zeros(6))
    # A column is drawn if any pixel in it is darker than the white background (240 of 255 lets
    # faint antialiased edges count).
    drawn_columns = np.any(frame.min(axis=-1) < 240, axis=0)
    # the scene runs edge to edge, up to the colour bar (the former cube view left ~30 % empty)
    assert drawn_columns.mean() > 0.95


def test_legend_names_the_target_and_the_colour_bar_its_unit(renderer):
    figure = renderer._fig
    assert "target" in [t.get_text() for t in figure.legends[0].get_texts()]
    assert any(ax.get_ylabel() == "leg force (N)" for ax in figure.axes)


@pytest.mark.parametrize("width, height", [(319, 241), (64, 48), (640, 360)])
def test_frame_size_is_exact(width, height):
    r = PlatformRenderer(BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, width=width, height=height)
    frame = r.render(HOME, np.eye(3), np.zeros(6))
    r.close()
    assert frame.shape == (height, width, 3) and frame.dtype == np.uint8


def test_render_after_close_raises():
    r = PlatformRenderer(BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, width=64, height=64)
    r.close()
    r.close()  # closing twice is harmless
    with pytest.raises(RuntimeError, match="close"):
        r.render(HOME, np.eye(3), np.zeros(6))


@pytest.mark.parametrize(
    "width, height", [(1, 1), (4, 4), (16, 16), (1, 4096), (4096, 1), (8, 480), (480, 8), (16, 480), (480, 16)]
)
def test_every_size_the_env_card_allows_renders(width, height):
    # The environment takes widths and heights from 1 to 4096 px: tiny and very thin frames have
    # no room for the margins and the text line, and the scene then fills the frame.
    r = PlatformRenderer(BASE_JOINTS, PLATFORM_JOINTS, HOME, FORCE_RANGE, width=width, height=height)
    frame = r.render(HOME, np.eye(3), np.zeros(6), text="t = 0.00 s")
    r.close()
    assert frame.shape == (height, width, 3) and frame.dtype == np.uint8
    if min(width, height) >= 8:  # a frame of a few pixels may fall on the background alone
        assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 2, "frame looks blank"
