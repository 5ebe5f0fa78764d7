"""The linkage: a tree of links with placements, gravity, point wrenches and hooks.

Links are numbered from 1 in the order given; ``parents[i]`` is the number of the link
whose tip link ``i + 1`` is attached to (0 = ground), and must be smaller than
``i + 1`` (links are listed parents first, which also rules out cycles). The same link
object may appear several times (a reused link).
"""

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._checks import check_se3, check_shape
from ._layout import Layout, build_layout
from ._link import AbstractLink, RigidLink, SoftLink
from ._loads import PointWrench


class Linkage(eqx.Module):
    """An open or branched linkage of soft and rigid links.

    Attributes:
        links: the links, numbered 1..N in this order.
        parents: 1-based parent number per link (0 = ground); default a serial chain.
        placements: (N, 4, 4) pose of each link's base in its parent's tip frame
            (the manual's ``g_ini``); default identities.
        gravity: gravitational acceleration in the world frame [m/s^2], e.g.
            (0, 0, -9.81); default none.
        point_wrenches: tuple of :class:`PointWrench`.
        custom_wrench: optional pure JAX function
            ``(t, q, qd, kinematics) -> (n_points, 6)`` of body-frame wrenches: per
            unit length at soft rod points (integrated with the quadrature weights),
            a point wrench at rigid centres of mass; ignored at other points.
    """

    links: tuple[AbstractLink, ...]
    parents: tuple[int, ...] = eqx.field(static=True)
    placements: Float[Array, "n_links 4 4"]
    gravity: Float[Array, "3"]
    point_wrenches: tuple[PointWrench, ...]
    custom_wrench: Callable | None = eqx.field(static=True)

    def __init__(
        self,
        links,
        parents=None,
        placements=None,
        gravity: ArrayLike = (0.0, 0.0, 0.0),
        point_wrenches=(),
        custom_wrench: Callable | None = None,
    ):
        if isinstance(links, AbstractLink):
            links = (links,)
        links = tuple(links)
        if not links:
            raise ValueError("Linkage.links is empty: give at least one link.")
        for i, link in enumerate(links, start=1):
            if not isinstance(link, SoftLink | RigidLink):
                raise ValueError(
                    f"Linkage.links[{i - 1}] = {link!r}: give SoftLink or RigidLink."
                )
        n = len(links)
        if parents is None:
            parents = tuple(range(n))
        parents = tuple(int(p) for p in parents)
        if len(parents) != n:
            raise ValueError(
                f"Linkage.parents has {len(parents)} entries for {n} links: give one "
                "parent number per link (0 = ground)."
            )
        for i, p in enumerate(parents, start=1):
            if not 0 <= p <= n:
                raise ValueError(
                    f"Linkage.parents[{i - 1}] = {p} is out of range: link {i}'s "
                    f"parent must be 0 (ground) or a link number in 1..{n}."
                )
            if p >= i:
                raise ValueError(
                    f"Linkage.parents[{i - 1}] = {p}: link {i} must be attached to "
                    f"ground or to an earlier link (1..{i - 1}); list links parents "
                    "first (this also rules out cycles)."
                )
        if placements is None:
            placements = jnp.broadcast_to(jnp.eye(4), (n, 4, 4))
        else:
            placements = jnp.asarray(placements, dtype=float)
            check_shape("Linkage.placements", placements, (n, 4, 4))
            for i in range(n):
                check_se3(f"Linkage.placements[{i}]", placements[i])
        check_shape("Linkage.gravity", gravity, (3,))
        if isinstance(point_wrenches, PointWrench):
            point_wrenches = (point_wrenches,)
        point_wrenches = tuple(point_wrenches)
        for k, pw in enumerate(point_wrenches):
            _check_point_wrench(k, pw, links)
        if custom_wrench is not None and not callable(custom_wrench):
            raise ValueError(
                f"Linkage.custom_wrench = {custom_wrench!r}: give a function "
                "(t, q, qd, kinematics) -> (n_points, 6) array, or None."
            )
        self.links = links
        self.parents = parents
        self.placements = placements
        self.gravity = jnp.asarray(gravity, dtype=float)
        self.point_wrenches = point_wrenches
        self.custom_wrench = custom_wrench

    # ---------------------------------------------------------------- structure
    @property
    def signature(self) -> tuple:
        """Hashable static structure (topology, basis sizes, Gauss counts, loads)."""
        extra: dict[tuple[int, int], list[float]] = {}
        for pw in self.point_wrenches:
            if pw.division is not None:
                extra.setdefault((pw.link, pw.division), []).append(pw.X1)
        sig = []
        for i, (link, parent) in enumerate(
            zip(self.links, self.parents, strict=True), 1
        ):
            if isinstance(link, SoftLink):
                divs = tuple(
                    (d.n_dof, d.n_gauss, tuple(sorted(extra.get((i, k), []))))
                    for k, d in enumerate(link.divisions, start=1)
                )
                sig.append((True, parent, link.joint.n_dof, divs))
            else:
                sig.append((False, parent, link.joint.n_dof, ()))
        return tuple(sig)

    @property
    def layout(self) -> Layout:
        """Static layout: coordinate offsets and the significant-point table."""
        return build_layout(self.signature)

    @property
    def n_dof(self) -> int:
        """Total number of generalised coordinates."""
        return self.layout.n_dof

    @property
    def n_links(self) -> int:
        """Number of links."""
        return len(self.links)

    @property
    def n_points(self) -> int:
        """Number of significant points."""
        return self.layout.n_points

    def point_index(self, pw: PointWrench) -> int:
        """Index of the significant point where ``pw`` acts."""
        lay = self.layout.links[pw.link - 1]
        if not lay.soft:
            return lay.tip_point if pw.at_tip else lay.cm_point  # type: ignore[return-value]
        if pw.division is None:
            return lay.tip_point
        dl = lay.divisions[pw.division - 1]
        k = int(np.argmin(np.abs(dl.X1 - pw.X1)))
        return dl.first_point + k

    def tip_point(self, link: int) -> int:
        """Index of the tip reference point of link number ``link`` (1-based)."""
        if not 1 <= link <= self.n_links:
            raise ValueError(f"link = {link} is out of range 1..{self.n_links}.")
        return self.layout.links[link - 1].tip_point

    def dof_slice(self, link: int) -> slice:
        """Slice of q holding link ``link``'s coordinates (joint then divisions)."""
        lay = self.layout.links[link - 1]
        return slice(lay.joint_offset, lay.joint_offset + self.links[link - 1].n_dof)


def _check_point_wrench(k: int, pw, links) -> None:
    field = f"Linkage.point_wrenches[{k}]"
    if not isinstance(pw, PointWrench):
        raise ValueError(f"{field} = {pw!r}: give a PointWrench.")
    n = len(links)
    if not 1 <= pw.link <= n:
        raise ValueError(f"{field}.link = {pw.link} is out of range: give 1..{n}.")
    link = links[pw.link - 1]
    if isinstance(link, RigidLink) and pw.division is not None:
        raise ValueError(
            f"{field}.division = {pw.division}: link {pw.link} is rigid; leave "
            "division None (the wrench acts at the CM, or the tip with at_tip=True)."
        )
    if isinstance(link, SoftLink) and pw.division is not None:
        nd = len(link.divisions)
        if not 1 <= pw.division <= nd:
            raise ValueError(
                f"{field}.division = {pw.division} is out of range: link {pw.link} has "
                f"divisions 1..{nd}."
            )
