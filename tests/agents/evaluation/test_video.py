"""Videos of the platform under a cueing policy (``stewart_env.agents.evaluation.video``): a
3-frame clip rendered, written as GIF and MP4, and read back."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from PIL import Image

from stewart_env.agents.controllers.washout import WashoutPolicy
from stewart_env.agents.evaluation.video import cueing_frames, manoeuvre_start, write_cueing_video, write_video
from stewart_env.cli import main
from stewart_env.errors import UsageError
from stewart_env.tasks.cueing.motions import EVALUATION_SEEDS, make_motion

HAS_FFMPEG = importlib.util.find_spec("imageio_ffmpeg") is not None


@pytest.fixture(scope="module")
def frames():
    # 3 frames: t = 0.5, 0.54, 0.58 s at 25 fps (every 4th control step of 10 ms)
    return cueing_frames(
        lambda env: WashoutPolicy(env, "washout"), {"action_mode": "pose"}, start=0.5, seconds=0.08, size=64
    )


def test_a_clip_has_one_frame_per_period(frames):
    assert len(frames) == 3
    assert all(f.shape == (64, 64, 3) and f.dtype == np.uint8 for f in frames)
    assert not np.array_equal(frames[0], frames[-1])  # the platform moves between them


def test_gif_round_trip(frames, tmp_path):
    path = write_video(frames, tmp_path / "clip.gif", fps=25)
    with Image.open(path) as gif:
        assert gif.n_frames == 3
        assert gif.info["duration"] == 40  # ms per frame at 25 fps


@pytest.mark.skipif(not HAS_FFMPEG, reason="MP4 needs imageio-ffmpeg (the extra video)")
def test_mp4_round_trip(frames, tmp_path):
    import imageio.v2 as imageio

    path = write_video(frames, tmp_path / "clip.mp4", fps=25)
    back = imageio.mimread(path)
    assert len(back) == 3
    assert back[0].shape == (64, 64, 3)
    # H.264 at constant quality 28 is lossy: the mean error of a frame stays a few grey levels
    assert np.abs(back[0].astype(float) - frames[0]).mean() < 8.0


def test_the_clip_starts_before_the_track():
    motion = make_motion("double_lane_change", EVALUATION_SEEDS[0])
    assert manoeuvre_start("double_lane_change", EVALUATION_SEEDS[0]) == pytest.approx(
        max(0.0, motion.meta["lead"] / motion.meta["speed"] - 0.5)
    )
    assert manoeuvre_start("sweep_x", EVALUATION_SEEDS[0]) == 0.0  # no track


@pytest.mark.parametrize(
    "kwargs, argument",
    [({"seconds": 0.0}, "seconds"), ({"start": -1.0}, "start"), ({"fps": float("nan")}, "fps"), ({"size": 8}, "size")],
)
def test_bad_clip_arguments_are_named(kwargs, argument):
    with pytest.raises(UsageError, match=argument):
        cueing_frames(lambda env: WashoutPolicy(env, "washout"), {"action_mode": "pose"}, **kwargs)


def test_write_video_refuses_another_format_and_no_frames(frames, tmp_path):
    with pytest.raises(UsageError, match="path.*suffix must be one of .mp4, .gif"):
        write_video(frames, tmp_path / "clip.avi")
    with pytest.raises(UsageError, match="frames.*no frames"):
        write_video([], tmp_path / "clip.gif")


def test_write_cueing_video_starts_before_the_track_by_default(tmp_path):
    path, frames, start = write_cueing_video(
        lambda env: WashoutPolicy(env, "washout"), {"action_mode": "pose"}, tmp_path / "clip.gif", seconds=0.08, size=64
    )
    assert (path, frames) == (tmp_path / "clip.gif", 3)
    assert start == manoeuvre_start("double_lane_change", EVALUATION_SEEDS[0])


def test_the_command_writes_the_video(tmp_path, capsys):
    path = tmp_path / "clip.mp4" if HAS_FFMPEG else tmp_path / "clip.gif"
    assert main(["evaluate", "--task", "cueing", "--video", str(path)]) == 0
    out = capsys.readouterr().out
    assert "washout: 176 frames from t = " in out  # 7 s at 25 frames per second, both ends
    assert path.stat().st_size > 1000


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--video", "v.mp4"], "argument --video: the video shows a cueing episode: give --task cueing"),
        (["--task", "cueing", "--video", "v.mp4", "--omct"], "argument --video: give --video or --omct, not both"),
        (
            ["--task", "cueing", "--video", "v.gif", "--model", "classical", "improved"],
            "argument --video: give one --model",
        ),
        (["--task", "cueing", "--video", "v.avi"], "expected a .mp4 or .gif file, got 'v.avi'"),
        (["--task", "cueing", "--video", "/proc/no/v.gif"], "argument --video: "),
    ],
)
def test_bad_video_options_are_one_line_errors(argv, message, capsys):
    try:
        status = main(["evaluate", *argv])
    except SystemExit as exit_:  # argparse's own errors
        status = exit_.code
    assert status != 0
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err
