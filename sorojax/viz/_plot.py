"""3D plots of a linkage configuration (the manual's ``plotq`` and ``plotq0``).

Soft links are drawn as tubes that follow the rod poses, with the link's real
cross-section (circle, rectangle or ellipse, tapered or not) in the local y-z plane of
every pose; rigid links as prisms of their section placed with the centre-of-mass
pose. Coordinate frames (local x, y, z as red, green, blue arrows) can be added at the
joint frames and the tips.

Matplotlib is imported only inside the functions, so importing :mod:`sorojax` (or
even :mod:`sorojax.viz`) never imports it.

Every artist drawn here carries a ``gid`` and, for the bodies, the world-frame
geometry it was built from, so that programs and tests can inspect what was drawn:

- ``"sorojax-link{i}-division{k}"``: the tube of division ``k`` of soft link ``i``
  (a ``Poly3DCollection``), with attributes ``sorojax_rings`` (``(n_rings, n_outline,
  3)`` section outlines), ``sorojax_centres`` (``(n_rings, 3)`` rod axis points) and
  ``sorojax_X1`` (``(n_rings,)`` normalised positions in the division);
- ``"sorojax-link{i}-body"``: the prism of rigid link ``i``, with the same attributes
  (two rings, at the two ends of the body);
- ``"sorojax-frames-x"``, ``"-y"``, ``"-z"``: the frame arrows (quivers), with
  ``sorojax_origins`` and ``sorojax_vectors`` (``(n_frames, 3)`` each);
- ``"sorojax-points"``: the significant points (``show_points=True``).
"""

import math

import numpy as np

from ..model._layout import JOINT, TIP
from ..model._link import RigidLink, SoftLink
from ..model._section import RectangularSection

_FRAME_COLORS = ("tab:red", "tab:green", "tab:blue")


# --------------------------------------------------------------------------- helpers
def _scalar(x) -> float:
    return float(np.asarray(x, dtype=float))


_EXTENT_CHUNK = 64
"""X1 points per call of a section's ``extent`` in :func:`section_extents`."""


def section_extents(section, X1) -> tuple[np.ndarray, np.ndarray]:
    """Half-widths ``(along y, along z)`` [m] of ``section`` at the points ``X1``.

    ``section.extent`` is called on chunks of :data:`_EXTENT_CHUNK` points (the last
    padded), where one call per point ran its few eager operations each time (0.4 s
    for the manual hybrid's figure); one array size, so each eager operation
    compiles once per process. A custom profile that does not take an array of X1
    (a Python ``if``, say) is evaluated point by point, as before.
    """
    X1 = np.asarray(X1, dtype=float).reshape(-1)
    m = X1.shape[0]
    padded = np.pad(X1, (0, -m % _EXTENT_CHUNK), mode="edge")
    try:
        parts = [
            [
                np.broadcast_to(np.asarray(v, dtype=float), chunk.shape)
                for v in section.extent(chunk)
            ]
            for chunk in padded.reshape(-1, _EXTENT_CHUNK)
        ]
        hy, hz = (np.concatenate(h)[:m] for h in zip(*parts, strict=True))
    except Exception:  # noqa: BLE001 - a scalar-only profile: point by point
        hy, hz = np.array(
            [[_scalar(v) for v in section.extent(float(x))] for x in X1]
        ).T.reshape(2, m)
    return hy, hz


def _outlines(section, X1, n_circle: int) -> np.ndarray:
    """Section outlines at the points ``X1`` as local ``(y, z)`` points ``(m, n, 2)``.

    A rectangle gives its four corners; any other section an ellipse of ``n_circle``
    points with the section's half-widths (a circle for a circular section).
    """
    hy, hz = section_extents(section, X1)
    if isinstance(section, RectangularSection):
        corners = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
        return corners * np.stack([hy, hz], axis=-1)[:, None, :]
    theta = 2.0 * np.pi * np.arange(n_circle) / n_circle
    return np.stack([hy[:, None] * np.cos(theta), hz[:, None] * np.sin(theta)], axis=-1)


def _ring(g: np.ndarray, yz: np.ndarray) -> np.ndarray:
    """World points of a local ``(y, z)`` outline placed in the y-z plane of ``g``."""
    return g[:3, 3] + yz[:, :1] * g[:3, 1] + yz[:, 1:] * g[:3, 2]


def _hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _so3_exp(w: np.ndarray) -> np.ndarray:
    th = float(np.linalg.norm(w))
    W = _hat(w)
    if th < 1e-12:
        return np.eye(3) + W
    return np.eye(3) + math.sin(th) / th * W + (1.0 - math.cos(th)) / th**2 * (W @ W)


def _so3_log(R: np.ndarray) -> np.ndarray:
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    th = math.acos(c)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    if th < 1e-9:
        return v
    if math.pi - th < 1e-6:
        # Near a half turn: the axis is the dominant column of (R + I) / 2.
        B = (R + np.eye(3)) / 2.0
        k = int(np.argmax(np.diag(B)))
        axis = B[:, k] / math.sqrt(max(B[k, k], 1e-300))
        return th * axis / np.linalg.norm(axis)
    return th / math.sin(th) * v


def _interpolate(g0: np.ndarray, g1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Poses between ``g0`` and ``g1`` at fractions ``s`` (exclusive of the ends).

    Positions follow a cubic Hermite curve whose end tangents are the local x axes,
    of length ``chord / cos^2(phi / 4)`` with ``phi`` the angle between them (the
    best cubic fit of a circular arc); orientations rotate uniformly about the
    relative axis.
    """
    p0, p1 = g0[:3, 3], g1[:3, 3]
    chord = float(np.linalg.norm(p1 - p0))
    phi = math.acos(float(np.clip(g0[:3, 0] @ g1[:3, 0], -1.0, 1.0)))
    scale = chord / max(math.cos(phi / 4.0) ** 2, 0.5)
    m0, m1 = scale * g0[:3, 0], scale * g1[:3, 0]
    w = _so3_log(g0[:3, :3].T @ g1[:3, :3])
    out = np.empty((len(s), 4, 4))
    for k, t in enumerate(s):
        h00 = 2 * t**3 - 3 * t**2 + 1
        h10 = t**3 - 2 * t**2 + t
        h01 = -2 * t**3 + 3 * t**2
        h11 = t**3 - t**2
        out[k] = np.eye(4)
        out[k, :3, :3] = g0[:3, :3] @ _so3_exp(t * w)
        out[k, :3, 3] = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
    return out


def _densify(g: np.ndarray, X1: np.ndarray, n_sub: int):
    """Insert ``n_sub - 1`` interpolated poses between consecutive rod points."""
    if n_sub <= 1 or len(X1) < 2:
        return g, X1
    s = np.arange(1, n_sub) / n_sub
    gs, xs = [g[:1]], [X1[:1]]
    for j in range(len(X1) - 1):
        gs.append(_interpolate(g[j], g[j + 1], s))
        xs.append(X1[j] + s * (X1[j + 1] - X1[j]))
        gs.append(g[j + 1 : j + 2])
        xs.append(X1[j + 1 : j + 2])
    return np.concatenate(gs), np.concatenate(xs)


def _tube_polygons(rings: np.ndarray, cap_start: bool, cap_end: bool) -> list:
    """Quadrilaterals between consecutive rings, plus optional end caps.

    Every polygon has four vertices (a cap of more than four points is a fan of
    degenerate quadrilaterals around its centroid): matplotlib pads polygons of mixed
    sizes with unset values, which its autoscaling would then read.
    """
    n = rings.shape[1]
    polys = []
    for j in range(len(rings) - 1):
        a, b = rings[j], rings[j + 1]
        for k in range(n):
            k1 = (k + 1) % n
            polys.append(np.stack([a[k], a[k1], b[k1], b[k]]))
    caps = ([rings[0]] if cap_start else []) + ([rings[-1]] if cap_end else [])
    for ring in caps:
        if n == 4:
            polys.append(ring)
            continue
        c = ring.mean(axis=0)
        for k in range(n):
            polys.append(np.stack([c, ring[k], ring[(k + 1) % n], c]))
    return polys


def _add_body(ax, art3d, polys, rings, centres, X1, color, gid, edge):
    coll = art3d.Poly3DCollection(polys, facecolors=color, shade=True)
    coll.set_edgecolor(edge)
    coll.set_linewidth(0.3 if edge != "none" else 0.0)
    coll.set_gid(gid)
    coll.sorojax_rings = rings
    coll.sorojax_centres = centres
    coll.sorojax_X1 = X1
    ax.add_collection3d(coll)
    return coll


def _set_equal_limits(ax, pts: np.ndarray, margin: float = 0.05) -> None:
    """Limits containing ``pts`` with equal scale on all axes (box aspect = ranges)."""
    from matplotlib.ticker import MaxNLocator

    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = hi - lo
    big = float(span.max()) if span.max() > 0 else 1.0
    # Give thin directions a minimum extent so the box never degenerates.
    half = np.maximum(span, 0.25 * big) * (0.5 + margin)
    mid = (lo + hi) / 2.0
    lo, hi = mid - half, mid + half
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(tuple(hi - lo))
    # Fewer ticks on the short sides, so their labels do not overlap.
    longest = float((hi - lo).max())
    for axis, r in zip((ax.xaxis, ax.yaxis, ax.zaxis), hi - lo, strict=True):
        axis.set_major_locator(MaxNLocator(nbins=max(2, round(6 * r / longest))))


def _prepare_axes(ax):
    import matplotlib.pyplot as plt

    if ax is None:
        fig = plt.figure()
        ax = fig.add_subplot(projection="3d")
        return fig, ax, None
    if getattr(ax, "name", None) != "3d":
        raise ValueError(
            f"ax = {ax!r} is not a 3D axes: create it with "
            "fig.add_subplot(projection='3d'), or pass ax=None."
        )
    prev = getattr(ax, "_sorojax_bounds", None)
    return ax.figure, ax, prev


# ------------------------------------------------------------------------------ API
def plot_configuration(
    linkage,
    q,
    ax=None,
    *,
    frames: bool = False,
    frame_scale: float | None = None,
    n_circle: int = 18,
    show_points: bool = False,
    color=None,
    n_sub: int = 3,
    poses=None,
):
    """Plot a configuration of a linkage in 3D (the manual's ``plotq``).

    Soft links are tubes through their rod points with the division's section at each
    (rotated with the pose's local y and z axes); rigid links are prisms of their
    section drawn in the CM frame from x = -L/2 to +L/2. Axes are in metres with equal
    scale in all directions. Plotting again into the same ``ax`` widens the limits to
    hold both drawings.

    Args:
        linkage: the :class:`~sorojax.Linkage`.
        q: coordinates, shape ``(n_dof,)`` (NumPy or JAX).
        ax: a 3D matplotlib axes to draw into, or None for a new figure.
        frames: draw the local frames (x red, y green, z blue) at every joint frame
            and tip.
        frame_scale: length of the frame arrows [m]; default 10 % of the largest
            extent of the drawing.
        n_circle: number of points on circular and elliptical section outlines.
        show_points: mark all significant points (black dots).
        color: one colour for every link, overriding the links' own ``color``.
        n_sub: subdivisions between consecutive rod points (positions by a cubic
            Hermite curve, orientations by uniform rotation); 1 draws rings at the
            significant points only.
        poses: ``forward_kinematics(linkage, q)`` if already at hand (it is then
            not computed again), shape ``(n_points, 4, 4)``.

    Returns:
        ``(fig, ax)``.

    Raises:
        ValueError: ``ax`` is not a 3D axes, ``n_circle < 3`` or ``n_sub < 1``, or
            ``q`` or ``poses`` has the wrong shape.
    """
    from mpl_toolkits.mplot3d import art3d

    from ..kinematics._api import forward_kinematics

    if int(n_circle) < 3:
        raise ValueError(f"n_circle = {n_circle!r}: give at least 3 outline points.")
    if int(n_sub) < 1:
        raise ValueError(f"n_sub = {n_sub!r}: give an integer >= 1.")
    n_circle, n_sub = int(n_circle), int(n_sub)
    if poses is None:
        g = np.asarray(forward_kinematics(linkage, q), dtype=float)
    else:
        g = np.asarray(poses, dtype=float)
        if g.shape != (linkage.n_points, 4, 4):
            raise ValueError(
                f"poses has shape {g.shape}; expected ({linkage.n_points}, 4, 4) "
                "(forward_kinematics(linkage, q)), or pass poses=None."
            )
    layout = linkage.layout
    fig, ax, prev = _prepare_axes(ax)

    pts = [g[:, :3, 3]]
    for i, (link, lay) in enumerate(zip(linkage.links, layout.links, strict=True), 1):
        c = link.color if color is None else color
        if isinstance(link, SoftLink):
            nd = len(lay.divisions)
            for k, (div, dl) in enumerate(
                zip(link.divisions, lay.divisions, strict=True), 1
            ):
                idx = dl.first_point + np.arange(len(dl.X1))
                gd, X1 = _densify(g[idx], np.asarray(dl.X1, dtype=float), n_sub)
                outlines = _outlines(div.section, X1, n_circle)
                rings = np.stack(
                    [_ring(gj, yz) for gj, yz in zip(gd, outlines, strict=True)]
                )
                polys = _tube_polygons(rings, cap_start=k == 1, cap_end=k == nd)
                _add_body(
                    ax,
                    art3d,
                    polys,
                    rings,
                    gd[:, :3, 3].copy(),
                    X1,
                    c,
                    f"sorojax-link{i}-division{k}",
                    "none",
                )
                pts.append(rings.reshape(-1, 3))
        elif isinstance(link, RigidLink):
            gc = g[lay.cm_point]
            half = 0.5 * _scalar(link.length)
            ends = []
            for x_local, _X1 in ((-half, 0.0), (half, 1.0)):
                ge = gc.copy()
                ge[:3, 3] = gc[:3, 3] + x_local * gc[:3, 0]
                ends.append(ge)
            outlines = _outlines(link.section, (0.0, 1.0), n_circle)
            rings = np.stack(
                [_ring(ge, yz) for ge, yz in zip(ends, outlines, strict=True)]
            )
            polys = _tube_polygons(rings, cap_start=True, cap_end=True)
            _add_body(
                ax,
                art3d,
                polys,
                rings,
                np.stack([e[:3, 3] for e in ends]),
                np.array([0.0, 1.0]),
                c,
                f"sorojax-link{i}-body",
                "k" if rings.shape[1] == 4 else "none",
            )
            pts.append(rings.reshape(-1, 3))

    pts = np.concatenate(pts)
    if prev is not None:
        pts = np.concatenate([pts, prev])
    span = float((pts.max(axis=0) - pts.min(axis=0)).max())

    if frames:
        scale = frame_scale
        if scale is None:
            scale = 0.1 * (span if span > 0 else 1.0)
        sel = np.flatnonzero(np.isin(layout.point_kind, (JOINT, TIP)))
        origin = g[sel, :3, 3]
        for a, (name, fc) in enumerate(zip("xyz", _FRAME_COLORS, strict=True)):
            d = scale * g[sel, :3, a]
            qv = ax.quiver(
                origin[:, 0],
                origin[:, 1],
                origin[:, 2],
                d[:, 0],
                d[:, 1],
                d[:, 2],
                color=fc,
                arrow_length_ratio=0.2,
                linewidths=1.2,
            )
            qv.set_gid(f"sorojax-frames-{name}")
            qv.sorojax_origins = origin
            qv.sorojax_vectors = d
            pts = np.concatenate([pts, origin + d])

    if show_points:
        p = g[:, :3, 3]
        sc = ax.scatter(p[:, 0], p[:, 1], p[:, 2], color="k", s=6, depthshade=False)
        sc.set_gid("sorojax-points")

    _set_equal_limits(ax, pts)
    ax._sorojax_bounds = np.stack([pts.min(axis=0), pts.max(axis=0)])
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    return fig, ax


def plot_reference(linkage, ax=None, **kw):
    """Plot the reference configuration q = 0 (the manual's ``plotq0``).

    Args:
        linkage: the :class:`~sorojax.Linkage`.
        ax: a 3D matplotlib axes, or None for a new figure.
        **kw: keyword options of :func:`plot_configuration`; ``frames`` defaults to
            True here.

    Returns:
        ``(fig, ax)``.
    """
    kw.setdefault("frames", True)
    return plot_configuration(linkage, np.zeros(linkage.n_dof), ax, **kw)


plotq = plot_configuration
plotq0 = plot_reference
