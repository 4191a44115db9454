"""Matplotlib drawing of Stewart platform states.

Frames and units follow the rest of the package: {B} is the base frame fixed to the
ground, {P} the platform frame; lengths are in metres, forces in newtons.

The renderer builds one figure with one 3D axes and keeps its artists; every call to
:meth:`PlatformRenderer.render` only moves vertices and recolours legs. In
``"rgb_array"`` mode the figure is drawn on a private Agg canvas, so frames are produced
headless and independently of the global pyplot backend; ``"human"`` mode goes through
pyplot to get a window. Where no window can be opened (no display, a non-interactive
backend such as Agg, or a backend that fails), ``"human"`` mode warns once and draws
nothing, so that scripts and checkers run unchanged on headless machines.
"""

from __future__ import annotations

import os
import sys

import numpy as np
from gymnasium import logger
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LinearSegmentedColormap, Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from mpl_toolkits.mplot3d import proj3d
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

from stewart_env.envs.config import RENDER_MODES
from stewart_env.validation import integer

__all__ = ["PlatformRenderer", "LEG_FORCE_COLORMAP"]

# Backends that cannot open a window; "human" mode would silently draw nothing with them.
_NON_INTERACTIVE_BACKENDS = {"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"}
_DPI = 100
#: Leg force colours: saturated blue (the most negative force) through dark grey (no force) to
#: saturated red (the most positive, extending). No white centre, so a leg at holding force stays
#: visible on white.
LEG_FORCE_COLORMAP = LinearSegmentedColormap.from_list("leg_force", ["#1f5fbf", "#505050", "#c8102e"])
# Room kept in view for the platform's motion, as a fraction of the platform radius: above and
# below the home plate, and beside it.
_HEADROOM = 0.6
_SIDE_MARGIN = 0.1
_VIEW_ELEVATION, _VIEW_AZIMUTH = 30.0, -60.0
# Triad length as a fraction of the platform radius: long enough to read at 480 px.
_TRIAD_SCALE = 0.3
_TRIAD_COLOURS = ("tab:red", "tab:green", "tab:blue")
_LEG_WIDTH = 3.0
# A dark rim around every leg keeps its edge visible whatever its colour and background.
_LEG_OUTLINE_WIDTH = _LEG_WIDTH + 2.0
_LEG_OUTLINE_COLOUR = "#1a1a1a"
_TARGET_FACE = (0.3, 0.7, 0.3, 0.12)
_TARGET_EDGE = (0.1, 0.5, 0.1, 0.9)
_PLATFORM_FACE = (0.27, 0.51, 0.71, 0.6)
_COLORBAR_WIDTH_PX = 12.0
_FONT_SIZE = 8

# Whether the no-display warning was given: once per process, not once per environment.
_warned_no_display = False


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


def _warn_no_display(reason: str) -> None:
    global _warned_no_display
    if not _warned_no_display:
        _warned_no_display = True
        logger.warn(
            f"render_mode='human': no display is available ({reason}), so human rendering draws "
            "nothing and render() returns None; use render_mode='rgb_array' to get frames as arrays"
        )


def _open_window(figsize: tuple[float, float]) -> Figure | None:
    """A pyplot figure shown in a window, or None (after the warning) where none can be opened."""
    if not _display_available():
        _warn_no_display("neither DISPLAY nor WAYLAND_DISPLAY is set")
        return None
    import matplotlib.pyplot as plt  # only human mode may touch the global backend

    try:
        backend = plt.get_backend().lower()
    except Exception as exc:  # the configured GUI toolkit cannot be loaded
        _warn_no_display(f"matplotlib's backend failed to load: {exc}")
        return None
    if backend in _NON_INTERACTIVE_BACKENDS:
        _warn_no_display(f"matplotlib uses the non-interactive backend {backend!r}")
        return None
    fig = None
    try:
        fig = plt.figure(figsize=figsize, dpi=_DPI)
        plt.ion()
        fig.show()
    except Exception as exc:  # e.g. Tk's "couldn't connect to display" behind a stale DISPLAY
        if fig is not None:
            plt.close(fig)
        _warn_no_display(f"the {backend!r} backend could not open a window: {exc}")
        return None
    return fig


class PlatformRenderer:
    """Draws Stewart platform states to RGB arrays (headless) or a window.

    The scene shows the base polygon through the base joints, the six legs coloured by
    leg force (:data:`LEG_FORCE_COLORMAP`: blue = ``force_range[0]``, dark grey = 0, red =
    ``force_range[1]``) with a dark outline, the platform polygon with a triad of the {P}
    axes, an optional dashed ghost of a target pose (legend entry "target"), a colour bar
    of the leg force in N and an optional text line. The view is fixed at construction,
    fitted to the base and the home platform with room for the platform's motion, at
    equal scale on the three axes, so consecutive frames share one view.

    Args:
        base_joints: (6, 3) base joint positions b_i in {B} [m].
        platform_joints: (6, 3) platform joint positions p_i in {P} [m].
        home_position: (3,) position of the {P} origin in {B} at home [m]; with the base
            joints it fixes the view.
        force_range: (min, max) leg force [N] mapped to the ends of the colormap; forces
            outside it are shown with the end colours.
        width: frame width [px].
        height: frame height [px].
        render_mode: ``"rgb_array"`` to return frames, ``"human"`` to draw in a window
            (nothing, after a one-time warning, where no window can be opened).
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
        width, height = integer("width", width, 1, sys.maxsize), integer("height", height, 1, sys.maxsize)
        if render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES}, got {render_mode!r}")
        self.width, self.height = int(width), int(height)
        self.render_mode = render_mode
        self._closed = False

        # Platform radius measured in the {P} x-y plane, where the joints form the plate.
        self._radius = float(np.max(np.linalg.norm(self._platform_joints[:, :2], axis=1)))
        self._triad_length = _TRIAD_SCALE * self._radius

        figsize = (self.width / _DPI, self.height / _DPI)
        if render_mode == "rgb_array":
            self._fig = Figure(figsize=figsize, dpi=_DPI)
            FigureCanvasAgg(self._fig)
        else:
            self._fig = _open_window(figsize)
        if self._fig is not None:
            self._build_scene(home_position, Normalize(force_min, force_max))

    @property
    def draws(self) -> bool:
        """False in ``"human"`` mode where no window could be opened: render() draws nothing."""
        return self._fig is not None

    def _build_scene(self, home_position: np.ndarray, norm: Normalize) -> None:
        """Create the axes and every artist once; render() only updates their data."""
        fig = self._fig
        ax = fig.add_axes((0.0, 0.0, 1.0, 1.0), projection="3d")

        # The view holds the base and the home plate, with room for the platform's motion
        # around it; the box's aspect follows its extents, so the scale is equal on all three
        # axes. Orthographic, so that the zoom scales the picture linearly (see _fit_view).
        home_joints = home_position + self._platform_joints
        room = self._radius * np.array([_SIDE_MARGIN, _SIDE_MARGIN, _HEADROOM])
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * room
        self._view_points = np.vstack([self._base_joints, (home_joints[:, None, :] + corners).reshape(-1, 3)])
        low, high = self._view_points.min(axis=0), self._view_points.max(axis=0)
        ax.set_xlim(low[0], high[0])
        ax.set_ylim(low[1], high[1])
        ax.set_zlim(low[2], high[2])
        self._box_aspect = tuple(high - low)
        ax.set_proj_type("ortho")
        ax.view_init(elev=_VIEW_ELEVATION, azim=_VIEW_AZIMUTH)
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
            [home_joints], facecolors=_TARGET_FACE, edgecolors=_TARGET_EDGE, linewidths=1.5, linestyles="--", zorder=2
        )
        self._ghost.set_visible(False)
        ax.add_collection3d(self._ghost)

        segments = np.stack([self._base_joints, home_joints], axis=1)
        self._leg_outlines = Line3DCollection(
            segments, colors=_LEG_OUTLINE_COLOUR, linewidths=_LEG_OUTLINE_WIDTH, capstyle="round", zorder=3
        )
        ax.add_collection3d(self._leg_outlines)
        self._legs = Line3DCollection(
            segments, cmap=LEG_FORCE_COLORMAP, norm=norm, linewidths=_LEG_WIDTH, capstyle="round", zorder=3.1
        )
        self._legs.set_array(np.zeros(6))
        ax.add_collection3d(self._legs)

        self._platform = Poly3DCollection(
            [home_joints], facecolors=_PLATFORM_FACE, edgecolors="navy", linewidths=1.0, zorder=4
        )
        ax.add_collection3d(self._platform)

        self._triad = [ax.plot([], [], [], color=colour, linewidth=2.0, zorder=5)[0] for colour in _TRIAD_COLOURS]

        handles = [
            Patch(facecolor=_PLATFORM_FACE, edgecolor="navy", label="platform"),
            Patch(facecolor=_TARGET_FACE, edgecolor=_TARGET_EDGE, linestyle="--", label="target"),
        ]
        legend = fig.legend(
            handles=handles, loc="upper right", fontsize=_FONT_SIZE, frameon=False, handlelength=1.6, borderaxespad=0.3
        )

        bar_height = 0.45
        bar = (0.9, 0.5 * (1.0 - bar_height), _COLORBAR_WIDTH_PX / self.width, bar_height)
        cax = fig.add_axes(bar)
        ticks = np.linspace(norm.vmin, norm.vmax, 5)
        colorbar = fig.colorbar(self._legs, cax=cax, ticks=ticks, format="{x:g}")
        colorbar.set_label("leg force (N)", fontsize=_FONT_SIZE, labelpad=2)
        cax.tick_params(labelsize=_FONT_SIZE - 1, length=2, pad=1)
        # Fonts have a fixed pixel size, so on small frames the tick labels and the label
        # would run off the right edge: measure them once and slide the bar left until they fit.
        overflow_px = cax.get_tightbbox().x1 - (self.width - 3)
        cax.set_position((bar[0] - max(overflow_px, 0.0) / self.width, *bar[1:]))

        self._text = fig.text(0.02, 0.97, "", ha="left", va="top", fontsize=9, family="monospace")
        # The scene fills the frame left of the colour bar, below the text line and the legend.
        # Small frames have no room for the legend, and the scene keeps at least half the width.
        bar_box, legend_box = cax.get_tightbbox(), legend.get_window_extent()
        text_bottom = self.height - 2.2 * 9.0 * _DPI / 72.0
        if legend_box.y0 - 2.0 < 0.5 * self.height:
            legend.remove()
            static = [(cax, bar_box)]
            top = text_bottom
        else:
            static = [(cax, bar_box), (legend, legend_box)]
            top = min(text_bottom, legend_box.y0) - 2.0
        right = bar_box.x0 - 4.0
        if right < 0.5 * self.width:
            right, static = 0.5 * self.width, []  # the scene runs under the bar: draw the bar every frame
        region = (4.0, 4.0, right, top)
        if min(right, top) < 5.0:  # no room for margins below the text line: the scene fills the frame
            region = (0.0, 0.0, float(self.width), float(self.height))
        self._fit_view(ax, region)

        # Text is most of the cost of a frame, and the colour bar and the legend never change:
        # in rgb_array mode they are drawn once and their pixels pasted into every frame.
        self._static_pixels = []
        if self.render_mode == "rgb_array":
            fig.canvas.draw()
            for artist, box in static:
                self._static_pixels.append(fig.canvas.copy_from_bbox(box.padded(2.0)))
                artist.set_visible(False)

    def _fit_view(self, ax, region: tuple[float, float, float, float]) -> None:
        """Zoom and place the 3D axes so that the projected view points fill ``region``
        (left, bottom, right, top in pixels), centred in it.

        The axes is a large square (its artists are clipped at its edges, the frame's edges
        clip it instead); in an orthographic view, the picture scales linearly with the zoom
        about the axes' centre, so one measurement gives the zoom and the shift, and a second
        pass corrects the rounding of the first.
        """
        side = 2.0 * max(self.width, self.height)
        region_centre = np.array([0.5 * (region[0] + region[2]), 0.5 * (region[1] + region[3])])
        size = np.array([region[2] - region[0], region[3] - region[1]])
        axes_centre, zoom = region_centre, 1.0

        def place() -> None:
            ax.set_position(
                (
                    (axes_centre[0] - 0.5 * side) / self.width,
                    (axes_centre[1] - 0.5 * side) / self.height,
                    side / self.width,
                    side / self.height,
                )
            )
            ax.set_box_aspect(self._box_aspect, zoom=zoom)

        for _ in range(2):
            place()
            x, y, _ = proj3d.proj_transform(*self._view_points.T, ax.get_proj())
            pixels = ax.transData.transform(np.column_stack([x, y]))
            low, high = pixels.min(axis=0), pixels.max(axis=0)
            scale = float(np.min(size / (high - low)))
            zoom *= scale
            # Zooming moves the picture's centre away from the axes' centre by the same factor.
            axes_centre = region_centre - (0.5 * (low + high) - axes_centre) * scale
        place()

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
            None after updating the window (or drawing nothing where there is none).
        """
        if self._closed:
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
        if self._fig is None:  # human mode without a window: the inputs are checked, nothing drawn
            return None

        joints = position + self._platform_joints @ rotation.T  # P_i = t + R p_i, (6, 3)
        segments = np.stack([self._base_joints, joints], axis=1)
        self._legs.set_segments(segments)
        self._leg_outlines.set_segments(segments)
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
        for pixels in self._static_pixels:
            canvas.restore_region(pixels)
        rgba = np.asarray(canvas.buffer_rgba())
        return np.array(rgba[: self.height, : self.width, :3], dtype=np.uint8)

    def close(self) -> None:
        """Release the figure (and close the window in human mode); safe to call twice."""
        if self._closed:
            return
        if self.render_mode == "human" and self._fig is not None:
            import matplotlib.pyplot as plt

            plt.close(self._fig)
        self._fig = None
        self._closed = True
