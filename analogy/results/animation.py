"""Animation: the mechanism moving beside its node voltages and, for nonlinear runs, its MP capacitances."""

from __future__ import annotations

import io
import logging
import re
import shutil
import textwrap
from dataclasses import dataclass
from html import escape
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import TYPE_CHECKING, Literal

import numpy as np
from matplotlib.figure import Figure

from ..files import write_figure, write_text, written
from ..errors import InputError

if TYPE_CHECKING:
    from matplotlib.animation import FuncAnimation

__all__ = ["Motion", "ANIMATION_FORMATS", "AnimationFormat", "VIEW", "check_animation_path", "offline"]

#: What an animation is written as, by the file's suffix.
AnimationFormat = Literal[".gif", ".mp4", ".html"]
ANIMATION_FORMATS: tuple[str, ...] = (".gif", ".mp4", ".html")
#: Capacitance traces drawn at most: the largest |c_ij| first (a 10-node arm has 45 MP models).
_MOST_TRACES = 6
#: Frames the tip's trail reaches back.
_TRAIL = 20
#: The view of a robot drawn in space: matplotlib's azimuth and elevation [degrees].
VIEW = (-60.0, 25.0)


@dataclass(frozen=True, eq=False)
class Motion:
    """One run seen as a motion: frames of the mechanism and the traces shown beside it.

    Attributes
    ----------
    title : str
        Robot, dynamics and solver.
    time : ndarray, shape (N,)
        The solver's time points.
    voltages : ndarray, shape (N, n)
        Node voltages (velocities) on them.
    nodes : list of str
        Node names.
    frame_times : ndarray, shape (F,)
        Times of the frames.
    outline : list of list of ndarray, or None
        Per frame, the link polylines (k, 2) in the robot's plane, or (k, 3) in space [m]; None: the
        nodes are drawn as masses on rails.
    displacements : ndarray, shape (F, n)
        Node positions x = ∫v dt at the frames (the rails' blocks when there is no outline).
    capacitances : ndarray, shape (F, n, n), or None
        M'(x) at the frames, for a circuit whose capacitances change (nonlinear runs).
    note : str
        What the drawing shows (its scale, its exaggeration).
    joint_axes : ndarray, shape (F, n, 2, 3), or None
        A robot drawn in space: each joint's axis at each frame, as a short segment through it.
    schematic : Schematic or None
        A linear circuit small enough to draw (:func:`analogy.circuit.diagram.schematic`), shown with
        its nodes coloured by their voltages and its parts by their currents.
    currents : ndarray, shape (F, parts), or None
        Each part of the schematic's current at the frames [A], in the order of ``schematic.parts``.
    current_peaks : ndarray, shape (parts,), or None
        Each part's largest |current| over the run's own points: the circles' scale.
    branches : ndarray, shape (F, n, n), or None
        A linear circuit too large for a schematic: at each frame, the current from node i to node j
        through the elements between them, and on the diagonal each node's current to ground.
    contacts : dict of str to ndarray, or None
        Each contact's normal force on the run's points [N] (``f_foot``): drawn in place of the
        capacitances, the one-sided current through the ground's contact.
    """

    title: str
    time: np.ndarray
    voltages: np.ndarray
    nodes: list
    frame_times: np.ndarray
    outline: list | None
    displacements: np.ndarray
    capacitances: np.ndarray | None = None
    note: str = ""
    joint_axes: np.ndarray | None = None
    schematic: object = None
    currents: np.ndarray | None = None
    current_peaks: np.ndarray | None = None
    branches: np.ndarray | None = None
    contacts: dict | None = None

    @property
    def spatial(self) -> bool:
        """Whether the mechanism is drawn in space (a URDF's tree) rather than in its plane."""
        return self.outline is not None and self.outline[0][0].shape[1] == 3

    def __repr__(self) -> str:
        drawn = "links" if self.outline is not None else "nodes on rails"
        varying = ", capacitances varying" if self.capacitances is not None else ""
        return (f"<Motion {self.title}: {len(self.frame_times)} frames over {self.frame_times[-1]:.3g} s, "
                f"{drawn}{varying}>")

    @property
    def frames(self) -> int:
        """Number of frames F."""
        return len(self.frame_times)

    def animation(self, fps: float = 15.0) -> "FuncAnimation":
        """The matplotlib animation of every frame, *fps* frames per second.

        Parameters
        ----------
        fps : float
            Frames per second.
        """
        from matplotlib.animation import FuncAnimation
        fig, update = _figure(self)
        return FuncAnimation(fig, update, frames=self.frames, interval=1000.0 / fps, blit=False)

    def save(self, path, fps: float = 15.0) -> Path:
        """Write the animation as GIF (pillow), MP4 (ffmpeg) or a self-contained HTML page.

        Parameters
        ----------
        path : str or Path
            Ends in .gif, .mp4 or .html.
        fps : float
            Frames per second.
        """
        path = Path(path)
        suffix = check_animation_path(path)
        anim = self.animation(fps)
        if suffix == ".html":
            write_text(path, _page(self.title, _player(anim, self.frames, fps)))
        elif suffix == ".gif":
            from matplotlib.animation import PillowWriter
            written(path, lambda tmp: anim.save(tmp, writer=PillowWriter(fps=fps)))
        else:
            from matplotlib.animation import FFMpegWriter
            written(path, lambda tmp: anim.save(tmp, writer=FFMpegWriter(
                fps=fps, codec="h264", extra_args=["-pix_fmt", "yuv420p"])))
        return path

    def to_jshtml(self, fps: float = 15.0) -> str:
        """The animation as HTML with its own player (JavaScript, frames embedded), for notebooks and pages.

        Parameters
        ----------
        fps : float
            Frames per second.
        """
        return _player(self.animation(fps), self.frames, fps)

    def _repr_html_(self) -> str:
        return self.to_jshtml()

    def frame_png(self, k: int, dpi: int = 100) -> bytes:
        """Frame *k* drawn as a PNG.

        Parameters
        ----------
        k : int
            Frame index (negative counts from the end).
        dpi : int
            Resolution.
        """
        fig, update = _figure(self)
        update(range(self.frames)[k])
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=dpi)
        return buffer.getvalue()

    def sheet(self, path=None, count: int = 3) -> Figure:
        """A contact sheet: *count* frames, evenly spread from the first to the last, side by side.

        Parameters
        ----------
        path : str or Path, optional
            Write it as PNG or SVG.
        count : int
            Frames shown.
        """
        import matplotlib.image as mpimg
        picks = np.unique(np.linspace(0, self.frames - 1, max(count, 1)).round().astype(int))
        images = [mpimg.imread(io.BytesIO(self.frame_png(int(k))), format="png") for k in picks]
        wide = images[0].shape[1] > 2.5 * images[0].shape[0]       # three panels: one frame a row
        sheet = Figure(figsize=(10.0, 3.3 * len(picks)) if wide else (5.0 * len(picks), 2.5), layout="constrained")
        panes = sheet.subplots(len(picks), 1, squeeze=False)[:, 0] if wide else \
            sheet.subplots(1, len(picks), squeeze=False)[0]
        for ax, k, image in zip(panes, picks, images):
            ax.imshow(image)
            ax.set_axis_off()
            ax.set_title(f"frame {k + 1} of {self.frames}, t = {self.frame_times[k]:.3g} s", fontsize=9)
        sheet.suptitle(self.title, fontsize=10)
        if path is not None:
            write_figure(sheet, path, dpi=160)
        return sheet


def check_animation_path(path) -> str:
    """The suffix of *path* if an animation can be written there; one sentence if not.

    Parameters
    ----------
    path : str or Path
        Where the animation goes.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in ANIMATION_FORMATS:
        raise InputError(f"cannot write an animation as {Path(path).name!r}: end the name in "
                         f"{', '.join(ANIMATION_FORMATS)}")
    if suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise InputError("an .mp4 needs ffmpeg, which is not installed (apt-get install ffmpeg): "
                         "write .gif or .html instead")
    return suffix


def _figure(motion: Motion):
    """The figure at frame 0 and ``update(k)``, which moves every artist to frame k."""
    varying = motion.capacitances is not None or motion.contacts is not None
    drawn = motion.schematic is not None or motion.branches is not None
    fig = Figure(figsize=(15.0 if drawn else 10.0, 4.6 if varying or drawn else 4.0), layout="constrained")
    grid = fig.add_gridspec(2 if varying else 1, 3 if drawn else 2,
                            width_ratios=(1.0, 1.6, 1.1) if drawn else (1.0, 1.25))
    arm = fig.add_subplot(grid[:, 0], projection="3d" if motion.spatial else None)
    volts = fig.add_subplot(grid[0, -1])
    glowing = (_draw_circuit if motion.schematic is not None else _draw_branches)(fig.add_subplot(grid[:, 1]), motion) \
        if drawn else (lambda k: [])
    draw = _draw_space if motion.spatial else _draw_outline if motion.outline is not None else _draw_rails
    moving = draw(arm, motion)
    cursors = [volts.axvline(0.0, color="0.3", lw=0.8)]
    peaks = np.max(np.abs(motion.voltages), axis=0) if motion.voltages.size else np.zeros(0)
    dots = []
    for j in _largest(peaks):
        # each over its own peak: a joint's rad/s and a mode's m/s differ by orders of magnitude
        scale = peaks[j] if peaks[j] > 0 else 1.0
        line, = volts.plot(motion.time, motion.voltages[:, j] / scale, lw=1.0,
                           label=f"v({motion.nodes[j]}), peak {peaks[j]:.3g}")
        dots.append((volts.plot([], [], "o", color=line.get_color(), ms=5)[0], motion.voltages[:, j] / scale))
    volts.set_xlabel("t [s]")
    volts.set_ylabel("velocity / its peak")
    volts.set_ylim(-1.15, 1.15)
    volts.legend(fontsize=7, loc="lower left", ncol=2)
    volts.set_title("node voltages (velocities), each over its own peak", fontsize=9)
    if varying:
        caps = fig.add_subplot(grid[1, 1], sharex=volts)
        cursors.append(caps.axvline(0.0, color="0.3", lw=0.8))
        (_draw_capacitances if motion.contacts is None else _draw_contacts)(caps, motion)
        volts.tick_params(labelbottom=False)
        volts.set_xlabel("")
    heading = fig.suptitle(motion.title, fontsize=10)

    def update(k: int):
        t = motion.frame_times[k]
        for cursor in cursors:
            cursor.set_xdata([t, t])
        for dot, values in dots:
            dot.set_data([t], [np.interp(t, motion.time, values)])
        heading.set_text(f"{motion.title}   t = {t:.3f} s")
        return moving(k) + glowing(k) + cursors + [d for d, _ in dots] + [heading]

    update(0)
    fig.draw_without_rendering()
    fig.set_layout_engine("none")       # laid out once: every frame has the same furniture
    return fig, update


def _largest(peaks: np.ndarray, most: int = _MOST_TRACES) -> list[int]:
    return sorted(np.argsort(-peaks, kind="stable")[:most].tolist())


def _draw_outline(ax, motion: Motion):
    frames = motion.outline
    every = np.concatenate([p for frame in frames for p in frame])
    low, high = every.min(axis=0), every.max(axis=0)
    middle, half = (low + high) / 2, max(float(np.max(high - low)) / 2, 1e-9) * 1.12
    ax.set_xlim(middle[0] - half, middle[0] + half)
    ax.set_ylim(middle[1] - half, middle[1] + half)
    ax.set_aspect("equal")
    ax.plot([0.0], [0.0], marker="^", ms=11, color="0.35", zorder=1)
    links = [ax.plot([], [], lw=3.0, solid_capstyle="round", color=f"C{i}")[0] for i in range(len(frames[0]))]
    joints = ax.plot([], [], "o", ms=6, mfc="white", mec="0.2", zorder=3)[0]
    tips = np.array([frame[-1][-1] for frame in frames])
    trail = ax.plot([], [], lw=0.8, color="0.6", zorder=0)[0]
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(motion.note or "the mechanism", fontsize=9)

    def moving(k: int):
        for line, points in zip(links, frames[k]):
            line.set_data(points[:, 0], points[:, 1])
        # a rigid link's polyline is its joints; a flexible one's many points are its bent shape
        ends = np.concatenate([p if len(p) <= 12 else p[[0, -1]] for p in frames[k]])
        joints.set_data(ends[:, 0], ends[:, 1])
        trail.set_data(tips[max(k - _TRAIL, 0):k + 1, 0], tips[max(k - _TRAIL, 0):k + 1, 1])
        return links + [joints, trail]
    return moving


def _draw_space(ax, motion: Motion):
    """The links as 3-D polylines with each joint's axis, in a cube around every frame, seen from :data:`VIEW`."""
    frames, axes = motion.outline, motion.joint_axes
    every = np.concatenate([p for frame in frames for p in frame])
    low, high = every.min(axis=0), every.max(axis=0)
    middle, half = (low + high) / 2, max(float(np.max(high - low)) / 2, 1e-9) * 1.05
    for set_limits, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), middle):
        set_limits(c - half, c + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.view_init(azim=VIEW[0], elev=VIEW[1])
    ax.plot([0.0], [0.0], [0.0], marker="s", ms=8, color="0.35")      # the base, held fixed
    links = [ax.plot([], [], [], lw=3.0, solid_capstyle="round", color=f"C{i}")[0] for i in range(len(frames[0]))]
    joints = ax.plot([], [], [], "o", ms=5, mfc="white", mec="0.2")[0]
    spins = [ax.plot([], [], [], lw=1.2, color="0.25")[0] for _ in range(0 if axes is None else axes.shape[1])]
    tips = np.array([frame[-1][-1] for frame in frames])
    trail = ax.plot([], [], [], lw=0.8, color="0.6")[0]
    for name, set_label in (("x", ax.set_xlabel), ("y", ax.set_ylabel), ("z", ax.set_zlabel)):
        set_label(f"{name} [m]", fontsize=8, labelpad=-2)
    ax.tick_params(labelsize=6, pad=0)
    ax.set_title(textwrap.fill(motion.note or "the robot", 48), fontsize=8)

    def moving(k: int):
        for line, points in zip(links, frames[k]):
            line.set_data_3d(points[:, 0], points[:, 1], points[:, 2])
        ends = np.concatenate([p[1:-1] for p in frames[k]])         # the joints: neither base nor tip
        joints.set_data_3d(ends[:, 0], ends[:, 1], ends[:, 2])
        for line, segment in zip(spins, [] if axes is None else axes[k]):
            line.set_data_3d(segment[:, 0], segment[:, 1], segment[:, 2])
        back = tips[max(k - _TRAIL, 0):k + 1]
        trail.set_data_3d(back[:, 0], back[:, 1], back[:, 2])
        return links + [joints, trail] + spins
    return moving


def _fit_labels(ax, box, inches_per_unit: float) -> None:
    """Labels that fit the panel: a schematic drawn under 0.7 of its own size (a wide one in the middle
    column) has its labels' font shrunk with the drawing, not under 6 pt, so they no longer overlap."""
    fig, spec = ax.figure, ax.get_subplotspec()
    ratios = spec.get_gridspec().get_width_ratios() or [1.0] * spec.get_gridspec().ncols
    share = sum(ratios[spec.colspan.start:spec.colspan.stop]) / sum(ratios)
    width, height = fig.get_size_inches()
    natural = ((box.xmax - box.xmin + 0.6) * inches_per_unit, (box.ymax - box.ymin + 0.6) * inches_per_unit)
    scale = min(0.9 * share * width / natural[0], 0.8 * height / natural[1], 1.0)
    if scale >= 0.7:
        return
    for text in ax.texts:
        text.set_fontsize(max(6.0, text.get_fontsize() * scale))


def _draw_circuit(ax, motion: Motion):
    """The schematic, each node bar coloured by its voltage over its own peak and each part marked by a
    circle sized by its current over its own peak (red positive, blue negative)."""
    from matplotlib import colormaps
    s = motion.schematic
    ax.set_axis_off()
    ax.set_aspect("equal")
    s.drawing.draw(show=False, canvas=ax)
    s.drawing.fig = None            # drawn again on the next figure (a frame, a sheet)
    box = s.drawing.get_bbox()
    ax.set_xlim(box.xmin - 0.3, box.xmax + 0.3)
    ax.set_ylim(box.ymin - 0.3, box.ymax + 0.3)
    _fit_labels(ax, box, s.drawing.dwgparams["inches_per_unit"])
    shades = colormaps["coolwarm"]
    peaks = np.max(np.abs(motion.voltages), axis=0) if motion.voltages.size else np.zeros(0)
    scaled = motion.voltages / np.where(peaks > 0, peaks, 1.0)
    bars = [ax.plot([xs, xe], [0.0, 0.0], lw=10, alpha=0.6, solid_capstyle="butt", zorder=0)[0]
            for xs, xe in s.bars]
    middles = np.array([[(a[0] + b[0]) / 2, (a[1] + b[1]) / 2] for a, b in s.parts.values()])
    glow = ax.scatter(middles[:, 0], middles[:, 1], s=np.zeros(len(middles)), alpha=0.45, zorder=0,
                      edgecolors="none")
    currents = motion.currents / np.where(motion.current_peaks > 0, motion.current_peaks, 1.0)

    def moving(k: int):
        t = motion.frame_times[k]
        for j, bar in enumerate(bars):
            bar.set_color(shades(0.5 + 0.5 * float(np.interp(t, motion.time, scaled[:, j]))))
        now = currents[k]
        glow.set_sizes(500.0 * np.abs(now))
        glow.set_color([shades(0.5 + 0.5 * np.sign(c)) for c in now])
        return bars + [glow]
    return moving


def _draw_branches(ax, motion: Motion):
    """The circuit's currents by node pair, each over its own peak over the frames (red +, blue −)."""
    b = motion.branches
    n = b.shape[1]
    peaks = np.max(np.abs(b), axis=0)
    scaled = b / np.where(peaks > 0, peaks, 1.0)
    image = ax.imshow(scaled[0], cmap="coolwarm", vmin=-1.0, vmax=1.0)
    ticks = range(0, n, max(1, n // 10))
    ax.set_xticks(list(ticks), [f"n{k + 1}" for k in ticks], fontsize=7)
    ax.set_yticks(list(ticks), [f"n{k + 1}" for k in ticks], fontsize=7)
    ax.set_title("current from node i to node j (diagonal: to ground), each over its own peak", fontsize=8)
    ax.figure.colorbar(image, ax=ax, shrink=0.7, label="current / its peak")

    def moving(k: int):
        image.set_data(scaled[k])
        return [image]
    return moving


def _draw_rails(ax, motion: Motion):
    x = motion.displacements
    n = x.shape[1]
    peaks = np.max(np.abs(x), axis=0)
    scaled = x / np.where(peaks > 0, peaks, 1.0)
    for i in range(n):
        ax.axhline(i, color="0.8", lw=1.0, zorder=0)
    blocks = ax.plot(scaled[0], np.arange(n), "s", ms=14, mfc="C0", mec="0.2")[0]
    ax.set_xlim(-1.25, 1.25)
    ax.set_ylim(-0.8, n - 0.2)
    ax.set_yticks(range(n), [f"{name}\n(peak {p:.2g})" for name, p in zip(motion.nodes, peaks)], fontsize=7)
    ax.set_xlabel("node position x = ∫v dt, over its own peak")
    ax.set_title(motion.note or "each node a mass on its rail", fontsize=9)

    def moving(k: int):
        blocks.set_data(scaled[k], np.arange(n))
        return [blocks]
    return moving


def _draw_capacitances(ax, motion: Motion) -> None:
    m = motion.capacitances
    n = m.shape[1]
    upper = [(i, j) for i in range(n) for j in range(i + 1, n)]
    floating = np.array([-m[:, i, j] for i, j in upper]).T if upper else np.zeros((len(m), 0))
    for k in _largest(np.max(np.abs(floating), axis=0) if upper else np.zeros(0)):
        i, j = upper[k]
        ax.plot(motion.frame_times, floating[:, k], lw=1.4, label=f"c{i + 1}{j + 1} (MP)")
    grounded = m.sum(axis=2)
    for i in _largest(np.max(np.abs(grounded), axis=0), 3):
        ax.plot(motion.frame_times, grounded[:, i], ls="--", lw=1.0, label=f"C{i + 1} (to ground)")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("capacitance = mass")
    ax.set_title("MP capacitances c_ij = -M'_ij change with the pose", fontsize=9)
    ax.legend(fontsize=7, loc="upper right", ncol=2)


def _draw_contacts(ax, motion: Motion) -> None:
    for name, force in motion.contacts.items():
        ax.plot(motion.time, force, lw=1.2, label=name)
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("force [N]")
    ax.set_title("contact forces: the ground's one-sided current, zero in flight", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")


#: The player's buttons as text: matplotlib's player fetches an icon font from the web for them.
_GLYPHS = {"fast-backward": "&#8676;", "step-backward": "&#9665;", "play fa-flip-horizontal": "&#9664;",
           "pause": "&#10074;&#10074;", "play": "&#9654;", "step-forward": "&#9655;",
           "fast-forward": "&#8677;", "minus": "&minus;", "plus": "+"}


#: The most a page embeds [MB]: 2,000 frames of an arm take about 170 MB.
_MOST_PAGE_MB = 512
_EMBEDDED = re.compile(r'^\s*frames\[\d+\] = "data:image/', re.MULTILINE)


def _player(anim: "FuncAnimation", frames: int, fps: float) -> str:
    """Matplotlib's HTML player of every one of the *frames*, offline, or one sentence.

    ``to_jshtml`` drops frames past ``animation.embed_limit`` (20 MB by default) with only a
    log line: the page's own limit is the stated maximum, and a page that would lose a frame
    is refused.
    """
    from matplotlib.animation import HTMLWriter
    with TemporaryDirectory() as folder:
        path = Path(folder, "player.html")
        writer = HTMLWriter(fps=fps, embed_frames=True, default_mode="loop", embed_limit=_MOST_PAGE_MB)
        logger = logging.getLogger("matplotlib.animation")
        level = logger.level
        logger.setLevel(logging.ERROR)     # its note on dropped frames becomes the sentence below
        try:
            anim.save(str(path), writer=writer)
        finally:
            logger.setLevel(level)
        player = path.read_text()
    if (kept := len(_EMBEDDED.findall(player))) != frames:
        raise InputError(f"a page of {frames:,} frames would embed more than {_MOST_PAGE_MB} MB (only {kept:,} fit): "
                         "ask for fewer frames or write .gif or .mp4")
    return offline(player)


def offline(player: str) -> str:
    """Matplotlib's HTML player with no address outside the page: its icon-font link dropped,
    its buttons labelled by characters.

    Parameters
    ----------
    player : str
        ``FuncAnimation.to_jshtml()``.
    """
    player = re.sub(r"<link[^>]*font-awesome[^>]*>", "", player)
    return re.sub(r'<i class="fa fa-([a-z -]+)"></i>', lambda m: _GLYPHS.get(m.group(1), m.group(1)), player)


def _page(title: str, body: str) -> str:
    return (f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>{escape(title)}</title></head>"
            f"<body><h3>{escape(title)}</h3>\n{body}\n</body></html>\n")
