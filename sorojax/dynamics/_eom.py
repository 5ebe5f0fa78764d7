"""Equations of motion M(q) qdd = F(q, qd, t) + tau - C(q, qd) qd - D qd - K q.

One pass forms the body Jacobians J at the kinematic chain's points, the twists J qd
and their velocity-product rates Jdot qd (the recursion differentiated in time, no
Jdot matrix), and the poses and twists of the leaves (contact samples, one Magnus
step each from their chain point); then M = sum w J^T M J over the points that carry
mass, and every point force (inertial, gravity, point wrenches, contact, custom hook)
is gathered as one body wrench per point and mapped by J^T (a leaf's wrench first
crosses its step to its chain point). With many coordinates in several groups
(:class:`~sorojax.model._precompute.GroupBasis`) M comes from composite inertias
(:mod:`sorojax.dynamics._composite`) and every wrench, the inertial ones included,
from the backward sweep (:func:`~sorojax.dynamics._wrench_recursion.
force_from_wrenches`): no point's Jacobian is formed. K and D are constant
(precomputed once per solve, outside the integrator's loop).
"""

import functools
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.linalg import cho_factor, cho_solve
from jaxtyping import Array, ArrayLike, Float

from .._jit import jit
from ..kinematics._api import Kinematics, _as_q
from ..kinematics._recursion import (
    PointRates,
    chain_layout,
    jacobians_dot,
    point_jacobians,
    point_rates,
    point_rows,
    rest_rates,
    rows_of,
    strains,
)
from ..model._checks import check_finite, is_concrete
from ..model._linkage import Linkage
from ..model._precompute import LinkageData, precompute
from ._actuation import actuation_loads, effective_inputs
from ._composite import composite_mass, uses_composite
from ._constraints import (
    constraint_terms_from_kinematics,
)
from ._contact import contact_loads, contact_pairs
from ._external import custom_wrenches, gravity_wrenches, point_wrenches
from ._mass import _gyroscopic, _mass_from_J
from ._wrench_recursion import force_from_point_rates, force_from_wrenches

GeneralizedForce = Callable[[Array, Array, Array], ArrayLike]
"""``tau(t, q, qd) -> (n_dof,)`` generalised actuation force added to the right side."""


InputFunction = Callable[[Array], Array]
"""``u(t) -> (n_inputs,)`` actuation inputs as a function of time (pure JAX)."""


_FIELDS = ("g", "J", "xi", "eta", "Jdot")


def _fields_read(read: Callable, shapes: dict) -> frozenset[str]:
    """The :class:`Kinematics` fields that ``read(kinematics)`` reads.

    ``read`` (a hook's call) is traced once on abstract fields and a field counts as
    read where the trace uses it; if that trace fails, every field.
    """

    def probe(*fields):
        return read(Kinematics(**dict(zip(_FIELDS, fields, strict=True))))

    try:
        jaxpr = jax.make_jaxpr(probe)(*(shapes[name] for name in _FIELDS)).jaxpr
    except Exception:  # noqa: BLE001 - the real call raises its own error
        return frozenset(_FIELDS)
    used = {id(v) for eqn in jaxpr.eqns for v in eqn.invars}
    used |= {id(v) for v in jaxpr.outvars}
    return frozenset(
        name for name, v in zip(_FIELDS, jaxpr.invars, strict=True) if id(v) in used
    )


def _field_shapes(n_points: int, n_dof: int, dtype) -> dict:
    """Abstract :class:`Kinematics` fields of a linkage, by name."""
    shapes = {
        "g": (n_points, 4, 4),
        "J": (n_points, 6, n_dof),
        "xi": (n_points, 6),
        "eta": (n_points, 6),
        "Jdot": (n_points, 6, n_dof),
    }
    return {k: jax.ShapeDtypeStruct(v, dtype) for k, v in shapes.items()}


def hooks_read(linkage: Linkage, t, q, qd, u, n_points: int) -> frozenset[str] | None:
    """The :class:`Kinematics` fields the linkage's hooks read; None: it has none.

    ``u``: the inputs (None: zeros), for the custom actuation hook's trace.
    """
    calls = []
    if linkage.custom_wrench is not None:
        calls.append(functools.partial(linkage.custom_wrench, t, q, qd))
    if linkage.actuator_strength is not None:
        calls.append(functools.partial(linkage.actuator_strength, t, q, qd))
    if linkage.custom_actuation is not None:
        u_ = jnp.zeros(linkage.n_inputs, q.dtype) if u is None else u
        hook = functools.partial(linkage.custom_actuation, t, q, qd)
        calls.append(lambda kin: hook(kin, u_))
    if not calls:
        return None
    shapes = _field_shapes(n_points, q.shape[0], q.dtype)
    return frozenset().union(*(_fields_read(c, shapes) for c in calls))


def lazy_kinematics(data: LinkageData, q, qd, rates: PointRates):
    """``kin_fn(read)``: the :class:`Kinematics` a hook call ``read(kinematics)`` reads.

    Each field is traced only if some hook reads it (:func:`_fields_read`), once;
    the fields a hook does not read are zeros in the kinematics it is given (its
    result does not depend on them). ``rates``, the dynamics' :func:`point_rates` at
    ``(q, qd)``, give the poses and twists; every point's Jacobian is carried from
    them (:func:`point_jacobians`). A field nobody reads is neither traced nor
    compiled: the damping hooks of :mod:`sorojax.contrib.cosseratbench` read the
    twists only, the crawler's actuation hook (``examples/crawler_gait.py``) nothing.
    """
    shapes = _field_shapes(rates.g.shape[0], q.shape[0], q.dtype)
    make = {
        "g": lambda: rates.g,
        "J": lambda: point_jacobians(data, rates),
        "xi": lambda: strains(data, q),
        "eta": lambda: rates.eta,
        "Jdot": lambda: jacobians_dot(data, q, qd),
    }
    cache: dict = {}

    def kin_fn(read: Callable | None = None) -> Kinematics:
        names = frozenset(_FIELDS) if read is None else _fields_read(read, shapes)
        for name in names:
            if name not in cache:
                cache[name] = make[name]()
        return Kinematics(**{
            k: cache[k] if k in names else jnp.zeros(shapes[k].shape, q.dtype)
            for k in _FIELDS
        })  # fmt: skip

    return kin_fn


def _added_mass(linkage: Linkage, data: LinkageData, idx) -> Array | None:
    """The points ``idx``'s added-mass matrices times their weights (None: none)."""
    if linkage.added_mass is None:
        return None
    return data.point_weight[idx, None, None] * linkage.added_mass[idx]


def mass_matrix(linkage: Linkage, data: LinkageData, rates: PointRates) -> Array:
    """``M``, the linkage's added mass included.

    From composite inertias (:mod:`sorojax.dynamics._composite`) where the chain's
    steps have :class:`~sorojax.model._precompute.GroupBasis` (many coordinates in
    several groups), else from the chain points' Jacobians.
    """
    idx = np.asarray(data.mass_points, dtype=int)
    Ma = _added_mass(linkage, data, idx)
    if uses_composite(data):
        k, ct = rates.records
        return composite_mass(data, k, ct, chain_layout(data), Ma)
    row = rows_of(data, rates)
    M = _mass_from_J(data, rates.J, row)
    if Ma is None:
        return M
    J_m = rates.J[row[idx]]
    return M + jnp.einsum("pai,pab,pbj->ij", J_m, Ma, J_m)


def mass_and_force(
    linkage: Linkage,
    data: LinkageData,
    t,
    q,
    qd,
    generalized_force: GeneralizedForce | None = None,
    u=None,
    rates: PointRates | None = None,
    kin_fn=None,
) -> tuple[Array, Array]:
    """``(M, f)`` with ``M qdd = f``: mass matrix and all other generalised forces.

    ``u`` are the actuation inputs at ``t`` (None: no actuator forces); prescribed
    joints add nothing here (their efforts are constraint multipliers). ``rates``:
    ``point_rates(data, q, qd)`` if the caller has it already, ``kin_fn`` its
    :func:`lazy_kinematics` (what the hooks read).

    The inertial forces and M sum over the points that carry mass; every other
    wrench is gathered per point and mapped in one product with the chain points'
    Jacobians (leaves' wrenches first carried to their chain points).
    """
    if rates is None:
        rates = point_rates(data, q, qd)
    g = rates.g
    if kin_fn is None:
        kin_fn = lazy_kinematics(data, q, qd, rates)
    row = rows_of(data, rates)
    idx = np.asarray(data.mass_points, dtype=int)
    rows = row[idx]  # the mass points' rows in J
    Mw = data.point_weight[idx, None, None] * data.point_M[idx]
    g_m, eta_m = point_rows(data, rates, idx)
    W_m = gravity_wrenches(data, g_m, idx) - _gyroscopic(Mw, eta_m, rates.etadot[rows])
    M = mass_matrix(linkage, data, rates)
    Ma = _added_mass(linkage, data, idx)
    if Ma is not None:
        W_m = W_m - jnp.einsum("pab,pb->pa", Ma, rates.etadot[rows])
    lay = chain_layout(data)
    W = point_wrenches(linkage, t, g)  # gravity: with the inertial forces
    # whether W may hold wrenches on the leaves (static, noted with each load that
    # may reach them): else the leaves' rows of W are not read
    on_leaves = bool(linkage.point_wrenches)
    leaf_rows = None
    if linkage.contact is not None:
        Wc, leaf_rows = contact_loads(linkage, t, rates, lay)
        W = W + Wc
        on_leaves = on_leaves or contact_pairs(linkage)
    if linkage.custom_wrench is not None:
        read = functools.partial(linkage.custom_wrench, t, q, qd)
        W = W + custom_wrenches(linkage, data, t, q, qd, kin_fn(read))
        on_leaves = True
    if u is not None:
        Qa, Wa = actuation_loads(linkage, data, t, q, qd, u, kin_fn, g)
        if Wa is not None:
            W = W + Wa
            on_leaves = True
    if uses_composite(data):  # no Jacobian: every wrench by the backward sweep
        at = np.full(W.shape[0], len(idx))
        at[idx] = np.arange(len(idx))
        W = W + jnp.concatenate([W_m, jnp.zeros_like(W_m[:1])])[at]
        records = (*rates.records, lay, rates.leaves)
        f = force_from_wrenches(data, records, W, leaf_rows, on_leaves)
    else:
        J_m = rates.J[rows]
        f = force_from_point_rates(data, rates, W, leaf_rows, on_leaves)
        f = f + jnp.einsum("pai,pa->i", J_m, W_m)
    f = f - data.K @ q - data.D @ qd
    if u is not None:
        f = f + Qa
    if generalized_force is not None:
        tau = jnp.asarray(generalized_force(t, q, qd), dtype=f.dtype)
        if tau.shape != f.shape:
            raise ValueError(
                f"generalized_force returned shape {tau.shape}; expected "
                f"({f.shape[0]},) (one force per coordinate)."
            )
        f = f + tau
    return M, f


@jax.custom_jvp
def spd_solve(M: Array, f: Array) -> Array:
    """``M^-1 f`` for symmetric positive definite ``M`` (Cholesky).

    Its JVP ``dx = M^-1 (df - dM x)`` reuses the factorisation: the implicit solvers'
    forward-mode Jacobians then cost one multi-column triangular solve, where the
    default Cholesky derivative under ``vmap`` costs a batched factorisation per
    tangent direction (~1000x slower on CPU at 12 DoF).
    """
    return cho_solve(cho_factor(M), f)


@spd_solve.defjvp
def _spd_solve_jvp(primals, tangents):
    M, f = primals
    dM, df = tangents
    c = cho_factor(M)
    x = cho_solve(c, f)
    return x, cho_solve(c, df - dM @ x)


def accelerations(
    linkage: Linkage,
    data: LinkageData,
    t,
    q,
    qd,
    generalized_force: GeneralizedForce | None = None,
) -> Array:
    """``qdd`` from one Cholesky solve of ``M qdd = f`` (no actuators, no loops)."""
    M, f = mass_and_force(linkage, data, t, q, qd, generalized_force)
    return spd_solve(M, f)


def _loop_terms(linkage: Linkage, data: LinkageData, rates: PointRates):
    """The closed loops' ``(e, A, Adot qd)`` from the dynamics' kinematics."""
    return constraint_terms_from_kinematics(
        linkage, rates.g, rates.J, rates.eta, rates.etadot, rows=rows_of(data, rates)
    )


def is_constrained(linkage: Linkage) -> bool:
    """Whether the dynamics has constraint rows (prescribed joints or closed loops)."""
    return bool(len(linkage.prescribed[0]) or linkage.closed_loops)


def prescribed_motion(linkage: Linkage, u_fn: InputFunction, t):
    """``(q_p, qd_p, qdd_p)`` of the prescribed coordinates at ``t`` (autodiff in t)."""
    _, ui = linkage.prescribed

    def qp(t_):
        return u_fn(t_)[ui]

    def qdp(t_):
        return jax.jvp(qp, (t_,), (jnp.ones_like(t_),))[1]

    v, vd = jax.jvp(qp, (t,), (jnp.ones_like(t),))
    return v, vd, jax.jvp(qdp, (t,), (jnp.ones_like(t),))[1]


class ConstrainedState(eqx.Module):
    """Accelerations and multipliers of the constrained dynamics at one instant.

    Attributes:
        qd: velocities with the prescribed entries set to their exact values.
        qdd: accelerations.
        u: inputs after the actuator-strength hook.
        efforts: efforts of the prescribed coordinates (multipliers of their rows).
        lam: closed-loop multipliers.
        M: the mass matrix at (q, qd) (the stiff part's matrices for
            :class:`sorojax.integrate.RosenbrockW`).
    """

    qd: Array
    qdd: Array
    u: Array
    efforts: Array
    lam: Array
    M: Array


def constrained_dynamics(
    linkage: Linkage,
    data: LinkageData,
    t,
    q,
    qd,
    u_fn: InputFunction,
    generalized_force: GeneralizedForce | None = None,
    return_rates: bool = False,
):
    """The saddle-point solve with prescribed coordinates and closed loops.

    Returns the :class:`ConstrainedState`, and with ``return_rates`` also the
    kinematics it used (:class:`~sorojax.kinematics._recursion.PointRates`, at the
    prescribed values).

    ``M qdd = f + G^T mu`` with constraint rows ``G qdd = b``: one-hot rows
    ``qdd_p = u''(t)`` for prescribed coordinates (their values and velocities are
    set to ``u(t)``, ``u'(t)`` first) and, for closed loops, Baumgarte-stabilised
    ``A qdd = -Adot qd - (2/T) A qd - e/T^2`` (T = ``linkage.baumgarte_time``). The
    multipliers come from ``(G M^-1 G^T + eps I) mu = b - G M^-1 f`` with a tiny
    relative ``eps`` (1e-10), which keeps redundant rows (a planar loop's out-of-plane
    rows) solvable: they get the minimum-norm multipliers.
    """
    qi, _ = linkage.prescribed
    n = q.shape[0]
    u = u_fn(t)
    rows, rhs = [], []
    if len(qi):
        qp, qdp, qddp = prescribed_motion(linkage, u_fn, t)
        q, qd = q.at[qi].set(qp), qd.at[qi].set(qdp)
        rows.append(jnp.eye(n, dtype=q.dtype)[qi])
        rhs.append(qddp)
    rates = point_rates(data, q, qd)
    if linkage.closed_loops:
        e, A, bias = _loop_terms(linkage, data, rates)
        Tb = linkage.baumgarte_time
        rows.append(A)
        rhs.append(-bias - (2.0 / Tb) * (A @ qd) - e / Tb**2)
    kin_fn = lazy_kinematics(data, q, qd, rates)
    M, f = mass_and_force(linkage, data, t, q, qd, generalized_force, u, rates, kin_fn)
    if rows:
        G, b = jnp.concatenate(rows), jnp.concatenate(rhs)
        X = spd_solve(M, jnp.concatenate([f[:, None], G.T], axis=1))
        Minv_f, Minv_Gt = X[:, 0], X[:, 1:]
        S = G @ Minv_Gt
        eps = 1e-10 * jnp.maximum(jnp.trace(S) / S.shape[0], 1e-300)
        mu = jnp.linalg.solve(
            S + eps * jnp.eye(S.shape[0], dtype=S.dtype), b - G @ Minv_f
        )
        qdd = Minv_f + Minv_Gt @ mu
    else:
        mu = jnp.zeros((0,), q.dtype)
        qdd = spd_solve(M, f)
    u_eff = effective_inputs(linkage, t, q, qd, kin_fn, u)
    st = ConstrainedState(
        qd=qd, qdd=qdd, u=u_eff, efforts=mu[: len(qi)], lam=mu[len(qi) :], M=M
    )
    return (st, rates) if return_rates else st


def consistent_velocities(
    linkage: Linkage, data: LinkageData, t, q, qd, u_fn: InputFunction
) -> Array:
    """``qd`` projected onto the velocity constraints (mass-weighted, least change).

    Prescribed entries become ``u'(t)`` and the rest change as little as possible in
    kinetic energy so that ``A qd = 0`` (closed loops): ``qd + M^-1 G^T mu``.
    """
    qi, _ = linkage.prescribed
    if not is_constrained(linkage):
        return qd
    rows, rhs = [], []
    if len(qi):
        _, qdp, _ = prescribed_motion(linkage, u_fn, t)
        rows.append(jnp.eye(q.shape[0], dtype=q.dtype)[qi])
        rhs.append(qdp)
    rates = rest_rates(data, q)  # zero twists and rates: A and M need J only
    if linkage.closed_loops:  # A from the body Jacobians M needs anyway
        rows.append(_loop_terms(linkage, data, rates)[1])
        rhs.append(jnp.zeros(linkage.n_constraints, q.dtype))
    G, b = jnp.concatenate(rows), jnp.concatenate(rhs)
    M = mass_matrix(linkage, data, rates)
    Minv_Gt = spd_solve(M, G.T)
    S = G @ Minv_Gt
    eps = 1e-12 * jnp.maximum(jnp.trace(S) / S.shape[0], 1e-300)
    mu = jnp.linalg.solve(S + eps * jnp.eye(S.shape[0], dtype=S.dtype), b - G @ qd)
    return qd + Minv_Gt @ mu


@jit
def forward_dynamics(
    linkage: Linkage,
    q: ArrayLike,
    qd: ArrayLike,
    t: ArrayLike = 0.0,
    generalized_force: GeneralizedForce | None = None,
    u: ArrayLike | None = None,
) -> Float[Array, " n_dof"]:
    """Generalised accelerations ``qdd`` at ``(q, qd, t)``.

    Args:
        linkage: the model.
        q: coordinates ``(n_dof,)``.
        qd: velocities ``(n_dof,)``.
        t: time [s] (for time-varying loads).
        generalized_force: optional ``tau(t, q, qd)`` added to the right-hand side.
        u: actuation inputs ``(n_inputs,)`` (default zeros). With prescribed
            joints or closed loops the accelerations satisfy the constraint rows
            (prescribed accelerations zero for a constant ``u``; Baumgarte terms
            for the loops).
    """
    q, qd = _as_q(linkage, q), _as_q(linkage, qd, "qd")
    t = jnp.asarray(t, dtype=q.dtype)
    data = precompute(linkage)
    if not (
        linkage.actuators
        or linkage.closed_loops
        or linkage.custom_actuation is not None
    ):
        if u is not None:  # refused unless empty: no actuator would take it
            as_inputs(linkage, u, q.dtype)
        return accelerations(linkage, data, t, q, qd, generalized_force)
    u_ = as_inputs(linkage, u, q.dtype)
    st = constrained_dynamics(linkage, data, t, q, qd, lambda _: u_, generalized_force)
    return st.qdd


@jit
def equations_of_motion(
    linkage: Linkage,
    q: ArrayLike,
    qd: ArrayLike,
    t: ArrayLike = 0.0,
    generalized_force: GeneralizedForce | None = None,
    u: ArrayLike | None = None,
) -> tuple[Float[Array, "n_dof n_dof"], Float[Array, " n_dof"]]:
    """``(M, f)``: mass matrix and right side of ``M qdd = f`` at ``(q, qd, t)``.

    ``u``: actuation inputs (default: none applied); actuator forces are included
    in ``f``, except prescribed joints' efforts and closed-loop forces, which are
    multipliers (see :func:`constrained_dynamics`).
    """
    q, qd = _as_q(linkage, q), _as_q(linkage, qd, "qd")
    t = jnp.asarray(t, dtype=q.dtype)
    u_ = None if u is None else as_inputs(linkage, u, q.dtype)
    return mass_and_force(linkage, precompute(linkage), t, q, qd, generalized_force, u_)


def as_inputs(linkage: Linkage, u, dtype) -> Array:
    """``u`` as an ``(n_inputs,)`` array (zeros if None), or a clear error."""
    m = linkage.n_inputs
    if u is None:  # made on the host: jnp.zeros compiles a program per size
        return jnp.asarray(np.zeros(m, dtype))
    u = jnp.asarray(u, dtype=dtype).reshape(-1)
    if u.shape != (m,):
        if m == 0:
            shown = (
                f"u = {np.asarray(u).tolist()}"
                if is_concrete(u)
                else f"u has shape {u.shape}"
            )
            raise ValueError(
                f"{shown}, but this linkage has no actuators (n_inputs = 0): "
                "add actuators to Linkage(actuators=...) or drop u."
            )
        raise ValueError(
            f"u has shape {u.shape}; this linkage has n_inputs = {m} (see "
            "Linkage.input_slices): give one entry per input, in actuator order."
        )
    check_finite("u", u, "give finite inputs (tensions [N], joint efforts, ...)")
    return u
