"""Generalised actuation forces: joint actuators, cables, the custom actuation hook.

Cables (DESIGN.md section 4): the generalised force of a cable of tension T is
``-T dl/dq`` with ``l(q)`` the cable's length, so ``B = -dl/dq`` is exact for any path.
Inside a soft link the cable runs at ``d(X) = (0, y, z)`` in the cross-section frame;
its position is ``r + R d`` and its tangent ``R (nu + k x d + d')`` with
``xi = (k, nu) = Phi q + xi_ref``, so the length of a span is

    l_span = int |nu + k x d + d'| ds

(Gauss quadrature at the division's points, the same rule as K). Between consecutive
route elements the cable runs straight, ``|p_b - p_a|`` between world points. For a
constant offset in an inextensible rod ``dl/dk_z = -y``: the tension bends the rod
toward the cable with moment ``T y``.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._jit import jit
from ..kinematics._api import Kinematics, _as_q
from ..model._actuation import Cable, CableSpan, JointActuator
from ..model._linkage import Linkage
from ..model._precompute import LinkageData, precompute
from ._wrench_recursion import poses_with_records


def _safe_norm(x: Array) -> Array:
    """Euclidean norm with a zero (not NaN) gradient at x = 0."""
    n2 = jnp.sum(x * x, axis=-1)
    pos = n2 > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, n2, 1.0)), 0.0)


def _span_divisions(linkage: Linkage, span: CableSpan) -> range:
    nd = len(linkage.links[span.link - 1].divisions)
    first, last = (1, nd) if span.divisions is None else span.divisions
    return range(first - 1, last)


def _division_X(linkage: Linkage, link: int, k: int, X1) -> Array:
    """Link-normalised X of division ``k`` (0-based) positions ``X1``."""
    divs = linkage.links[link - 1].divisions
    start = sum((d.length for d in divs[:k]), jnp.zeros(()))
    return (start + jnp.asarray(X1) * divs[k].length) / linkage.links[link - 1].length


def _offset3(path, X) -> Array:
    yz = path(X)
    return jnp.concatenate([jnp.zeros((1,), yz.dtype), yz])


def _span_offsets(linkage: Linkage, span: CableSpan, k: int):
    """``(d, d')`` of a span at division ``k``'s points, ``(points, 3)`` each.

    The offset and its arc-length derivative (``k`` 0-based); constants of the model.
    """
    dl = linkage.layout.links[span.link - 1].divisions[k]
    X = _division_X(linkage, span.link, k, dl.X1)
    path = jax.vmap(lambda x: _offset3(span.path, x))
    d, dX = jax.jvp(path, (X,), (jnp.ones_like(X),))
    return d, dX / linkage.links[span.link - 1].length


def _division_strain_and_weights(linkage: Linkage, data: LinkageData, link_no, k, q):
    """``(xi, w L)``: strains ``Phi q + xi_ref`` at division ``k``'s points, weights.

    The quadrature weights are in metres (times the division's length).
    """
    dd = data.links[link_no - 1].divisions[k]
    dl = linkage.layout.links[link_no - 1].divisions[k]
    xi = jnp.einsum("pij,j->pi", dd.Phi, q[dd.offset : dd.offset + dd.n_dof])
    wL = jnp.asarray(dl.w) * linkage.links[link_no - 1].divisions[k].length
    return xi + dd.xi_ref, wL


def _cable_tangent(xi, d, d_prime):
    """The cable's tangent ``nu + omega x d + d'`` from the strain ``(omega, nu)``."""
    return xi[..., 3:] + jnp.cross(xi[..., :3], d) + d_prime


def span_length(linkage: Linkage, data: LinkageData, span: CableSpan, q) -> Array:
    """Length of the cable inside ``span`` at ``q`` [m]."""
    total = jnp.zeros((), q.dtype)
    for k in _span_divisions(linkage, span):
        d, d_prime = _span_offsets(linkage, span, k)
        xi, wL = _division_strain_and_weights(linkage, data, span.link, k, q)
        total = total + jnp.sum(wL * _safe_norm(_cable_tangent(xi, d, d_prime)))
    return total


def _span_ends(linkage: Linkage, span: CableSpan):
    """((point, local offset) at the start, (point, local offset) at the end)."""
    ks = _span_divisions(linkage, span)
    lay = linkage.layout.links[span.link - 1]
    d0, d1 = lay.divisions[ks[0]], lay.divisions[ks[-1]]
    X0 = _division_X(linkage, span.link, ks[0], 0.0)
    X1 = _division_X(linkage, span.link, ks[-1], 1.0)
    return (
        (d0.first_point, _offset3(span.path, X0)),
        (d1.first_point + len(d1.X1) - 1, _offset3(span.path, X1)),
    )


def _world_point(g, point: int | None, offset) -> Array:
    if point is None:  # ground
        return offset
    return g[point, :3, :3] @ offset + g[point, :3, 3]


def _route_points(linkage: Linkage, cable: Cable) -> list:
    """``((point, offset) start, (point, offset) end)`` of each route element.

    ``point`` is a significant-point index or None (ground); consecutive elements
    are joined by straight segments (end of one to start of the next).
    """
    ends = []
    for r in cable.route:
        if isinstance(r, CableSpan):
            ends.append(_span_ends(linkage, r))
        else:
            point = None if r.link == 0 else linkage.anchor_index(r)
            ends.append(((point, r.offset), (point, r.offset)))
    return ends


def _segments(linkage: Linkage, cable: Cable) -> list:
    """Straight segments ``((point_a, offset_a), (point_b, offset_b))`` of a cable."""
    ends = _route_points(linkage, cable)
    return [(a[1], b[0]) for a, b in zip(ends[:-1], ends[1:], strict=True)]


def _spans_length(linkage: Linkage, data: LinkageData, cable: Cable, q) -> Array:
    """Length of the cable inside the body (its spans) [m]; strains only."""
    total = jnp.zeros((), q.dtype)
    for r in cable.route:
        if isinstance(r, CableSpan):
            total = total + span_length(linkage, data, r, q)
    return total


def _spans_force(linkage: Linkage, data: LinkageData, cables, q, tensions) -> Array:
    """``-sum_c T_c dl_c/dq`` of the cables' spans, in closed form, per division.

    A span's length is ``sum_p w_p |t_p|`` with the cable tangent
    ``t = nu + omega x d + d'`` (strain ``xi = (omega, nu) = Phi q + xi_ref``, offset
    ``d(X)``), so ``d|t|/d xi = (d x t_hat, t_hat)`` (zero where ``t = 0``, like
    :func:`_safe_norm`'s gradient) and the force on a division's coordinates is
    ``-sum_c T_c sum_p w_p Phi_p^T (d x t_hat, t_hat)``. All spans through one
    division share one strain evaluation and one batched formula; the offsets are
    constants of the model. (Autodiff of the lengths, cable by cable and division by
    division, gave the 16-DoF two-division cable arm's dynamics program 1.1k of its
    16k HLO lines.) Equal to the length's gradient (tested).
    """
    groups: dict[tuple[int, int], list[tuple[int, CableSpan]]] = {}
    for ci, c in enumerate(cables):
        for r in c.route:
            if isinstance(r, CableSpan):
                for k in _span_divisions(linkage, r):
                    groups.setdefault((r.link, k), []).append((ci, r))
    Q = jnp.zeros_like(q)
    for (link_no, k), members in groups.items():
        dd = data.links[link_no - 1].divisions[k]
        offsets = [_span_offsets(linkage, span, k) for _, span in members]
        d = jnp.stack([o[0] for o in offsets])  # (members, points, 3)
        d_prime = jnp.stack([o[1] for o in offsets])
        T = tensions[np.array([ci for ci, _ in members])]
        xi, wL = _division_strain_and_weights(linkage, data, link_no, k, q)
        t = _cable_tangent(xi[None], d, d_prime)
        n = _safe_norm(t)
        t_hat = t / jnp.where(n > 0, n, 1.0)[..., None]
        G = jnp.concatenate([jnp.cross(d, t_hat), t_hat], axis=-1)  # (m, p, 6)
        G = jnp.einsum("m,p,mpa->pa", T, wL, G)
        Q = Q.at[dd.offset : dd.offset + dd.n_dof].add(
            -jnp.einsum("pai,pa->i", dd.Phi, G)
        )
    return Q


def cable_length(linkage: Linkage, data: LinkageData, cable: Cable, q, g=None):
    """Total length of ``cable`` at ``q``: spans plus straight segments [m]."""
    total = _spans_length(linkage, data, cable, q)
    segments = _segments(linkage, cable)
    if segments and g is None:
        g = poses_with_records(data, q)[0]
    for (pa, oa), (pb, ob) in segments:
        total = total + _safe_norm(_world_point(g, pb, ob) - _world_point(g, pa, oa))
    return total


def cable_lengths_from_data(linkage: Linkage, data: LinkageData, q) -> Array:
    """Lengths of all cables (in actuator order), ``(n_cables,)``."""
    cables = [a for a in linkage.actuators if isinstance(a, Cable)]
    if not cables:
        return jnp.zeros((0,), q.dtype)
    g = None
    if any(len(c.route) > 1 for c in cables):
        g = poses_with_records(data, q)[0]
    return jnp.stack([cable_length(linkage, data, c, q, g) for c in cables])


def cable_loads(linkage: Linkage, data: LinkageData, q, tensions, g):
    """Generalised force ``-sum_c T_c dl_c/dq`` split as ``(Q_spans, W)``.

    ``Q_spans`` is the part of the spans inside the body (their length depends on
    the strains alone: a gradient of the strain quadrature, no kinematics).
    ``W`` ``(n_points, 6)`` holds body wrenches whose ``sum_p J_p^T W_p`` is the part
    of the straight segments: a segment from ``a = r_a + R_a o_a`` to
    ``b = r_b + R_b o_b`` has ``dl = u . (db - da)``, ``u = (b - a) / |b - a|``,
    and ``db = R_b (v_b + w_b x o_b)``, so its tension acts at b with the body wrench
    ``-T (o_b x f_b, f_b)``, ``f_b = R_b^T u``, and at a with the opposite sign (the
    cable pulls its ends toward each other). Exact, like the length's gradient,
    which the tests compare it with.
    """
    cables = [a for a in linkage.actuators if isinstance(a, Cable)]
    Q = _spans_force(linkage, data, cables, q, tensions)
    W = jnp.zeros((data.point_weight.shape[0], 6), q.dtype)
    for T, c in zip(tensions, cables, strict=True):
        for (pa, oa), (pb, ob) in _segments(linkage, c):
            u = _world_point(g, pb, ob) - _world_point(g, pa, oa)
            n = _safe_norm(u)
            u = u / jnp.where(n > 0, n, 1.0)
            for point, o, sign in ((pb, ob, -T), (pa, oa, T)):
                if point is not None:
                    f = g[point, :3, :3].T @ u
                    W = W.at[point].add(sign * jnp.concatenate([jnp.cross(o, f), f]))
    return Q, W


def _cable_tensions(linkage: Linkage, u) -> Array:
    return jnp.stack(
        [
            u[sl][0]
            for a, sl in zip(linkage.actuators, linkage.input_slices, strict=True)
            if isinstance(a, Cable)
        ]
    )


def has_cables(linkage: Linkage) -> bool:
    """Whether any actuator is a cable."""
    return any(isinstance(a, Cable) for a in linkage.actuators)


def has_segments(linkage: Linkage) -> bool:
    """Whether any cable has a straight segment (its force needs the poses)."""
    return any(_segments(linkage, a) for a in linkage.actuators if isinstance(a, Cable))


def effective_inputs(linkage: Linkage, t, q, qd, kin_fn, u) -> Array:
    """Inputs after the actuator-strength hook (prescribed entries kept from ``u``)."""
    if linkage.actuator_strength is None:
        return u
    hook = functools.partial(linkage.actuator_strength, t, q, qd)
    v = jnp.asarray(hook(kin_fn(hook)), dtype=q.dtype)
    if v.shape != (linkage.n_inputs,):
        raise ValueError(
            f"Linkage.actuator_strength returned shape {v.shape}; expected "
            f"({linkage.n_inputs},) (one entry per actuation input)."
        )
    _, ui = linkage.prescribed
    return v.at[ui].set(u[ui]) if len(ui) else v


def actuation_loads(linkage: Linkage, data: LinkageData, t, q, qd, u, kin_fn, g):
    """Generalised force of all actuators at inputs ``u`` (hook applied), in two parts.

    Returns ``(Q, W)``: ``Q`` ``(n_dof,)`` acts on the coordinates directly (joint
    actuators, cable spans, the custom actuation hook); ``W`` ``(n_points, 6)`` (or
    None) holds body wrenches of cable segments outside the body, to be mapped by
    ``J^T`` (or the backward recursion) together with the other point loads.
    Prescribed joints contribute nothing here: their efforts are unknowns of the
    solvers. ``kin_fn(read)`` returns the :class:`Kinematics` at ``(q, qd)`` with the
    fields the hook call ``read(kinematics)`` reads (:func:`~sorojax.dynamics._eom.
    lazy_kinematics`); ``g`` are the point poses at ``q``.
    """
    Q = jnp.zeros_like(q)
    W = None
    if not linkage.actuators and linkage.custom_actuation is None:
        return Q, W
    u = effective_inputs(linkage, t, q, qd, kin_fn, u)
    for a, sl in zip(linkage.actuators, linkage.input_slices, strict=True):
        if isinstance(a, JointActuator) and not a.prescribed:
            jo = linkage.layout.links[a.link - 1].joint_offset
            Q = Q.at[jo : jo + a.n_inputs].add(u[sl])
    if has_cables(linkage):
        Qc, Wc = cable_loads(linkage, data, q, _cable_tensions(linkage, u), g)
        Q = Q + Qc
        W = Wc if has_segments(linkage) else None
    if linkage.custom_actuation is not None:
        hook = functools.partial(linkage.custom_actuation, t, q, qd)
        kin = kin_fn(lambda kin: hook(kin, u))
        Q = Q + custom_actuation_force(linkage, data, t, q, qd, kin, u)
    return Q, W


def custom_actuation_force(
    linkage: Linkage, data: LinkageData, t, q, qd, kin: Kinematics, u
) -> Array:
    """``sum w Phi^T W`` of the custom actuation hook's wrenches at rod points."""
    W = jnp.asarray(linkage.custom_actuation(t, q, qd, kin, u), dtype=q.dtype)  # type: ignore[misc]
    n_pts = linkage.layout.n_points
    if W.shape != (n_pts, 6):
        raise ValueError(
            f"Linkage.custom_actuation returned shape {W.shape}; expected "
            f"({n_pts}, 6) (one internal body-frame wrench per significant point)."
        )
    Q = jnp.zeros_like(q)
    for ld, ll in zip(data.links, linkage.layout.links, strict=True):
        for dd, dl in zip(ld.divisions, ll.divisions, strict=True):
            if not dd.n_dof:
                continue
            p = slice(dl.first_point, dl.first_point + len(dl.X1))
            w = data.point_weight[p]
            Qd = jnp.einsum("p,pai,pa->i", w, dd.Phi, W[p])
            Q = Q.at[dd.offset : dd.offset + dd.n_dof].add(Qd)
    return Q


def actuation_matrix_from_data(linkage: Linkage, data: LinkageData, q) -> Array:
    """``B (n_dof, n_inputs)``: generalised force per unit effort of each input.

    Joint actuators (wrench or prescribed) give unit columns on their coordinates
    (for a prescribed joint, the column its solved effort acts through); cables give
    ``-dl/dq``. The custom actuation hook is not included.
    """
    n = q.shape[0]
    cols = []
    dl = None
    if has_cables(linkage):
        dl = jax.jacrev(lambda q_: cable_lengths_from_data(linkage, data, q_))(q)
    c = 0
    for a in linkage.actuators:
        if isinstance(a, JointActuator):
            jo = linkage.layout.links[a.link - 1].joint_offset
            cols.append(jnp.eye(n, dtype=q.dtype)[:, jo : jo + a.n_inputs])
        else:
            assert dl is not None
            cols.append(-dl[c][:, None])
            c += 1
    if not cols:
        return jnp.zeros((n, 0), q.dtype)
    return jnp.concatenate(cols, axis=1)


@jit
def cable_lengths(linkage: Linkage, q: ArrayLike) -> Float[Array, " n_cables"]:
    """Lengths [m] of the linkage's cables at ``q``, in actuator order."""
    q = _as_q(linkage, q)
    return cable_lengths_from_data(linkage, precompute(linkage), q)


@jit
def actuation_matrix(linkage: Linkage, q: ArrayLike) -> Float[Array, "n_dof n_inputs"]:
    """The manual's actuation matrix ``B(q)``: generalised force = ``B`` times efforts.

    One column per input (actuator order): unit columns on the coordinates of joint
    actuators (wrench or prescribed), ``-dl/dq`` for a cable (force per newton of
    tension). Exact (autodiff of the cable lengths).
    """
    q = _as_q(linkage, q)
    return actuation_matrix_from_data(linkage, precompute(linkage), q)
