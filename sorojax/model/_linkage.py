"""The linkage: a tree of links with placements, gravity, point wrenches and hooks.

Links are numbered from 1 in the order given; ``parents[i]`` is the number of the link
whose tip link ``i + 1`` is attached to (0 = ground), and must be smaller than
``i + 1`` (links are listed parents first, which also rules out cycles). The same link
object may appear several times (a reused link).
"""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._actuation import (
    Cable,
    CableAnchor,
    CableSpan,
    ConstantPath,
    HelicalPath,
    JointActuator,
    ObliquePath,
)
from ._checks import check_finite, check_se3, check_shape, is_concrete
from ._closure import ClosedLoopJoint
from ._contact import Contact, resolve_contact
from ._hook import Hook, as_hook
from ._layout import Layout, build_layout
from ._link import AbstractLink, RigidLink, SoftLink
from ._loads import PointWrench
from ._profile import Constant, Linear
from ._section import (
    AnnularSection,
    CircularSection,
    EllipticalSection,
    RectangularSection,
)


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
        actuators: tuple of :class:`~sorojax.JointActuator` and
            :class:`~sorojax.Cable`; each owns a block of the input vector ``u``
            (see :attr:`input_slices`).
        closed_loops: tuple of :class:`~sorojax.ClosedLoopJoint`.
        custom_actuation: optional pure JAX function ``(t, q, qd, kinematics, u) ->
            (n_points, 6)`` of internal actuation wrenches per unit length at soft rod
            points (body frame, moment first), mapped to generalised forces by the
            strain basis, ``sum w Phi^T W`` (the manual's CustomActuation); ignored at
            other points.
        actuator_strength: optional pure JAX function ``(t, q, qd, kinematics) ->
            (n_inputs,)`` that replaces the given inputs ``u`` (the manual's
            CustomActuatorStrength: feedback control inside the solvers). Entries of
            prescribed joints are ignored (their inputs stay the given q(t)).

            Each hook is stored as a :class:`~sorojax.model.Hook`. A plain function
            is static: the compiled programs are keyed by the function object (a new
            closure recompiles). To change a hook's parameters without recompiling,
            or to differentiate with respect to them, give them as arrays in an
            ``equinox.Partial(f, *args)`` of a module-level ``f`` (or an
            ``equinox.Module`` with a ``__call__``): its array leaves are model
            arrays, like E or a radius; its other values (Python numbers included)
            stay static.
        added_mass: optional ``(n_points, 6, 6)`` added inertia (per unit length at
            rod points, absolute at rigid CMs) in body frames: the force
            ``-M_a etadot`` of a surrounding fluid, added to M (the manual's
            M_added).
        baumgarte_time: T_bs [s] of the Baumgarte stabilisation of closed loops in
            dynamics (smaller holds the constraint more tightly; default 0.01); an
            array, so a new value reuses compiled programs and ``jax.grad``
            reaches it.
        contact: optional :class:`~sorojax.Contact`: obstacles, the contact law,
            rigid links' contact shapes, rod-rod pairs and self-contact. Its
            samples on soft links become significant points of the layout, as
            leaves of the kinematic chain (each one Magnus step from the chain
            point before it); their number is fixed here (see
            ``Contact.spacing``).
    """

    links: tuple[AbstractLink, ...]
    parents: tuple[int, ...] = eqx.field(static=True)
    placements: Float[Array, "n_links 4 4"]
    gravity: Float[Array, "3"]
    point_wrenches: tuple[PointWrench, ...]
    custom_wrench: Hook | None
    actuators: tuple[Cable | JointActuator, ...]
    closed_loops: tuple[ClosedLoopJoint, ...]
    custom_actuation: Hook | None
    actuator_strength: Hook | None
    added_mass: Float[Array, "n_points 6 6"] | None
    baumgarte_time: Float[Array, ""]
    contact: Contact | None

    def __init__(
        self,
        links,
        parents=None,
        placements=None,
        gravity: ArrayLike = (0.0, 0.0, 0.0),
        point_wrenches=(),
        custom_wrench: Callable | None = None,
        actuators=(),
        closed_loops=(),
        custom_actuation: Callable | None = None,
        actuator_strength: Callable | None = None,
        added_mass: ArrayLike | None = None,
        baumgarte_time: float = 0.01,
        contact: Contact | None = None,
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
            placements = jnp.asarray(np.broadcast_to(np.eye(4), (n, 4, 4)))
        else:
            placements = jnp.asarray(placements, dtype=float)
            check_shape("Linkage.placements", placements, (n, 4, 4))
            # a concrete stack is checked on the host (indexing the device array
            # ran one eager program per link)
            host = np.asarray(placements) if is_concrete(placements) else placements
            for i in range(n):
                check_se3(f"Linkage.placements[{i}]", host[i])
        check_shape("Linkage.gravity", gravity, (3,))
        check_finite("Linkage.gravity", gravity, "give it in m/s^2, e.g. (0, 0, -9.81)")
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
        # hooks: their array leaves are model arrays, the rest static (see Hook)
        self.links = links
        self.parents = parents
        self.placements = placements
        self.gravity = jnp.asarray(gravity, dtype=float)
        self.point_wrenches = point_wrenches
        self.custom_wrench = as_hook(custom_wrench, "custom_wrench")
        self.custom_actuation = as_hook(custom_actuation, "custom_actuation")
        self.actuator_strength = as_hook(actuator_strength, "actuator_strength")
        if isinstance(actuators, Cable | JointActuator):
            actuators = (actuators,)
        self.actuators = tuple(
            _check_actuator(k, a, links) for k, a in enumerate(tuple(actuators))
        )
        if isinstance(closed_loops, ClosedLoopJoint):
            closed_loops = (closed_loops,)
        closed_loops = tuple(closed_loops)
        for k, c in enumerate(closed_loops):
            _check_closed_loop(k, c, n)
        self.closed_loops = closed_loops
        if is_concrete(baumgarte_time) and not float(baumgarte_time) > 0:
            raise ValueError(
                f"Linkage.baumgarte_time = {baumgarte_time!r}: give T_bs > 0 [s] "
                "(default 0.01)."
            )
        # an array (a parameter: a new value reuses compiled programs)
        with jax.ensure_compile_time_eval():
            self.baumgarte_time = jnp.asarray(baumgarte_time, dtype=float)
        self.contact = None if contact is None else resolve_contact(contact, links)
        if added_mass is not None:
            added_mass = jnp.asarray(added_mass, dtype=float)
            n_pts = build_layout(self.signature).n_points
            check_shape("Linkage.added_mass", added_mass, (n_pts, 6, 6))
        self.added_mass = added_mass

    # ---------------------------------------------------------------- structure
    @property
    def signature(self) -> tuple:
        """Hashable static structure (topology, basis sizes, Gauss counts, loads)."""
        extra: dict[tuple[int, int], list[float]] = {}
        for pw in self.point_wrenches:
            if pw.division is not None:
                extra.setdefault((pw.link, pw.division), []).append(pw.X1)
        for a in getattr(self, "actuators", ()):
            if isinstance(a, Cable):
                for r in a.route:
                    if isinstance(r, CableAnchor) and r.division is not None:
                        extra.setdefault((r.link, r.division), []).append(r.X1)
        leaves: dict[tuple[int, int], list[float]] = {}
        contact = getattr(self, "contact", None)
        if contact is not None:
            for link, cells in contact.cells:
                for k, n in enumerate(cells, start=1):
                    leaves.setdefault((link, k), []).extend(j / n for j in range(1, n))
        sig = []
        for i, (link, parent) in enumerate(
            zip(self.links, self.parents, strict=True), 1
        ):
            if isinstance(link, SoftLink):
                divs = tuple(
                    (
                        d.n_dof,
                        d.n_gauss,
                        tuple(sorted(extra.get((i, k), []))),
                        tuple(sorted(leaves.get((i, k), []))),
                    )
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

    def anchor_index(self, anchor: CableAnchor) -> int:
        """Index of the significant point a cable anchor is fixed to (not ground)."""
        return self.point_index(
            PointWrench(
                anchor.link,
                jnp.zeros(6),
                division=anchor.division,
                X1=anchor.X1,
                at_tip=anchor.at_tip,
            )
        )

    # --------------------------------------------------------------- actuation
    @property
    def n_inputs(self) -> int:
        """Length of the actuation input vector ``u``."""
        return sum(a.n_inputs for a in self.actuators)

    @property
    def input_slices(self) -> tuple[slice, ...]:
        """Slice of ``u`` owned by each actuator, in order."""
        out, k = [], 0
        for a in self.actuators:
            out.append(slice(k, k + a.n_inputs))
            k += a.n_inputs
        return tuple(out)

    @property
    def prescribed(self) -> tuple[np.ndarray, np.ndarray]:
        """``(coords, inputs)``: indices into q and into u of prescribed coordinates."""
        qi, ui = [], []
        for a, sl in zip(self.actuators, self.input_slices, strict=True):
            if isinstance(a, JointActuator) and a.prescribed:
                jo = self.layout.links[a.link - 1].joint_offset
                qi.extend(range(jo, jo + a.n_inputs))
                ui.extend(range(sl.start, sl.stop))
        return np.asarray(qi, dtype=int), np.asarray(ui, dtype=int)

    @property
    def n_constraints(self) -> int:
        """Number of closed-loop constraint rows (redundant ones included)."""
        return sum(c.n_constraints for c in self.closed_loops)

    def tip_point(self, link: int) -> int:
        """Index of the tip reference point of link number ``link`` (1-based)."""
        if not 1 <= link <= self.n_links:
            raise ValueError(f"link = {link} is out of range 1..{self.n_links}.")
        return self.layout.links[link - 1].tip_point

    def dof_slice(self, link: int) -> slice:
        """Slice of q holding link ``link``'s coordinates (joint then divisions)."""
        lay = self.layout.links[link - 1]
        return slice(lay.joint_offset, lay.joint_offset + self.links[link - 1].n_dof)


def _check_point_wrench(k: int, pw, links, field: str | None = None) -> None:
    field = f"Linkage.point_wrenches[{k}]" if field is None else field
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


def _check_actuator(k: int, a, links):
    field = f"Linkage.actuators[{k}]"
    n = len(links)
    if isinstance(a, JointActuator):
        if not 1 <= a.link <= n:
            raise ValueError(f"{field}.link = {a.link} is out of range: give 1..{n}.")
        nj = links[a.link - 1].joint.n_dof
        if nj == 0:
            raise ValueError(
                f"{field}: link {a.link}'s joint is fixed ('N'), nothing to actuate; "
                "give the link a joint with freedoms or drop the actuator."
            )
        return JointActuator(a.link, a.prescribed, nj)
    if isinstance(a, Cable):
        for j, r in enumerate(a.route):
            f = f"{field}.route[{j}]"
            if isinstance(r, CableSpan):
                if not 1 <= r.link <= n or not isinstance(links[r.link - 1], SoftLink):
                    raise ValueError(
                        f"{f}.link = {r.link}: a CableSpan runs inside a soft link; "
                        "give the number of a SoftLink."
                    )
                nd = len(links[r.link - 1].divisions)
                if r.divisions is not None and r.divisions[1] > nd:
                    raise ValueError(
                        f"{f}.divisions = {r.divisions}: link {r.link} has divisions "
                        f"1..{nd}."
                    )
                _check_cable_path(f, r, links[r.link - 1])
            else:
                if not 0 <= r.link <= n:
                    raise ValueError(
                        f"{f}.link = {r.link} is out of range: give 0 (ground) or "
                        f"1..{n}."
                    )
                if r.link:
                    _check_point_wrench(
                        k,
                        PointWrench(r.link, jnp.zeros(6), r.division, r.X1),
                        links,
                        field=f,
                    )
        return a
    raise ValueError(f"{field} = {a!r}: give a JointActuator or a Cable.")


def _profile_np(profile, X1: float) -> float | None:
    """A built-in profile's value at ``X1`` on the host; None if unknown or traced."""
    if isinstance(profile, Constant) and is_concrete(profile.value):
        return float(profile.value)
    if (
        isinstance(profile, Linear)
        and is_concrete(profile.start)
        and is_concrete(profile.end)
    ):
        start, end = float(profile.start), float(profile.end)
        return start + (end - start) * X1
    return None


def _extent_np(section, X1: float) -> tuple[float, float] | None:
    """Half-widths (along y, along z) of a built-in section on the host, or None."""
    if isinstance(section, CircularSection):
        r = _profile_np(section.radius, X1)
        return None if r is None else (r, r)
    if isinstance(section, AnnularSection):
        r = _profile_np(section.outer, X1)
        return None if r is None else (r, r)
    if isinstance(section, EllipticalSection):
        a, b = _profile_np(section.a, X1), _profile_np(section.b, X1)
        return None if a is None or b is None else (a, b)
    if isinstance(section, RectangularSection):
        w, h = _profile_np(section.width, X1), _profile_np(section.height, X1)
        return None if w is None or h is None else (w / 2, h / 2)
    return None


def _path_np(path, X: float) -> np.ndarray | None:
    """A built-in cable path's ``(y, z)`` at link position ``X`` (host), or None."""
    leaves = jax.tree.leaves(path)
    if not all(is_concrete(x) for x in leaves):
        return None
    if isinstance(path, ConstantPath):
        return np.array([float(path.y), float(path.z)])
    if isinstance(path, ObliquePath):
        start, end = np.asarray(path.start), np.asarray(path.end)
        return start + X * (end - start)
    if isinstance(path, HelicalPath):
        a = float(path.phase) + 2.0 * np.pi * float(path.turns) * X
        return float(path.radius) * np.array([np.cos(a), np.sin(a)])
    return None


def _check_cable_path(field: str, span: CableSpan, link: SoftLink) -> None:
    """Refuse a built-in cable path that leaves its soft link's sections.

    Checked on the host where the path, the section dimensions and the division
    lengths are concrete built-in values (custom paths and sections are the user's
    to check): at the start, middle and end of each spanned division the offset
    must lie within the section's half-widths along y and z (the bounding box, with
    1e-9 relative slack: a cable on the surface is allowed).
    """
    lengths = [d.length for d in link.divisions]
    if not all(is_concrete(x) for x in lengths):
        return
    lengths = [float(x) for x in lengths]
    starts = np.concatenate([[0.0], np.cumsum(lengths)])
    first, last = span.divisions or (1, len(lengths))
    for k in range(first - 1, last):
        for X1 in (0.0, 0.5, 1.0):
            d = _path_np(span.path, (starts[k] + X1 * lengths[k]) / starts[-1])
            if d is None:
                return
            if not np.all(np.isfinite(d)):
                raise ValueError(
                    f"{field}.path gives the offset (y, z) = {d.tolist()} [m]: give "
                    "finite offsets."
                )
            ext = _extent_np(link.divisions[k].section, X1)
            if ext is None:
                continue
            if abs(d[0]) > ext[0] * (1 + 1e-9) or abs(d[1]) > ext[1] * (1 + 1e-9):
                raise ValueError(
                    f"{field}.path puts the cable at offset (y, z) = "
                    f"({d[0]:.6g}, {d[1]:.6g}) m in division {k + 1} at X1 = {X1}, "
                    f"outside the section (half-widths {ext[0]:.6g} m along y, "
                    f"{ext[1]:.6g} m along z: radius or half-width): a CableSpan "
                    "runs inside its link. Give offsets in metres within the section "
                    "(e.g. a fraction of the radius), or route a cable outside the "
                    "body between CableAnchor points."
                )


def _check_closed_loop(k: int, c, n: int) -> None:
    field = f"Linkage.closed_loops[{k}]"
    if not isinstance(c, ClosedLoopJoint):
        raise ValueError(f"{field} = {c!r}: give a ClosedLoopJoint.")
    if not 1 <= c.link_A <= n:
        raise ValueError(f"{field}.link_A = {c.link_A} is out of range: give 1..{n}.")
    if not 0 <= c.link_B <= n or c.link_B == c.link_A:
        raise ValueError(
            f"{field}.link_B = {c.link_B}: give 0 (ground) or another link in 1..{n}."
        )
