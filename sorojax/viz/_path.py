"""Load-response charts of equilibrium paths (:func:`sorojax.continuation`).

Stable segments are drawn solid, unstable ones dashed, limit points and bifurcations
marked; matplotlib is imported only inside the function.
"""

from collections.abc import Callable

import numpy as np


def plot_equilibrium_path(
    path,
    response: Callable[[np.ndarray], float] | int = 0,
    *,
    ax=None,
    label: str | None = None,
    color: str | None = None,
    swap_axes: bool = False,
):
    """Draw a load-response curve: parameter ``p`` against a scalar of ``q``.

    Segments between two stable points are solid, others dashed (unstable);
    limit points are marked with triangles, bifurcations with circles.

    Args:
        path: an :class:`~sorojax.EquilibriumPath`.
        response: a function ``q -> float`` (e.g. a tip coordinate:
            ``lambda q: float(sj.tip_pose(lk, q)[1, 3])``) or the index of a
            coordinate of q.
        ax: a 2D matplotlib axes, or None for a new figure.
        label: legend label of the curve.
        color: line colour (default: the axes' next colour).
        swap_axes: draw the response horizontally and ``p`` vertically (the
            usual way for a load-deflection chart).

    Returns:
        The matplotlib axes.

    Raises:
        ValueError: an empty path or a coordinate index out of range.
    """
    import matplotlib.pyplot as plt

    q = np.asarray(path.q)
    if q.shape[0] == 0:
        raise ValueError("path has no points: there is nothing to draw.")
    if isinstance(response, int | np.integer):
        if not -q.shape[1] <= response < q.shape[1]:
            raise ValueError(
                f"response = {response}: give a function of q or a coordinate "
                f"index in [0, {q.shape[1]})."
            )
        idx = int(response)

        def response(q_, idx=idx):
            return float(q_[idx])

    y = np.asarray([response(qi) for qi in q], dtype=float)
    p = np.asarray(path.p, dtype=float)
    stable = np.asarray(path.stable, dtype=bool)
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    if color is None:
        color = ax._get_lines.get_next_color()

    def xy(a, b):
        return (b, a) if swap_axes else (a, b)

    # Segment i joins points i and i+1 and is solid when both are stable; runs of
    # equal style are drawn as one line, so that the dashes of many short
    # segments do not merge into a solid-looking line.
    seg_stable = stable[:-1] & stable[1:]
    start, labelled = 0, False
    for i in range(1, len(seg_stable) + 1):
        if i < len(seg_stable) and seg_stable[i] == seg_stable[start]:
            continue
        ax.plot(
            *xy(p[start : i + 1], y[start : i + 1]),
            linestyle="-" if seg_stable[start] else "--",
            color=color,
            label=label if (label and not labelled) else None,
        )
        start, labelled = i, True
    if len(p) == 1:
        ax.plot(*xy(p, y), "o", color=color, label=label)
    for c in path.critical:
        yc = float(response(np.asarray(c.q)))
        marker = "^" if c.kind == "limit" else "o"
        ax.plot(
            *xy(np.asarray([c.p]), np.asarray([yc])),
            marker,
            color=color,
            markerfacecolor="white",
            markersize=8,
        )
    ax.set_xlabel("response" if swap_axes else "p")
    ax.set_ylabel("p" if swap_axes else "response")
    return ax
