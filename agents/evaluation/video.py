"""A video of the platform under a cueing policy: the environment's ``render_mode="rgb_array"``
frames of one scheduled cueing episode, written as MP4 or as an animated GIF.

:func:`cueing_frames` runs a policy on one (motion, seed) episode of the cueing task and keeps
the frames of a window of it, one every ``1 / fps`` seconds of simulated time;
:func:`write_video` writes frames as MP4 (H.264, through imageio and imageio-ffmpeg, the extra
``video``) or as an animated GIF (through Pillow, which matplotlib already needs), by the path's
suffix; :func:`write_cueing_video` does both.  From a shell, the tuned washout on the first
held-out double lane change, from half a second before the track for 7 s::

    stewart-env evaluate --task cueing --video docs/figures/cueing/video.mp4
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from stewart_env.errors import UsageError

__all__ = ["VIDEO_SUFFIXES", "cueing_frames", "manoeuvre_start", "write_cueing_video", "write_video"]

#: The formats :func:`write_video` writes, by suffix.
VIDEO_SUFFIXES = (".mp4", ".gif")


def manoeuvre_start(motion_name: str, seed: int) -> float:
    """When a driving manoeuvre's track begins, s: the straight before it over the speed, less
    half a second of approach (0 for a motion without them in its record).

    Args:
        motion_name: a built-in motion's name.
        seed: its seed.

    Returns:
        The time, s, at least 0.
    """
    from stewart_env.tasks.cueing.motions import make_motion

    meta = make_motion(motion_name, seed).meta
    if "lead" not in meta or "speed" not in meta:
        return 0.0
    return max(0.0, meta["lead"] / meta["speed"] - 0.5)


def cueing_frames(
    policy,
    env_kwargs: dict | None = None,
    motion: tuple[str, int] = ("double_lane_change", 2**30),
    start: float = 0.0,
    seconds: float = 6.0,
    fps: float = 25.0,
    size: int = 480,
) -> list[np.ndarray]:
    """The rendered frames of one cueing episode between ``start`` and ``start + seconds``.

    Args:
        policy: an object with SB3's ``predict``, or a callable env -> such an object.
        env_kwargs: the environment's keywords besides ``task`` and ``render_mode``
            (``{"action_mode": "pose"}`` for washout); ``task_options`` without ``motions``.
        motion: the (built-in motion name, seed) episode played.
        start: the first frame's time in the episode, s.
        seconds: the clip's length, s (> 0).
        fps: frames per second of simulated time (at most one per control step).
        size: the frames' width and height, px.

    Returns:
        The (size, size, 3) uint8 frames, in order; fewer than ``seconds * fps`` when the
        episode ends first (its motion, or the platform's limits).

    Raises:
        UsageError: a negative ``start``, a non-positive ``seconds``, ``fps`` or ``size``, or an
            unknown motion (named ``motion``).
    """
    import gymnasium as gym

    from stewart_env.registration import ENV_ID

    for name, value, low in (("start", start, 0.0), ("seconds", seconds, None), ("fps", fps, None)):
        ok = (
            isinstance(value, (int, float))
            and math.isfinite(value)
            and (value >= low if low is not None else value > 0)
        )
        if not ok:
            raise UsageError.about(
                name, f"must be a finite {'non-negative' if low is not None else 'positive'} number, got {value!r}"
            )
    if isinstance(size, bool) or not isinstance(size, int) or size < 16:
        raise UsageError.about("size", f"must be an integer number of pixels >= 16, got {size!r}")
    kwargs = dict(env_kwargs or {})
    options = {**kwargs.pop("task_options", {}), "motions": (motion[0],)}
    try:
        env = gym.make(
            ENV_ID,
            task="cueing",
            task_options=options,
            render_mode="rgb_array",
            width=size,
            height=size,
            max_episode_steps=10**7,
            **kwargs,
        )
    except UsageError as err:
        raise UsageError.about("motion", f"{motion!r}: {err}") from err
    try:
        env.unwrapped.task.schedule([motion])
        dt = env.unwrapped.dt
        every = max(1, int(round(1.0 / (fps * dt))))
        first, last = int(round(start / dt)), int(round((start + seconds) / dt))
        agent = policy(env) if callable(policy) and not hasattr(policy, "predict") else policy
        if callable(getattr(agent, "reset", None)):
            agent.reset()
        obs, _ = env.reset(seed=0)
        frames = []
        for k in range(last + 1):
            if k >= first and (k - first) % every == 0:
                frames.append(np.asarray(env.render()))
            if k == last:
                break
            action, _ = agent.predict(obs, deterministic=True)
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        return frames
    finally:
        env.close()


def write_video(frames: Sequence[np.ndarray], path, fps: float = 25.0) -> Path:
    """Write frames as a video: MP4 (H.264, yuv420p, through imageio-ffmpeg) or an animated GIF
    (Pillow), by the path's suffix.

    Args:
        frames: (H, W, 3) uint8 frames, at least one, all of one shape (even H and W for MP4).
        path: the file, ``.mp4`` or ``.gif``.
        fps: frames per second.

    Returns:
        The path written.

    Raises:
        UsageError: no frames, another suffix, or MP4 without imageio-ffmpeg (named ``path``).
    """
    path = Path(path)
    if not frames:
        raise UsageError.about("frames", "no frames to write")
    suffix = path.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise UsageError.about("path", f"{str(path)!r}: the suffix must be one of {', '.join(VIDEO_SUFFIXES)}")
    path.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".gif":
        from PIL import Image

        images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
        # GIF stores delays in hundredths of a second
        images[0].save(path, save_all=True, append_images=images[1:], duration=int(round(1000.0 / fps)), loop=0)
        return path
    try:
        import imageio.v2 as imageio
        import imageio_ffmpeg  # noqa: F401  (the MP4 writer's ffmpeg)
    except ImportError as err:
        raise UsageError.about(
            "path", f'{str(path)!r}: MP4 needs imageio and imageio-ffmpeg (pip install -e ".[video]"), or write a .gif'
        ) from err
    # yuv420p and a constant quality: the H.264 that browsers play, small for a few seconds of
    # a mostly white scene
    with imageio.get_writer(
        path,
        fps=fps,
        codec="libx264",
        pixelformat="yuv420p",
        quality=None,
        macro_block_size=16,
        ffmpeg_params=["-crf", "28", "-preset", "slow"],
        ffmpeg_log_level="error",
    ) as writer:
        for frame in frames:
            writer.append_data(np.asarray(frame, dtype=np.uint8))
    return path


def write_cueing_video(
    policy,
    env_kwargs: dict | None,
    path,
    motion: tuple[str, int] | None = None,
    start: float | None = None,
    seconds: float = 7.0,
    fps: float = 25.0,
    size: int = 480,
) -> tuple[Path, int, float]:
    """Render a policy on one cueing episode (:func:`cueing_frames`) and write the video
    (:func:`write_video`).

    Args:
        policy: an object with SB3's ``predict``, or a callable env -> such an object.
        env_kwargs: the environment's keywords besides ``task`` and ``render_mode``.
        path: the video file, ``.mp4`` or ``.gif``.
        motion: the (built-in motion, seed) episode (default the double lane change at the first
            held-out seed).
        start: the clip's start, s (default :func:`manoeuvre_start`: half a second before the track).
        seconds: the clip's length, s.
        fps: frames per second.
        size: width and height, px.

    Returns:
        (the path written, the frames, the start in s).

    Raises:
        UsageError: a bad argument, named (see :func:`cueing_frames` and :func:`write_video`).
    """
    from stewart_env.tasks.cueing.motions import EVALUATION_SEEDS

    motion = ("double_lane_change", EVALUATION_SEEDS[0]) if motion is None else motion
    if start is None:
        start = manoeuvre_start(*motion)
    frames = cueing_frames(policy, env_kwargs, motion, start, seconds, fps, size)
    return write_video(frames, path, fps), len(frames), start
