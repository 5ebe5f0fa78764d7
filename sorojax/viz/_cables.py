"""Cable routes as world polylines, and their drawing on a 3D axes.

A cable (:class:`~sorojax.Cable`) is drawn as it is modelled: through each in-body
span at the path offset ``d(X) = (0, y, z)`` in the cross-section frame of every rod
point of the spanned divisions, through each anchor, and straight between consecutive
route elements. Everything here is NumPy on evaluated poses (never traced).
"""

import numpy as np

from ..model._actuation import Cable, CableSpan


def _span_points(linkage, g: np.ndarray, span: CableSpan) -> np.ndarray:
    link = linkage.links[span.link - 1]
    lay = linkage.layout.links[span.link - 1]
    lengths = np.array([float(np.asarray(d.length)) for d in link.divisions])
    starts = np.concatenate([[0.0], np.cumsum(lengths)])
    first, last = (1, len(lengths)) if span.divisions is None else span.divisions
    pts = []
    for k in range(first - 1, last):
        dl = lay.divisions[k]
        X = (starts[k] + np.asarray(dl.X1) * lengths[k]) / starts[-1]
        for j, x in enumerate(X):
            gp = g[dl.first_point + j]
            yz = np.asarray(span.path(x), dtype=float)
            pts.append(gp[:3, 3] + gp[:3, 1] * yz[0] + gp[:3, 2] * yz[1])
    return np.stack(pts)


def _route_points(linkage, g: np.ndarray, cable: Cable):
    """``(points (n, 3), anchor mask (n,))`` of one cable's route."""
    pts, anchor = [], []
    for r in cable.route:
        if isinstance(r, CableSpan):
            p = _span_points(linkage, g, r)
            anchor.extend([False] * len(p))
        else:
            offset = np.asarray(r.offset, dtype=float)
            if r.link == 0:
                p = offset[None]
            else:
                gp = g[linkage.anchor_index(r)]
                p = (gp[:3, :3] @ offset + gp[:3, 3])[None]
            anchor.append(True)
        pts.append(p)
    return np.concatenate(pts), np.asarray(anchor)


def cable_polylines(linkage, q) -> list[tuple[str, np.ndarray]]:
    """World polylines of the linkage's cables at ``q``.

    Args:
        linkage: the :class:`~sorojax.Linkage`.
        q: coordinates ``(n_dof,)``.

    Returns:
        One ``(name, points)`` per cable in actuator order, ``points`` an ``(n, 3)``
        array [m]: the span paths at the rod points and the anchors, in route order
        (consecutive points are joined straight, as in the model).
    """
    from ..kinematics._api import forward_kinematics

    g = np.asarray(forward_kinematics(linkage, q), dtype=float)
    return [
        (a.name, _route_points(linkage, g, a)[0])
        for a in linkage.actuators
        if isinstance(a, Cable)
    ]


def plot_cables(linkage, q, ax, *, color="k", linewidth=1.5, markers=True, **kw):
    """Draw the linkage's cables at ``q`` into a 3D axes (after ``plot_configuration``).

    Args:
        linkage: the :class:`~sorojax.Linkage`.
        q: coordinates ``(n_dof,)``.
        ax: a 3D matplotlib axes.
        color: line colour (one for all cables).
        linewidth: line width [points].
        markers: mark the anchors (route elements that are points) with dots.
        **kw: further options of ``ax.plot``.

    Returns:
        The list of line artists, one per cable (gid ``sorojax-cable-NAME``).
    """
    from ..kinematics._api import forward_kinematics

    g = np.asarray(forward_kinematics(linkage, q), dtype=float)
    lines = []
    for a in linkage.actuators:
        if not isinstance(a, Cable):
            continue
        pts, anchor = _route_points(linkage, g, a)
        (line,) = ax.plot(
            pts[:, 0], pts[:, 1], pts[:, 2], color=color, linewidth=linewidth, **kw
        )
        line.set_gid(f"sorojax-cable-{a.name}")
        lines.append(line)
        if markers and anchor.any():
            p = pts[anchor]
            ax.scatter(p[:, 0], p[:, 1], p[:, 2], color=color, s=8, depthshade=False)
    return lines
