"""Size classes: models of different orders (and modes) that share compiled programs.

JAX compiles one program per model *structure*: the number of coordinates of every
division is part of every array shape, so a new polynomial order or set of modes
compiles again. :func:`size_class` pads a model to a class: every soft division gets
the class's modes at the class order and a fixed number of points, and a 0/1 array
(:class:`~sorojax.model.PaddedBasis`) switches off the columns the model does not
have. The class's structure is then fixed, and the model's own orders and modes are
array values: a convergence study over orders 1..P, or a sweep that switches modes
on and off, compiles each program once.

The padded coordinates are decoupled and held at zero (their basis columns are
zero; ``K`` and ``M`` give them the mean diagonal stiffness and inertia of the
other coordinates), so a padded model's equilibria and motions are those of the
model at the class's points and Magnus order. With ``divisions``, every soft link
is also filled up to a number of divisions with empty ones (length 0, every
coefficient off): models with fewer divisions then share the programs as well
(their equations are the same; in adaptive dynamics the round-off of the longer
sums can move the steps, so trajectories agree to the tolerance). What
recompiles: the class itself (its order, modes, points and divisions), another
number of links or loads, and a load or cable anchor moved to another division
or point (each changes the points or coordinates).

Padding pays where compiles dominate: on a 2-core CPU (fresh processes, cache off)
the statics of a 3D cantilever at orders 1..6 take 4.7-7.2 s padded to class 6
against 14.3-14.7 s unpadded, and 0.5 s of the damped free-fall rod at orders 1..4
8.2-8.8 s against 14.4-15.2 s; a padded model runs at its class's size, so a low
order costs more per call (order 1 in class 6: 13.5-14.7 ms warm against 3.2-3.6 ms).
"""

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._basis import MODE_NAMES, AbstractPolynomialBasis, PaddedBasis
from ._link import Division, SoftLink, default_n_gauss
from ._linkage import Linkage


def replace_divisions(
    linkage: Linkage, fn: Callable[[int, int, Division], Division], what: str
) -> Linkage:
    """The same linkage with each soft division ``div`` replaced by ``fn(i, k, div)``.

    ``i`` is the 1-based link, ``k`` the 0-based division; loads, actuators and
    loops are kept.

    ``added_mass`` is kept when the new divisions have the same points, else a
    ``ValueError`` (its per-point shape depends on them) names ``what``.
    """
    links = []
    for i, link in enumerate(linkage.links, start=1):
        if not isinstance(link, SoftLink):
            links.append(link)
            continue
        divs = [fn(i, k, div) for k, div in enumerate(link.divisions)]
        links.append(
            SoftLink(divs, link.material, link.joint, link.g_i, link.g_f, link.color)
        )
    kw = dict(
        parents=linkage.parents,
        placements=linkage.placements,
        gravity=linkage.gravity,
        point_wrenches=linkage.point_wrenches,
        custom_wrench=linkage.custom_wrench,
        actuators=linkage.actuators,
        closed_loops=linkage.closed_loops,
        custom_actuation=linkage.custom_actuation,
        actuator_strength=linkage.actuator_strength,
        baumgarte_time=linkage.baumgarte_time,
        contact=linkage.contact,
    )
    out = Linkage(links, **kw)
    if linkage.added_mass is None:
        return out
    if out.n_points != linkage.n_points:
        raise ValueError(
            f"{what}: this linkage has added_mass, whose shape depends on the points, "
            f"and the new divisions have {out.n_points} points instead of "
            f"{linkage.n_points}; rebuild it by hand (or keep the points: give "
            "n_gauss)."
        )
    return Linkage(links, **kw, added_mass=linkage.added_mass)


def size_class(
    linkage: Linkage,
    order: int,
    modes=None,
    n_gauss: int | None = None,
    divisions: int | None = None,
) -> Linkage:
    """``linkage`` padded to the size class of ``order`` (see the module docstring).

    Models padded to the same class share their compiled programs: a new order
    (up to ``order``) or, with ``modes`` given, a new set of modes, reuses them.
    Their coordinates are the class's (``q`` is longer, the padding stays exactly
    0): :func:`active_coordinates` gives the model's own ones.

    Args:
        linkage: a linkage whose soft divisions have Legendre or monomial bases.
        order: the class order, >= every division's own orders.
        modes: six 0/1 flags of the class's modes (every division gets them; its
            own modes must be among them), or None to keep each division's own
            modes (then only orders vary within the class).
        n_gauss: interior points of every padded division; default the larger of
            the division's own and the default for ``order`` (``max(8, 2 order +
            4)``), so that every order up to ``order`` lands on the same points.
        divisions: pad every soft link to this many divisions with empty ones
            (length 0, every coefficient off, after the link's own), so that
            models with up to ``divisions`` divisions per link share the
            programs too; None keeps each link's own number.

    Returns:
        The padded :class:`~sorojax.Linkage`.

    Raises:
        ValueError: a division with a custom or already padded basis, an order above
            ``order``, a mode outside ``modes``, a link with more than
            ``divisions`` divisions, or a bad ``order``/``n_gauss``/``divisions``.
    """
    if not isinstance(order, int | np.integer) or order < 0:
        raise ValueError(f"size_class: order = {order!r}: give an integer >= 0.")
    if n_gauss is not None and (
        not isinstance(n_gauss, int | np.integer) or n_gauss < 1
    ):
        raise ValueError(f"size_class: n_gauss = {n_gauss!r}: give an integer >= 1.")
    if divisions is not None and (
        not isinstance(divisions, int | np.integer) or divisions < 1
    ):
        raise ValueError(
            f"size_class: divisions = {divisions!r}: give an integer >= 1, or None."
        )
    if modes is not None:
        modes = tuple(int(bool(m)) for m in modes)
        if len(modes) != 6:
            raise ValueError(
                f"size_class: modes has {len(modes)} entries: give six 0/1 flags for "
                f"{MODE_NAMES}, or None to keep each division's modes."
            )

    def pad(i: int, k: int, div: Division) -> Division:
        b = div.basis
        where = f"link {i} division {k + 1}"
        if not isinstance(b, AbstractPolynomialBasis):
            raise ValueError(
                f"size_class: {where} has a {type(b).__name__}; only Legendre and "
                "monomial bases pad (their families are nested: the first o + 1 "
                "polynomials of order `order` are those of order o)."
            )
        cm = b.modes if modes is None else modes
        cols = []
        for name, m, o, c in zip(MODE_NAMES, b.modes, b.orders, cm, strict=True):
            if m and not c:
                raise ValueError(
                    f"size_class: {where} has mode {name} on, but the class's modes "
                    f"{cm} have it off: give modes with {name} on."
                )
            if m and o > order:
                raise ValueError(
                    f"size_class: {where} has {name} at order {o} > the class order "
                    f"{order}: give order >= {o}."
                )
            if c:
                cols += [1.0 if m and j <= o else 0.0 for j in range(order + 1)]
        basis = PaddedBasis(type(b)(cm, order), jnp.asarray(np.asarray(cols)))
        ng = max(div.n_gauss, default_n_gauss(order)) if n_gauss is None else n_gauss
        return Division(div.length, div.section, basis, ng, div.xi_ref)

    padded = replace_divisions(linkage, pad, "size_class")
    if divisions is None:
        return padded
    return _pad_divisions(padded, divisions)


def _pad_divisions(linkage: Linkage, divisions: int) -> Linkage:
    """Every soft link of a padded linkage filled up to ``divisions`` divisions.

    The empty divisions copy the link's last one (section, class basis, points)
    with length 0 and every column off: their Magnus steps are the identity, their
    weights (mass, stiffness, loads) zero, their coordinates locked at zero, and
    their points sit at the link's tip.
    """

    def empty(div: Division) -> Division:
        b = div.basis
        # host arrays (jnp.zeros would compile a program per shape)
        off = PaddedBasis(b.basis, jnp.asarray(np.zeros(b.active.shape)))
        return eqx.tree_at(lambda d: (d.length, d.basis), div, (jnp.asarray(0.0), off))

    links = list(linkage.links)
    for i, link in enumerate(links, start=1):
        if not isinstance(link, SoftLink):
            continue
        n = len(link.divisions)
        if n < divisions and linkage.added_mass is not None:
            raise ValueError(
                "size_class: this linkage has added_mass, whose shape depends on the "
                f"points, and padding link {i} to {divisions} divisions adds points; "
                "leave divisions None."
            )
        if n > divisions:
            raise ValueError(
                f"size_class: link {i} has {n} divisions > divisions = {divisions}: "
                f"give divisions >= {n}."
            )
        extra = tuple(empty(link.divisions[-1]) for _ in range(divisions - n))
        links[i - 1] = eqx.tree_at(
            lambda lk: lk.divisions, link, link.divisions + extra
        )
    return eqx.tree_at(lambda lk: lk.links, linkage, tuple(links))


def active_coordinates(linkage: Linkage) -> np.ndarray:
    """Indices into ``q`` of the model's own coordinates, in the model's order.

    For a padded linkage (:func:`size_class`), ``q[active_coordinates(padded)]`` is
    the unpadded model's ``q``, and the model's ``q`` goes the other way as
    ``np.zeros(padded.n_dof)`` with those entries set (e.g. an initial shape); for
    any other linkage, every index.
    """
    lay = linkage.layout
    out = []
    for link, ll in zip(linkage.links, lay.links, strict=True):
        out.extend(range(ll.joint_offset, ll.joint_offset + ll.joint_n_dof))
        if not isinstance(link, SoftLink):
            continue
        for div, dl in zip(link.divisions, ll.divisions, strict=True):
            b = div.basis
            if isinstance(b, PaddedBasis):
                act = np.asarray(b.active)
                out.extend(dl.offset + int(j) for j in np.flatnonzero(act > 0.5))
            else:
                out.extend(range(dl.offset, dl.offset + dl.n_dof))
    return np.asarray(out, dtype=int)
