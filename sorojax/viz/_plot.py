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
- ``"sorojax-points"``: the significant points (``show_points=True``);
- ``"sorojax-obstacle{k}"``: obstacle ``k`` (0-based, the index in
  ``linkage.contact.obstacles`` and :attr:`~sorojax.ContactState.obstacle`): a
  translucent square (``Plane``), a translucent surface (``Sphere``, ``Capsule``), both
  ``Poly3DCollection``, or the 12 edges of a ``Box`` (a ``Line3DCollection``), with
  ``sorojax_kind`` (``"plane"``, ``"sphere"``, ``"capsule"`` or ``"box"``),
  ``sorojax_pose`` (``(4, 4)`` world pose of the obstacle frame at the time drawn) and
  ``sorojax_points`` (world points it was built from: the plane's 4 corners, the
  surface's ``(n_rings, n_circle, 3)`` rings, the box's 8 corners);
- ``"sorojax-contact-forces"``: the contact forces of the active contacts (a quiver),
  with ``sorojax_origins`` (contact points), ``sorojax_forces`` [N] and
  ``sorojax_vectors`` (drawn arrows, ``sorojax_scale`` [m/N] times the forces), each
  ``(n_active, 3)``.
"""

import itertools
import math
import numbers

import numpy as np

from ..model._layout import JOINT, TIP
from ..model._link import RigidLink, SoftLink
from ..model._section import RectangularSection

_FRAME_COLORS = ("tab:red", "tab:green", "tab:blue")
_OBSTACLE_COLOR = "0.55"
_OBSTACLE_EDGE_COLOR = "0.3"
_PLANE_ALPHA = 0.2  # translucent, so that a rod resting on it stays visible
_SURFACE_ALPHA = 0.35
_FORCE_COLOR = "tab:red"
FORCE_ARROW_FRACTION = 0.2
"""Default contact-force scale: the largest arrow is this fraction of the scene's
largest extent."""


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


# ------------------------------------------------------- obstacles and contact forces
def _largest_extent(pts: np.ndarray) -> float:
    """Largest side of the bounding box of ``pts`` [m]; 1 for a single point."""
    span = float((pts.max(axis=0) - pts.min(axis=0)).max())
    return span if span > 0 else 1.0


def _obstacle_pose(obstacle, t: float = 0.0) -> np.ndarray:
    """World pose ``(4, 4)`` of an obstacle's frame at time ``t`` [s] (NumPy)."""
    return np.asarray(obstacle.frame(float(t))[0], dtype=float)


def _to_world(G: np.ndarray, x) -> np.ndarray:
    """Points ``x`` (..., 3) of the obstacle frame ``G`` in the world."""
    return np.asarray(x, dtype=float) @ G[:3, :3].T + G[:3, 3]


def _perpendicular_axes(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ``u, v`` with ``(u, v, a)`` a right-handed orthonormal frame."""
    e = np.zeros(3)
    e[int(np.argmin(np.abs(a)))] = 1.0  # the world axis least aligned with a
    u = np.cross(a, e)
    u /= np.linalg.norm(u)
    return u, np.cross(a, u)


def _box_corners(G: np.ndarray, half_extents) -> np.ndarray:
    """The 8 corners ``(8, 3)`` (world) of a box at pose ``G``.

    In ``itertools.product((-1, 1), repeat=3)`` order of the signs along the box's
    x, y, z.
    """
    signs = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    return _to_world(G, signs * np.asarray(half_extents, dtype=float))


_BOX_EDGES = tuple(
    (i, j) for i in range(8) for j in range(i + 1, 8) if bin(i ^ j).count("1") == 1
)  # corners that differ in one sign: the 12 edges


def _capsule_rings(
    start: np.ndarray, end: np.ndarray, radius: float, n_circle: int
) -> np.ndarray:
    """Rings ``(n_rings, n_circle, 3)`` of a capsule's surface (world).

    A hemisphere about ``end`` from its pole to the equator, then one about ``start``
    from the equator to its pole (a sphere if ``start == end``): the quadrilaterals
    between consecutive rings cover the surface, the cylinder being the band between
    the two equators.
    """
    axis = end - start
    length = float(np.linalg.norm(axis))
    a = axis / length if length > 0 else np.array([0.0, 0.0, 1.0])
    u, v = _perpendicular_axes(a)
    theta = 2.0 * np.pi * np.arange(n_circle) / n_circle
    around = np.cos(theta)[:, None] * u + np.sin(theta)[:, None] * v
    m = max(2, n_circle // 4)  # latitude steps per hemisphere
    phi = np.linspace(0.0, 0.5 * np.pi, m + 1)
    rings = [end + radius * (np.cos(p) * a + np.sin(p) * around) for p in phi]
    # A sphere's two equators coincide: start the second hemisphere one step down.
    phi2 = np.linspace(0.5 * np.pi, np.pi, m + 1)[0 if length > 0 else 1 :]
    rings += [start + radius * (np.cos(p) * a + np.sin(p) * around) for p in phi2]
    return np.stack(rings)


def _finite_obstacle_points(obstacle, G: np.ndarray) -> np.ndarray | None:
    """World points bounding a finite obstacle at pose ``G`` (None for a plane)."""
    from ..model._contact import Box, Capsule, Sphere

    if isinstance(obstacle, Sphere):
        r = _scalar(obstacle.radius)
        return _box_corners(np.eye(4), (r, r, r)) + _to_world(G, obstacle.centre)
    if isinstance(obstacle, Capsule):
        r = _scalar(obstacle.radius)
        ends = _to_world(G, np.stack([obstacle.start, obstacle.end]))
        cube = _box_corners(np.eye(4), (r, r, r))
        return np.concatenate([cube + ends[0], cube + ends[1]])
    if isinstance(obstacle, Box):
        return _box_corners(G, obstacle.half_extents)
    return None


_SQUARE = ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))


def _plane_corners(obstacle, G: np.ndarray, scene: np.ndarray) -> np.ndarray:
    """Corners ``(4, 3)`` of the square drawn for a plane at pose ``G``.

    Its side is the largest extent of the ``scene`` points (world) and its centre
    the projection of theirs onto the plane.
    """
    n = G[:3, :3] @ np.asarray(obstacle.normal, dtype=float)
    p0 = _to_world(G, obstacle.point)
    c = 0.5 * (scene.min(axis=0) + scene.max(axis=0))
    c = c - float((c - p0) @ n) * n
    h = 0.5 * _largest_extent(scene)
    u, v = _perpendicular_axes(n)
    return np.stack([c + h * (su * u + sv * v) for su, sv in _SQUARE])


def _scene_points(linkage, pts: np.ndarray, times=(0.0,)) -> np.ndarray:
    """``pts`` and the bounding points of the finite obstacles at ``times`` [s].

    Spheres, capsules and boxes of ``linkage.contact`` add the corners of boxes that
    hold them (planes are unbounded); a static obstacle is taken once.
    """
    contact = getattr(linkage, "contact", None)
    if contact is None:
        return pts
    moving = any(ob.motion is not None for ob in contact.obstacles)
    out = [pts]
    for t in times if moving else tuple(times)[:1]:
        for ob in contact.obstacles:
            p = _finite_obstacle_points(ob, _obstacle_pose(ob, t))
            if p is not None:
                out.append(p)
    return np.concatenate(out)


def _plane_points(linkage, scene: np.ndarray, times=(0.0,)) -> np.ndarray:
    """Corners ``(n, 3)`` of the squares drawn for the planes at ``times`` [s].

    Sized and centred from the ``scene`` points as in :func:`_plane_corners`; a
    static plane is taken once.
    """
    from ..model._contact import Plane

    contact = getattr(linkage, "contact", None)
    out = [np.zeros((0, 3))]
    for ob in contact.obstacles if contact is not None else ():
        if isinstance(ob, Plane):
            ts = times if ob.motion is not None else tuple(times)[:1]
            out += [_plane_corners(ob, _obstacle_pose(ob, t), scene) for t in ts]
    return np.concatenate(out)


def _draw_obstacles(ax, linkage, scene: np.ndarray, *, t: float = 0.0, n_circle=18):
    """Draw the linkage's obstacles at time ``t`` [s] into the 3D axes ``ax``.

    Planes are translucent squares of side the largest extent of the ``scene``
    points (``(n, 3)``, world [m]) centred at the projection of their centre onto
    the plane, spheres and capsules
    translucent surfaces with ``n_circle`` points around, boxes their 12 edges. The
    artists carry the gids and attributes listed in this module's docstring.

    Returns:
        The world points drawn, ``(n, 3)``, to widen the axis limits with.
    """
    from mpl_toolkits.mplot3d import art3d

    from ..model._contact import Box, Capsule, Plane, Sphere

    contact = getattr(linkage, "contact", None)
    drawn = [np.zeros((0, 3))]
    for k, ob in enumerate(contact.obstacles if contact is not None else ()):
        G = _obstacle_pose(ob, t)
        if isinstance(ob, Plane):
            kind, points = "plane", _plane_corners(ob, G, scene)
            art = art3d.Poly3DCollection(
                [points], facecolors=_OBSTACLE_COLOR, alpha=_PLANE_ALPHA
            )
            art.set_edgecolor(_OBSTACLE_EDGE_COLOR)
            art.set_linewidth(0.5)
            ax.add_collection3d(art)
        elif isinstance(ob, Sphere | Capsule):
            r = _scalar(ob.radius)
            if isinstance(ob, Sphere):
                kind = "sphere"
                start = end = _to_world(G, ob.centre)
            else:
                kind = "capsule"
                start, end = _to_world(G, ob.start), _to_world(G, ob.end)
            points = _capsule_rings(start, end, r, n_circle)
            art = art3d.Poly3DCollection(
                _tube_polygons(points, cap_start=False, cap_end=False),
                facecolors=_OBSTACLE_COLOR,
                alpha=_SURFACE_ALPHA,
                shade=True,
            )
            art.set_edgecolor("none")
            art.set_linewidth(0.0)
            ax.add_collection3d(art)
        elif isinstance(ob, Box):
            kind, points = "box", _box_corners(G, ob.half_extents)
            art = art3d.Line3DCollection(
                [points[[i, j]] for i, j in _BOX_EDGES],
                colors=_OBSTACLE_EDGE_COLOR,
                linewidths=1.0,
            )
            ax.add_collection3d(art)
        else:
            continue
        art.set_gid(f"sorojax-obstacle{k}")
        art.sorojax_kind = kind
        art.sorojax_pose = G
        art.sorojax_points = points
        drawn.append(points.reshape(-1, 3))
    return np.concatenate(drawn)


def _check_force_scale(contact_forces) -> None:
    """Refuse a ``contact_forces`` that is neither a bool nor a positive scale."""
    if isinstance(contact_forces, bool):
        return
    if not (
        isinstance(contact_forces, numbers.Real)
        and math.isfinite(contact_forces)
        and contact_forces > 0
    ):
        raise ValueError(
            f"contact_forces = {contact_forces!r}: give True (largest arrow "
            f"{FORCE_ARROW_FRACTION:.0%} of the scene), False, or a scale > 0 [m/N]."
        )


def _active_contacts(linkage, q, qd=None, t: float = 0.0):
    """Points and forces of the active contacts at ``(q, qd, t)``.

    From :func:`~sorojax.contact_state`: the rows with penetration > 0.

    Returns:
        ``(points (n_active, 3) [m], forces (n_active, 3) [N])``, world frame.

    Raises:
        ValueError: the linkage has no contact.
    """
    from ..dynamics._contact import contact_state

    if getattr(linkage, "contact", None) is None:
        raise ValueError(
            "contact_forces: this linkage has no contact to draw; give "
            "Linkage(contact=sorojax.Contact(...)) or contact_forces=False."
        )
    cs = contact_state(linkage, q, qd, t)
    active = np.asarray(cs.active)
    return (
        np.asarray(cs.point, dtype=float)[active],
        np.asarray(cs.force, dtype=float)[active],
    )


def _draw_contact_forces(ax, points: np.ndarray, forces: np.ndarray, scale: float):
    """Quiver of ``scale`` [m/N] times ``forces`` at ``points`` (nothing if empty).

    Returns:
        The arrow tips ``(n, 3)`` [m], to widen the axis limits with.
    """
    if len(points) == 0:
        return np.zeros((0, 3))
    d = scale * forces
    qv = ax.quiver(
        points[:, 0],
        points[:, 1],
        points[:, 2],
        d[:, 0],
        d[:, 1],
        d[:, 2],
        color=_FORCE_COLOR,
        arrow_length_ratio=0.2,
        linewidths=1.5,
    )
    qv.set_gid("sorojax-contact-forces")
    qv.sorojax_origins = points
    qv.sorojax_forces = forces
    qv.sorojax_vectors = d
    qv.sorojax_scale = float(scale)
    return points + d


def _default_force_scale(forces: np.ndarray, extent: float) -> float:
    """Scale [m/N] that draws the largest force as a fraction of ``extent``.

    The largest of ``forces`` ``(n, 3)`` [N] becomes an arrow of
    :data:`FORCE_ARROW_FRACTION` times ``extent`` [m]; 1 if there is no force.
    """
    fmax = float(np.linalg.norm(forces, axis=1).max()) if len(forces) else 0.0
    return FORCE_ARROW_FRACTION * extent / fmax if fmax > 0 else 1.0


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
    obstacles: bool = True,
    contact_forces: bool | float = False,
    qd=None,
    t: float = 0.0,
):
    """Plot a configuration of a linkage in 3D (the manual's ``plotq``).

    Soft links are tubes through their rod points with the division's section at each
    (rotated with the pose's local y and z axes); rigid links are prisms of their
    section drawn in the CM frame from x = -L/2 to +L/2. Axes are in metres with equal
    scale in all directions. Plotting again into the same ``ax`` widens the limits to
    hold both drawings.

    A linkage with contact (``linkage.contact``) is drawn with its obstacles at time
    ``t``: a plane as a translucent square whose side is the scene's largest extent
    (the linkage, the earlier drawings in ``ax`` and the finite obstacles), centred at
    the projection of the scene's centre onto the plane; a sphere or capsule as a
    translucent surface; a box as its 12 edges. ``contact_forces`` adds the forces of
    :func:`~sorojax.contact_state` at ``(q, qd, t)`` as arrows (red) at the active
    contacts' points (penetration > 0; inactive contacts are not drawn), along the
    force on the robot (for a rod-rod pair, on its first link).

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
        obstacles: draw the obstacles of ``linkage.contact`` (if it has contact).
        contact_forces: draw the contact forces: False (none), True (scaled so that
            the largest arrow is 20 % of the scene's largest extent) or a scale
            [m/N] (arrow length per newton).
        qd: velocities ``(n_dof,)`` for the contact forces (damping and friction);
            default None (zero velocities: the elastic normal forces only).
        t: time [s] at which moving obstacles are drawn and the contact forces
            evaluated.

    Returns:
        ``(fig, ax)``.

    Raises:
        ValueError: ``ax`` is not a 3D axes, ``n_circle < 3`` or ``n_sub < 1``,
            ``q`` or ``poses`` has the wrong shape, or ``contact_forces`` is asked of
            a linkage without contact or is not a bool or a scale > 0.
    """
    from mpl_toolkits.mplot3d import art3d

    from ..kinematics._api import forward_kinematics

    if int(n_circle) < 3:
        raise ValueError(f"n_circle = {n_circle!r}: give at least 3 outline points.")
    if int(n_sub) < 1:
        raise ValueError(f"n_sub = {n_sub!r}: give an integer >= 1.")
    n_circle, n_sub = int(n_circle), int(n_sub)
    _check_force_scale(contact_forces)
    if contact_forces is not False:
        contact_points, forces = _active_contacts(linkage, q, qd, t)
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
    if obstacles:
        # The scene sizes the planes' squares and the default force arrows.
        pts = _scene_points(linkage, pts, (t,))
        scene_extent = _largest_extent(pts)
        pts = np.concatenate(
            [pts, _draw_obstacles(ax, linkage, pts, t=t, n_circle=n_circle)]
        )
    else:
        scene_extent = _largest_extent(pts)
    span = float((pts.max(axis=0) - pts.min(axis=0)).max())

    if contact_forces is not False:
        scale = (
            _default_force_scale(forces, scene_extent)
            if contact_forces is True
            else float(contact_forces)
        )
        tips = _draw_contact_forces(ax, contact_points, forces, scale)
        pts = np.concatenate([pts, tips])

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
