"""Animations and time plots of a simulated trajectory (the manual's ``plotqqd``).

``animate`` draws the linkage with :func:`~sorojax.viz.plot_configuration` at every
video frame (with its contact obstacles where they are at that time, and optionally
the contact forces) and writes an mp4 (matplotlib's ffmpeg writer) or a GIF (Pillow);
``plot_time_series`` plots coordinates, velocities, the tip position or the energies
against time. Matplotlib is imported only inside the functions.
"""

import math
import numbers
import os
import pathlib
import warnings
from collections.abc import Sequence

import numpy as np

from ..io._files import as_path, check_target, writing
from ._plot import (
    _active_contacts,
    _check_force_scale,
    _default_force_scale,
    _draw_contact_forces,
    _draw_obstacles,
    _largest_extent,
    _plane_points,
    _scene_points,
    _set_equal_limits,
    plot_configuration,
    section_extents,
)

VIDEO_SUFFIXES = (".mp4", ".gif")
"""Suffixes :func:`animate` writes: ``.mp4`` needs ffmpeg, ``.gif`` uses Pillow."""

QUANTITIES = ("q", "qd", "tip", "energy")
"""Quantities :func:`plot_time_series` can plot."""

_N_PROFILE = 11  # section extents are sampled at this many X1 to pad the axis limits


# --------------------------------------------------------------------------- helpers
def _states(traj) -> tuple[np.ndarray, np.ndarray]:
    """Saved times and coordinates as NumPy, cut before the first non-finite state."""
    t = np.asarray(traj.t, dtype=float)
    q = np.asarray(traj.q, dtype=float)
    if t.ndim != 1 or q.ndim != 2 or q.shape[0] != t.shape[0]:
        raise ValueError(
            f"traj has t {t.shape} and q {q.shape}; animate takes one trajectory "
            "(t (n_save,), q (n_save, n_dof)): select a member of a vmapped batch "
            "with jax.tree.map(lambda x: x[i], traj)."
        )
    ok = np.isfinite(t) & np.all(np.isfinite(q), axis=1)
    n_ok = len(t) if ok.all() else int(np.argmin(ok))
    if n_ok == 0:
        raise ValueError(
            "the trajectory's first state is not finite: there is nothing to draw."
        )
    if n_ok < len(t):
        warnings.warn(
            f"the trajectory has non-finite states from t = {t[n_ok]:g} s on (the "
            f"integration failed: {traj.result!r}); animating up to "
            f"t = {t[n_ok - 1]:g} s only.",
            UserWarning,
            stacklevel=3,
        )
        t, q = t[:n_ok], q[:n_ok]
    if np.any(np.diff(t) < 0):
        raise ValueError("traj.t is not non-decreasing: save times must be sorted.")
    return t, q


def frame_times(t0: float, t1: float, fps: float, speed: float) -> np.ndarray:
    """Simulation times shown by the video frames [s].

    Frame ``k`` is shown at video time ``k / fps`` and draws simulation time
    ``t0 + k speed / fps``; there are ``floor((t1 - t0) / speed * fps) + 1`` frames
    (the first at ``t0``, the last within one frame of ``t1``).
    """
    duration = (t1 - t0) / speed
    n = int(math.floor(duration * fps + 1e-9)) + 1
    return t0 + np.arange(n) * (speed / fps)


def _interpolate_q(t: np.ndarray, q: np.ndarray, tf: np.ndarray) -> np.ndarray:
    """``q`` linearly interpolated in time at ``tf`` (clamped to the saved range)."""
    if len(t) == 1:
        return np.repeat(q, len(tf), axis=0)
    return np.stack([np.interp(tf, t, q[:, j]) for j in range(q.shape[1])], axis=1)


def _section_pad(linkage) -> float:
    """Largest distance from the rod axis to a section's outline [m]."""
    from ..model._link import RigidLink, SoftLink

    X1 = np.linspace(0.0, 1.0, _N_PROFILE)
    sections = []
    for link in linkage.links:
        if isinstance(link, SoftLink):
            sections += [div.section for div in link.divisions]
        elif isinstance(link, RigidLink):
            sections.append(link.section)
    pad = 0.0
    for section in sections:
        hy, hz = section_extents(section, X1)
        pad = max(pad, float(np.hypot(hy, hz).max()))
    return pad


def _motion_bounds(linkage, q_frames: np.ndarray) -> np.ndarray:
    """``(2, 3)`` lower/upper corners holding the linkage in every frame [m]."""
    from ..kinematics._api import forward_kinematics

    pts = np.concatenate(
        [np.asarray(forward_kinematics(linkage, q))[:, :3, 3] for q in q_frames]
    )
    pad = _section_pad(linkage)
    return np.stack([pts.min(axis=0) - pad, pts.max(axis=0) + pad])


def _video_target(path: pathlib.Path, overwrite: bool) -> tuple[pathlib.Path, str]:
    """The file actually written and the writer name (``"ffmpeg"`` or ``"pillow"``)."""
    from matplotlib import animation

    suffix = path.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise ValueError(
            f"{str(path)!r} has the suffix {path.suffix!r}: animate writes "
            f"{' or '.join(VIDEO_SUFFIXES)} (mp4 needs ffmpeg on the PATH)."
        )
    if suffix == ".gif":
        return path, "pillow"
    if animation.writers.is_available("ffmpeg"):
        return path, "ffmpeg"
    gif = path.with_suffix(".gif")
    check_target(gif, overwrite)
    warnings.warn(
        f"ffmpeg is not available to matplotlib, so {str(path)!r} cannot be written: "
        f"writing the GIF {str(gif)!r} instead. Install ffmpeg (e.g. apt-get install "
        "ffmpeg, or set matplotlib.rcParams['animation.ffmpeg_path']) for mp4.",
        UserWarning,
        stacklevel=3,
    )
    return gif, "pillow"


# ------------------------------------------------------------------------------ API
def animate(
    linkage,
    traj,
    path: str | os.PathLike,
    *,
    fps: float = 30,
    speed: float = 1.0,
    overwrite: bool = False,
    figsize: tuple[float, float] = (6.4, 4.8),
    dpi: float = 100,
    view: tuple[float, float] | None = None,
    obstacles: bool = True,
    contact_forces: bool | float = False,
    **plot_kwargs,
) -> pathlib.Path:
    """Write a video of a trajectory (the manual's ``plotqqd``).

    Frame ``k`` shows the linkage at simulation time ``t0 + k speed / fps``, with
    ``q`` interpolated linearly between the saved states, so the video plays at
    ``speed`` times real time: ``floor((t1 - t0) / speed * fps) + 1`` frames for a
    trajectory saved over ``[t0, t1]``. The axis limits are fixed and hold the whole
    motion; the title shows the time. States after a failed integration (non-finite)
    are left out with a warning.

    A linkage with contact is drawn with its obstacles, a moving obstacle where it is
    at the frame's time; planes are squares sized once from the whole motion (the
    linkage and the finite obstacles in every frame), as in
    :func:`~sorojax.viz.plot_configuration`. ``contact_forces`` draws the forces of
    :func:`~sorojax.contact_state` at each frame's ``q``, ``qd`` (both interpolated
    linearly) and time, at the active contacts, with one scale for the whole video.

    The format follows the suffix: ``.mp4`` through matplotlib's ffmpeg writer, or
    ``.gif`` through Pillow. If ``.mp4`` is asked for and ffmpeg is not available to
    matplotlib, the GIF is written next to it (same name, ``.gif``) with a
    ``UserWarning``; the returned path says which file was written. GIF frame delays
    are whole hundredths of a second: an ``fps`` dividing 100 (10, 20, 25, 50) plays
    at exactly real time / ``speed``, 30 plays about 10 % fast. Drawing costs about
    0.1 s per frame: lower ``fps`` or raise ``speed`` for long trajectories.

    Args:
        linkage: the :class:`~sorojax.Linkage` that was simulated.
        traj: its :class:`~sorojax.Trajectory` (t (n_save,) [s], q (n_save, n_dof)).
        path: the video file (``str`` or ``pathlib.Path``), ``.mp4`` or ``.gif``.
        fps: frames per second of the video [1/s].
        speed: simulated seconds per second of video (0.5 = slow motion).
        overwrite: replace an existing file; by default it is never touched.
        figsize: figure size [inch].
        dpi: resolution [dots per inch]; the frames are ``figsize * dpi`` pixels.
        view: ``(elev, azim)`` camera angles [deg] of the 3D axes, or None for
            matplotlib's default.
        obstacles: draw the obstacles of ``linkage.contact`` (if it has contact).
        contact_forces: draw the contact forces: False (none), True (the largest
            arrow of the video is 20 % of the largest extent of the motion and the
            obstacles) or a scale [m/N].
        **plot_kwargs: options of :func:`~sorojax.viz.plot_configuration`
            (``frames``, ``frame_scale``, ``n_circle``, ``show_points``, ``color``,
            ``n_sub``; not ``ax``, ``t`` or ``qd``, which animate sets).

    Returns:
        The path of the file written (``.gif`` in place of ``.mp4`` without ffmpeg).

    Raises:
        ValueError: unknown suffix; ``fps`` or ``speed`` not positive; ``traj`` not
            a single trajectory, unsorted or with a non-finite first state;
            ``contact_forces`` asked of a linkage without contact, or neither a bool
            nor a scale > 0.
        TypeError: ``plot_kwargs`` holds ``ax``, ``t`` or ``qd``.
        FileExistsError: the file exists and ``overwrite`` is False.
        FileNotFoundError: the folder of ``path`` does not exist.
    """
    import matplotlib.pyplot as plt
    from matplotlib import animation

    path = as_path(path)
    for name, value in (("fps", fps), ("speed", speed)):
        if not (isinstance(value, numbers.Real) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name} = {value!r}: give a positive number.")
    if "ax" in plot_kwargs:
        raise TypeError(
            "animate draws into its own figure: remove ax (use figsize, dpi, view)."
        )
    for name in ("t", "qd"):
        if name in plot_kwargs:
            raise TypeError(
                f"animate sets {name} at every frame from the trajectory: remove "
                f"{name}."
            )
    _check_force_scale(contact_forces)
    target, writer_name = _video_target(path, overwrite)
    check_target(target, overwrite)

    t, q = _states(traj)
    tf = frame_times(float(t[0]), float(t[-1]), float(fps), float(speed))
    qf = _interpolate_q(t, q, tf)
    bounds = _motion_bounds(linkage, qf)
    if plot_kwargs.get("frames", False) and plot_kwargs.get("frame_scale") is None:
        # Same arrow length in every frame (plot_configuration's default scales
        # with the drawing, which changes as the linkage moves).
        plot_kwargs["frame_scale"] = 0.1 * float((bounds[1] - bounds[0]).max())
    # One scene for the whole video: the planes' squares, the force scale and the
    # axis limits stay put while the linkage and the obstacles move.
    scene = _scene_points(linkage, bounds, tf) if obstacles else bounds
    pts = [scene]
    if obstacles:
        pts.append(_plane_points(linkage, scene, tf))
    contacts = []
    if contact_forces is not False:
        qd = getattr(traj, "qd", None)
        qdf = None if qd is None else _interpolate_q(t, np.asarray(qd)[: len(t)], tf)
        contacts = [
            _active_contacts(linkage, qf[k], None if qdf is None else qdf[k], tf[k])
            for k in range(len(tf))
        ]
        scale = (
            _default_force_scale(
                np.concatenate([f for _, f in contacts]), _largest_extent(scene)
            )
            if contact_forces is True
            else float(contact_forces)
        )
        pts += [p + scale * f for p, f in contacts]
    pts = np.concatenate(pts)
    bounds = np.stack([pts.min(axis=0), pts.max(axis=0)])

    fig = plt.figure(figsize=figsize, dpi=dpi)
    ax = fig.add_subplot(projection="3d")

    def draw(k: int):
        ax.cla()
        plot_configuration(linkage, qf[k], ax, obstacles=False, **plot_kwargs)
        if obstacles:
            n_circle = plot_kwargs.get("n_circle", 18)
            _draw_obstacles(ax, linkage, scene, t=float(tf[k]), n_circle=n_circle)
        if contacts:
            _draw_contact_forces(ax, *contacts[k], scale)
        _set_equal_limits(ax, bounds)
        if view is not None:
            ax.view_init(elev=view[0], azim=view[1])
        ax.set_title(f"t = {tf[k]:.3f} s")
        return ()

    try:
        anim = animation.FuncAnimation(
            fig, draw, frames=len(tf), interval=1000.0 / fps, blit=False, repeat=False
        )
        if writer_name == "ffmpeg":
            writer = animation.FFMpegWriter(fps=fps)
        else:
            writer = animation.PillowWriter(fps=fps)
        with writing(target, overwrite) as tmp:
            anim.save(tmp, writer=writer, dpi=dpi)
    finally:
        plt.close(fig)
    return target


def plot_time_series(
    traj,
    linkage=None,
    *,
    quantities: Sequence[str] = ("q",),
    ax=None,
):
    """Plot quantities of a trajectory against time, one axes per quantity.

    Quantities:

    - ``"q"``: the coordinates ``q_1 .. q_ndof`` (rad/m, rad or m by kind);
    - ``"qd"``: the velocities;
    - ``"tip"``: world position ``x, y, z`` [m] of the tip of the last link
      (needs ``linkage``);
    - ``"energy"``: kinetic, gravitational, elastic and their total [J] (needs
      ``linkage``; point wrenches and custom forces have no energy here, see
      :func:`sorojax.total_energy`).

    Args:
        traj: a :class:`~sorojax.Trajectory` (one, not a batch).
        linkage: the simulated :class:`~sorojax.Linkage`, for ``"tip"`` and
            ``"energy"``.
        quantities: names from ``("q", "qd", "tip", "energy")``, one axes each,
            stacked vertically with a shared time axis.
        ax: None for a new figure, or one 2D matplotlib axes per quantity (a single
            axes is taken for one quantity).

    Returns:
        The matplotlib ``Figure``.

    Raises:
        ValueError: unknown or repeated quantity, ``ax`` of the wrong length, or
            ``"tip"``/``"energy"`` without ``linkage``.
    """
    import matplotlib.pyplot as plt

    if isinstance(quantities, str):
        quantities = (quantities,)
    quantities = tuple(quantities)
    unknown = [x for x in quantities if x not in QUANTITIES]
    if unknown or not quantities or len(set(quantities)) != len(quantities):
        raise ValueError(
            f"quantities = {quantities!r}: give distinct names from {QUANTITIES}."
        )
    needs = [x for x in quantities if x in ("tip", "energy")]
    if needs and linkage is None:
        raise ValueError(
            f"quantities {needs} need the linkage: call "
            "plot_time_series(traj, linkage, quantities=...)."
        )
    t = np.asarray(traj.t, dtype=float)
    if t.ndim != 1:
        raise ValueError(
            f"traj.t has shape {t.shape}: plot one trajectory, not a vmapped batch "
            "(select one with jax.tree.map(lambda x: x[i], traj))."
        )

    if ax is None:
        fig, axes = plt.subplots(
            len(quantities),
            1,
            sharex=True,
            squeeze=False,
            figsize=(6.4, 2.4 * len(quantities) + 0.6),
            layout="constrained",
        )
        axes = list(axes[:, 0])
    else:
        axes = [ax] if not isinstance(ax, Sequence | np.ndarray) else list(ax)
        if len(axes) != len(quantities):
            raise ValueError(
                f"ax holds {len(axes)} axes for {len(quantities)} quantities: give "
                "one axes per quantity, or ax=None."
            )
        fig = axes[0].figure

    for name, a in zip(quantities, axes, strict=True):
        if name in ("q", "qd"):
            values = np.asarray(getattr(traj, name), dtype=float)
            sym = "q" if name == "q" else "\\dot q"
            labels = [f"${sym}_{{{j + 1}}}$" for j in range(values.shape[1])]
            ylabel = name
        elif name == "tip":
            values = np.asarray(traj.tip_positions(linkage))
            labels = ["x", "y", "z"]
            ylabel = "tip position [m]"
        else:
            values = np.asarray(traj.energies(linkage))
            labels = ["kinetic", "gravitational", "elastic", "total"]
            ylabel = "energy [J]"
        for j, label in enumerate(labels):
            a.plot(t, values[:, j], label=label)
        a.set_ylabel(ylabel)
        a.legend(
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            fontsize="small",
            ncol=max(1, math.ceil(len(labels) / 8)),
        )
        a.grid(True, alpha=0.3)
    axes[-1].set_xlabel("t [s]")
    return fig
