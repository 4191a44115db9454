"""Matplotlib drawing of Stewart platform states.

Frames and units follow the rest of the package: {B} is the base frame fixed to the
ground, {P} the platform frame; lengths are in metres, forces in newtons.

The renderer builds one figure with one 3D axes and keeps its artists; every call to
:meth:`PlatformRenderer.render` only moves vertices and recolours legs. In
``"rgb_array"`` mode the figure is drawn on a private Agg canvas, so frames are produced
headless and independently of the global pyplot backend; ``"human"`` mode goes through
pyplot to get a window.
"""

from __future__ import annotations

import os
import sys

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

__all__ = ["PlatformRenderer"]

_RENDER_MODES = ("rgb_array", "human")
# Backends that cannot open a window; "human" mode would silently draw nothing with them.
_NON_INTERACTIVE_BACKENDS = {"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"}
_DPI = 100
# Room around the geometry so the platform stays in view when it moves off home.
_VIEW_MARGIN = 1.15
_VIEW_ZOOM = 1.35
# Triad length as a fraction of the platform radius: long enough to read at 480 px.
_TRIAD_SCALE = 0.3
_COLORBAR_WIDTH_PX = 8.0
_TRIAD_COLOURS = ("tab:red", "tab:green", "tab:blue")


def _as_array(value, shape: tuple[int, ...], name: str) -> np.ndarray:
    """Return ``value`` as a finite float array of ``shape``, else raise ValueError naming it."""
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    return arr


def _display_available() -> bool:
    """Whether a window can be opened (only Linux/BSD need an X11 or Wayland display)."""
    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


class PlatformRenderer:
    """Draws Stewart platform states to RGB arrays (headless) or a window.

    The scene shows the base polygon through the base joints, the six legs coloured by
    leg force on a diverging colormap (blue = ``force_range[0]``, red =
    ``force_range[1]``), the platform polygon with a triad of the {P} axes, an optional
    dashed ghost of a target pose and an optional text line. Axis limits are fixed at
    construction, so consecutive frames share one view.

    Args:
        base_joints: (6, 3) base joint positions b_i in {B} [m].
        platform_joints: (6, 3) platform joint positions p_i in {P} [m].
        home_position: (3,) position of the {P} origin in {B} at home [m]; with the base
            joints it fixes the view limits.
        force_range: (min, max) leg force [N] mapped to the ends of the colormap; forces
            outside it are shown with the end colours.
        width: frame width [px].
        height: frame height [px].
        render_mode: ``"rgb_array"`` to return frames, ``"human"`` to draw in a window.
    """

    def __init__(
        self,
        base_joints: np.ndarray,
        platform_joints: np.ndarray,
        home_position: np.ndarray,
        force_range: tuple[float, float],
        width: int = 480,
        height: int = 480,
        render_mode: str = "rgb_array",
    ):
        self._base_joints = _as_array(base_joints, (6, 3), "base_joints")
        self._platform_joints = _as_array(platform_joints, (6, 3), "platform_joints")
        home_position = _as_array(home_position, (3,), "home_position")
        force_min, force_max = _as_array(force_range, (2,), "force_range")
        if not force_min < force_max:
            raise ValueError(f"force_range must be (min, max) with min < max, got {tuple(force_range)}")
        for name, size in (("width", width), ("height", height)):
            if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size <= 0:
                raise ValueError(f"{name} must be a positive integer number of pixels, got {size!r}")
        if render_mode not in _RENDER_MODES:
            raise ValueError(f"render_mode must be one of {_RENDER_MODES}, got {render_mode!r}")
        self.width, self.height = int(width), int(height)
        self.render_mode = render_mode

        # Platform radius measured in the {P} x-y plane, where the joints form the plate.
        radius = float(np.max(np.linalg.norm(self._platform_joints[:, :2], axis=1)))
        self._triad_length = _TRIAD_SCALE * radius

        self._fig = self._make_figure()
        self._build_scene(home_position, Normalize(force_min, force_max))

    def _make_figure(self) -> Figure:
        """Create the figure: a private Agg canvas, or a pyplot window in human mode."""
        figsize = (self.width / _DPI, self.height / _DPI)
        if self.render_mode == "rgb_array":
            fig = Figure(figsize=figsize, dpi=_DPI)
            FigureCanvasAgg(fig)
            return fig

        no_window = (
            "render_mode='human' needs a display to open a window, {reason}; "
            "use render_mode='rgb_array' to get frames as arrays instead"
        )
        if not _display_available():
            raise RuntimeError(no_window.format(reason="but neither DISPLAY nor WAYLAND_DISPLAY is set"))
        import matplotlib.pyplot as plt  # only human mode may touch the global backend

        backend = plt.get_backend().lower()
        if backend in _NON_INTERACTIVE_BACKENDS:
            raise RuntimeError(no_window.format(reason=f"but matplotlib uses the non-interactive backend {backend!r}"))
        plt.ion()
        fig = plt.figure(figsize=figsize, dpi=_DPI)
        fig.show()
        return fig

    def _build_scene(self, home_position: np.ndarray, norm: Normalize) -> None:
        """Create the axes and every artist once; render() only updates their data."""
        fig = self._fig
        ax = fig.add_axes((0.0, 0.0, 0.88, 1.0), projection="3d")

        # A cube around the base and the home platform, equal scale on all three axes.
        home_joints = home_position + self._platform_joints
        points = np.vstack([self._base_joints, home_joints])
        centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
        half = 0.5 * _VIEW_MARGIN * float(np.max(points.max(axis=0) - points.min(axis=0)))
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(centre[2] - half, centre[2] + half)
        # Zoom past the cube's own corners: with the axes hidden they are empty space.
        ax.set_box_aspect((1.0, 1.0, 1.0), zoom=_VIEW_ZOOM)
        ax.view_init(elev=25.0, azim=-55.0)
        # Ticks, panes and grid dominate the cost of a 3D draw and carry little here.
        ax.set_axis_off()
        # Fixed layering (base, ghost, legs, platform, triad) instead of per-frame depth
        # sorting, which lets the translucent plate hide the triad at some poses.
        ax.computed_zorder = False

        base = Poly3DCollection(
            [self._base_joints], facecolors="lightgrey", edgecolors="dimgrey", linewidths=1.0, zorder=1
        )
        ax.add_collection3d(base)

        self._ghost = Poly3DCollection(
            [home_joints], facecolors=(0.3, 0.7, 0.3, 0.12), edgecolors=(0.1, 0.5, 0.1, 0.8),
            linewidths=1.2, linestyles="--", zorder=2,
        )
        self._ghost.set_visible(False)
        ax.add_collection3d(self._ghost)

        segments = np.stack([self._base_joints, home_joints], axis=1)
        self._legs = Line3DCollection(segments, cmap=colormaps["coolwarm"], norm=norm, linewidths=3.0, zorder=3)
        self._legs.set_array(np.zeros(6))
        ax.add_collection3d(self._legs)

        self._platform = Poly3DCollection(
            [home_joints], facecolors=(0.27, 0.51, 0.71, 0.6), edgecolors="navy", linewidths=1.0, zorder=4
        )
        ax.add_collection3d(self._platform)

        self._triad = [ax.plot([], [], [], color=colour, linewidth=2.0, zorder=5)[0] for colour in _TRIAD_COLOURS]

        # The colorbar never changes, but it is cheap: one small image and a few ticks.
        bar = (0.9, 0.3, _COLORBAR_WIDTH_PX / self.width, 0.4)
        cax = fig.add_axes(bar)
        fig.colorbar(self._legs, cax=cax, ticks=[norm.vmin, 0.5 * (norm.vmin + norm.vmax), norm.vmax])
        cax.set_title("F [N]", fontsize=7)
        cax.tick_params(labelsize=6)
        # Fonts have a fixed pixel size, so on small frames the tick labels would run off
        # the right edge: measure them once and slide the bar left until they fit.
        overflow_px = cax.get_tightbbox().x1 - (self.width - 2)
        bar_left = bar[0] - max(overflow_px, 0.0) / self.width
        cax.set_position((bar_left, *bar[1:]))
        ax.set_position((0.0, 0.0, max(bar_left - 0.02, 0.1), 1.0))

        self._text = fig.text(0.02, 0.97, "", ha="left", va="top", fontsize=9, family="monospace")

    def render(
        self,
        position: np.ndarray,
        rotation: np.ndarray,
        leg_forces: np.ndarray,
        target_position: np.ndarray | None = None,
        target_rotation: np.ndarray | None = None,
        text: str = "",
    ) -> np.ndarray | None:
        """Draw one state.

        Args:
            position: (3,) position t of the {P} origin in {B} [m].
            rotation: (3, 3) rotation matrix R of {P} in {B} (columns are the {P} axes).
            leg_forces: (6,) axial leg forces [N], colour-mapped over ``force_range``.
            target_position: optional (3,) target position in {B} [m]; when given, the
                platform at the target pose is drawn as a dashed ghost.
            target_rotation: optional (3, 3) target rotation; identity if omitted while
                ``target_position`` is given.
            text: line shown at the top-left, e.g. ``"t = 1.23 s"``.

        Returns:
            In ``"rgb_array"`` mode a (height, width, 3) uint8 array; in ``"human"`` mode
            None after updating the window.
        """
        if self._fig is None:
            raise RuntimeError("PlatformRenderer.render called after close()")
        position = _as_array(position, (3,), "position")
        rotation = _as_array(rotation, (3, 3), "rotation")
        leg_forces = _as_array(leg_forces, (6,), "leg_forces")
        if target_position is None:
            if target_rotation is not None:
                raise ValueError("target_rotation was given without target_position")
            target_joints = None
        else:
            target_position = _as_array(target_position, (3,), "target_position")
            target_rotation = (
                np.eye(3) if target_rotation is None else _as_array(target_rotation, (3, 3), "target_rotation")
            )
            target_joints = target_position + self._platform_joints @ target_rotation.T

        joints = position + self._platform_joints @ rotation.T  # P_i = t + R p_i, (6, 3)
        self._legs.set_segments(np.stack([self._base_joints, joints], axis=1))
        self._legs.set_array(leg_forces)
        self._platform.set_verts([joints])

        # The triad sits on the plate (joint centroid) rather than at the {P} origin,
        # which may lie well off the plate; it shows orientation, not origin.
        centre = joints.mean(axis=0)
        for line, axis in zip(self._triad, rotation.T):
            tip = centre + self._triad_length * axis
            line.set_data_3d([centre[0], tip[0]], [centre[1], tip[1]], [centre[2], tip[2]])

        if target_joints is None:
            self._ghost.set_visible(False)
        else:
            self._ghost.set_verts([target_joints])
            self._ghost.set_visible(True)
        self._text.set_text(text)

        if self.render_mode == "human":
            import matplotlib.pyplot as plt

            self._fig.canvas.draw_idle()
            plt.pause(1e-3)  # runs the GUI event loop so the window repaints
            return None

        canvas = self._fig.canvas
        canvas.draw()
        rgba = np.asarray(canvas.buffer_rgba())
        return np.array(rgba[: self.height, : self.width, :3], dtype=np.uint8)

    def close(self) -> None:
        """Release the figure (and close the window in human mode); safe to call twice."""
        if self._fig is None:
            return
        if self.render_mode == "human":
            import matplotlib.pyplot as plt

            plt.close(self._fig)
        self._fig = None
