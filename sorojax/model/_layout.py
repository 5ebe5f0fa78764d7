"""Static layout of a linkage: coordinate offsets and the table of significant points.

Everything here is plain Python / NumPy derived from static structure (topology, basis
sizes, Gauss counts, load positions), computed at trace time and cached.

Significant points, link by link in order: the joint frame (after the joint), then for a
rigid link its CM, for a soft link every point of every division (start, interior
Gauss points, extra load points, contact samples, end), then the link's tip reference
point.

A division's points are either on the kinematic chain (its ends, Gauss points and load
points: the Magnus steps join consecutive ones) or *leaves* (contact samples that are
none of those): a leaf's pose, twist and Jacobian come from one Magnus step of its own
from the chain point before it (:mod:`sorojax.kinematics._recursion`), so that adding
contact samples neither lengthens the chain nor changes the kinematics of the other
points.
"""

import dataclasses
import functools

import numpy as np

# Point kinds.
JOINT, CM, ROD, TIP = 0, 1, 2, 3
KIND_NAMES = {JOINT: "joint", CM: "cm", ROD: "rod", TIP: "tip"}


@functools.lru_cache(maxsize=64)
def gauss_legendre01(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return (x + 1.0) / 2.0, w / 2.0


@dataclasses.dataclass(frozen=True)
class DivisionLayout:
    """Points of one division: normalised positions and unit-length weights."""

    offset: int
    n_dof: int
    X1: np.ndarray  # (n_pts,) sorted, starts at 0, ends at 1
    w: np.ndarray  # (n_pts,) Gauss weights on [0, 1], 0 at extra points
    first_point: int  # index of X1[0] in the linkage's point table
    leaf: np.ndarray  # (n_pts,) True at leaves (contact samples off the chain)


@dataclasses.dataclass(frozen=True)
class LinkLayout:
    """Offsets and point indices of one link."""

    soft: bool
    parent: int  # 1-based, 0 = ground
    joint_offset: int
    joint_n_dof: int
    joint_point: int
    cm_point: int | None
    divisions: tuple[DivisionLayout, ...]
    tip_point: int


@dataclasses.dataclass(frozen=True)
class Layout:
    """Static layout of the whole linkage.

    Attributes:
        n_dof: total number of generalised coordinates.
        links: per-link layout.
        point_link: (n_points,) 1-based link number of each significant point.
        point_kind: (n_points,) JOINT, CM, ROD or TIP.
        point_division: (n_points,) 1-based division (0 if not a rod point).
        point_X1: (n_points,) normalised position in its division (0 off rods).
        point_leaf: (n_points,) True at leaves (contact samples off the chain).
    """

    n_dof: int
    links: tuple[LinkLayout, ...]
    point_link: np.ndarray
    point_kind: np.ndarray
    point_division: np.ndarray
    point_X1: np.ndarray
    point_leaf: np.ndarray

    @property
    def n_points(self) -> int:
        """Number of significant points."""
        return len(self.point_kind)


def division_points(
    n_gauss: int, extra: tuple[float, ...], leaves: tuple[float, ...] = ()
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Union of 0, the Gauss points, the extra load points, the leaves and 1.

    Returns the sorted positions, their weights (Gauss weights, 0 elsewhere) and
    whether each is a leaf: a point given only in ``leaves`` (a point that is also a
    chain point, an end, a Gauss or a load point, stays on the chain).
    """
    xg, wg = gauss_legendre01(n_gauss)
    leaves = np.asarray(leaves, dtype=float)
    X = np.concatenate([[0.0], xg, [1.0], np.asarray(extra, dtype=float), leaves])
    W = np.concatenate([[0.0], wg, [0.0], np.zeros(len(extra) + len(leaves))])
    F = np.concatenate(
        [np.zeros(len(X) - len(leaves), bool), np.ones_like(leaves, bool)]
    )
    order = np.argsort(X, kind="stable")
    X, W, F = X[order], W[order], F[order]
    keep = np.concatenate([[True], np.diff(X) > 1e-12])
    # When an extra point coincides with a Gauss point keep the Gauss weight; a
    # leaf that coincides with a chain point is that chain point.
    Xk, Wk, Fk = [], [], []
    for x, w, f, k in zip(X, W, F, keep, strict=True):
        if k:
            Xk.append(x)
            Wk.append(w)
            Fk.append(f)
        else:
            Wk[-1] = max(Wk[-1], w)
            Fk[-1] = Fk[-1] and f
    return np.asarray(Xk), np.asarray(Wk), np.asarray(Fk, bool)


def build_layout(signature) -> Layout:
    """Build the layout from a hashable static signature (see ``Linkage.signature``).

    ``signature`` is a tuple over links of ``(soft, parent, joint_n_dof, divisions)``
    where ``divisions`` is a tuple of ``(n_dof, n_gauss, extra_X1s, leaf_X1s)``.
    """
    return _build_layout(signature)


@functools.lru_cache(maxsize=256)
def _build_layout(signature) -> Layout:
    offset = 0
    links = []
    p_link, p_kind, p_div, p_X1, p_leaf = [], [], [], [], []

    def add(link, kind, div=0, X1=0.0, leaf=False):
        p_link.append(link)
        p_kind.append(kind)
        p_div.append(div)
        p_X1.append(X1)
        p_leaf.append(leaf)
        return len(p_kind) - 1

    for i, (soft, parent, jn, divs) in enumerate(signature, start=1):
        joint_offset = offset
        offset += jn
        joint_point = add(i, JOINT)
        cm_point = None
        dls = []
        if soft:
            for d, (nd, ng, extra, leaves) in enumerate(divs, start=1):
                X1, w, leaf = division_points(ng, extra, leaves)
                first = len(p_kind)
                for x, f in zip(X1, leaf, strict=True):
                    add(i, ROD, d, float(x), bool(f))
                dls.append(DivisionLayout(offset, nd, X1, w, first, leaf))
                offset += nd
        else:
            cm_point = add(i, CM)
        tip_point = add(i, TIP)
        links.append(
            LinkLayout(
                soft,
                parent,
                joint_offset,
                jn,
                joint_point,
                cm_point,
                tuple(dls),
                tip_point,
            )
        )
    return Layout(
        offset,
        tuple(links),
        np.asarray(p_link, dtype=int),
        np.asarray(p_kind, dtype=int),
        np.asarray(p_div, dtype=int),
        np.asarray(p_X1, dtype=float),
        np.asarray(p_leaf, dtype=bool),
    )
