"""Static equilibrium K q = F(q) + Q_act(q, u) + A^T mu, e(q) = 0, by Newton's method.

The residual ``r(q) = K q - lambda (F(q, 0, t) + Q_act)`` is Jacobi-scaled by diag(K),
so the solver's absolute tolerance reads as a coordinate tolerance whatever the
stiffness units; with closed loops the unknowns add the multipliers and the rows the
closure errors. The Jacobian comes from autodiff. For large loads the load factor
lambda goes 1/n, 2/n, ..., 1, each solve warm-started from the last; by default n is
chosen from the size of the scaled residual at full load (automatic load stepping), so
the straight rod does not jump to a far (e.g. looped) equilibrium branch.
All increments and Newton iterations run in one ``lax.while_loop`` whose body evaluates
the residual, its Jacobian and the unscaled rows in one forward-mode pass (loose
tolerances for the intermediate increments, the requested ones for the last; only as
many increments as needed, also under ``vmap``) on stop-gradient data: the compiled
program holds one trace of the residual, which keeps its compile short (an
optimistix Newton solve with separate start and final evaluations traces it several
times). Gradients come from the implicit function theorem at the converged root,
by a custom JVP outside that loop (what ``optx.ImplicitAdjoint`` does) that solves
with the loop's last Jacobian instead of forming it again (a quarter smaller
differentiated programs); the returned residual rows carry their derivative in the
same JVP, from the same forward-mode pass of the residual. A user's optimistix
solver (``solver=``) runs each increment with optimistix's own loop.
"""

import math
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
from jax import lax
from jaxtyping import Array, ArrayLike

from .._jit import _bound_arguments, _top_level, jit
from .._recompile import note_hooks
from .._results import RESULTS, StaticsSolution, failed, throw_on_failure
from ..dynamics._actuation import actuation_loads
from ..dynamics._constraints import (
    closure_errors_and_wrenches,
    numerical_rank,
)
from ..dynamics._contact import (
    contact_wrenches_and_penetrations,
    obstacle_samples,
    smallest_radius,
    state_from_data,
)
from ..dynamics._eom import as_inputs, hooks_read
from ..dynamics._external import custom_wrenches, external_wrenches
from ..dynamics._generalized import kinematics_from_data
from ..dynamics._wrench_recursion import force_from_wrenches, poses_with_records
from ..kinematics._api import Kinematics, _as_q
from ..kinematics._recursion import poses, strains
from ..model._checks import check_finite, check_tolerances, is_concrete
from ..model._linkage import Linkage
from ..model._precompute import LinkageData, precompute
from ._stability import (
    UnstableEquilibriumWarning,
    reduced_tangent_spectrum,
    stability_summary,
)


def _row_scale(K) -> Array:
    d = jnp.abs(jnp.diag(K))
    fallback = jnp.where(jnp.any(d > 0), jnp.max(d), 1.0)
    return 1.0 / jnp.where(d > 0, d, fallback)


def equilibrium_residual(
    linkage: Linkage, data: LinkageData, q, t=0.0, lam=1.0, u=None, mu=None
) -> Array:
    """Unscaled residual ``K q - lam (F(q, 0, t) + Q_act(q, u)) - A^T mu``.

    ``u`` are the actuation inputs (default zeros), ``mu`` the closed-loop
    multipliers (default zeros). At equilibrium the rows of prescribed coordinates
    are their joint efforts.
    """
    return _residual_and_closure(linkage, data, q, t, lam, u, mu)[0]


def _residual_and_closure(linkage: Linkage, data: LinkageData, q, t, lam, u, mu):
    """``(r, e, d)``: residual, closure errors and contact penetrations, one pose pass.

    Every load is gathered as body wrenches at the significant points (gravity,
    point wrenches, cable segments outside the body, the multipliers' ``A^T mu``)
    and mapped to the coordinates together, by the backward wrench recursion (no
    Jacobian formed) or, when a hook reads the Jacobians, by ``J^T``; only joint
    actuators and cable spans act on the coordinates directly. The hooks' twists
    and Jacobian rates are zero here (``qd = 0``).
    """
    qd = jnp.zeros_like(q)
    read = hooks_read(linkage, t, q, qd, u, data.point_weight.shape[0])
    if read is not None and "J" in read:  # every point's Jacobian, for J^T W too
        kin = kinematics_from_data(data, q, qd, need_jdot=False)
        g, records = kin.g, None
    else:
        g, records = poses_with_records(data, q)
        kin = None
        if read is not None:  # hooks that read no Jacobian
            z6 = jnp.zeros((g.shape[0], 6), q.dtype)
            zJ = jnp.zeros((g.shape[0], 6, q.shape[0]), q.dtype)
            kin = Kinematics(g=g, J=zJ, xi=strains(data, q), eta=z6, Jdot=zJ)
    W = lam * external_wrenches(linkage, data, t, g)
    d = jnp.zeros((0,), q.dtype)
    if linkage.contact is not None:  # a reaction: never scaled by the load factor
        Wk, d = contact_wrenches_and_penetrations(linkage, t, g)
        W = W + Wk
    if linkage.custom_wrench is not None:
        W = W + lam * custom_wrenches(linkage, data, t, q, qd, kin)
    Q = jnp.zeros_like(q)
    if linkage.actuators or linkage.custom_actuation is not None:
        u = jnp.zeros(linkage.n_inputs, q.dtype) if u is None else u
        Qa, Wa = actuation_loads(linkage, data, t, q, qd, u, lambda read=None: kin, g)
        Q = lam * Qa
        if Wa is not None:
            W = W + lam * Wa
    e = jnp.zeros((0,), q.dtype)
    if linkage.closed_loops:
        mu_ = jnp.zeros(linkage.n_constraints, q.dtype) if mu is None else mu
        e, Wc = closure_errors_and_wrenches(linkage, g, mu_)
        if mu is not None:
            W = W + Wc
    if records is not None:
        F = force_from_wrenches(data, records, W)
    else:
        F = jnp.einsum("pai,pa->i", kin.J, W)
    return data.K @ q - F - Q, e, d, g


def _limits_moves(linkage: Linkage) -> bool:
    """Whether statics bounds each step's motion of the points.

    So it does for contacts between bodies, which a broad phase finds (rod pairs,
    self-contact, tubes).
    """
    c = linkage.contact
    return c is not None and bool(c.rod_pairs or c.self_contact or c.inside)


def free_coordinates(linkage: Linkage) -> np.ndarray:
    """Indices of the coordinates statics solves for (all but the prescribed)."""
    return np.setdiff1d(np.arange(linkage.n_dof), linkage.prescribed[0])


def scaled_equilibrium(linkage: Linkage, data: LinkageData, x, t, lam, u, q_p):
    """``(f, r)``: the statics solver's rows at unknowns ``x = (q_free, mu)``.

    ``f = (diag(K)^-1 r_free, e)`` (Jacobi-scaled equilibrium rows of the free
    coordinates, then the closure errors); ``r`` the unscaled residual, all rows,
    followed (where :func:`_limits_moves`) by the significant points' positions and
    by the contact penetrations (none without contact), whose Jacobians bound the
    Newton steps.
    Prescribed coordinates take the values ``q_p`` (``Linkage.prescribed`` order).
    """
    free = free_coordinates(linkage)
    nf = len(free)
    q = jnp.zeros(linkage.n_dof, x.dtype).at[free].set(x[:nf])
    qi = linkage.prescribed[0]
    if len(qi):
        q = q.at[qi].set(q_p)
    mu = x[nf:] if linkage.n_constraints else None
    r, e, d, g = _residual_and_closure(linkage, data, q, t, lam, u, mu)
    rows = [r, g[:, :3, 3].reshape(-1), d] if _limits_moves(linkage) else [r, d]
    f = jnp.concatenate([_row_scale(data.K)[free] * r[free], e])
    return f, jnp.concatenate(rows)


def _closure_converted(fn, *inputs):
    """``(g, consts)``: ``fn(*inputs)`` as ``g(ins, c)``, in one trace.

    The arrays ``fn`` closes over are lifted into ``c``, so that custom derivatives
    can see them.
    """
    conv, consts = jax.closure_convert(fn, *inputs)
    return (lambda i, c_: conv(*i, *c_)), list(consts)


def _value_with_jvp(value, converted, inputs, rule):
    """``value`` (computed elsewhere, e.g. inside a solver loop) with a custom JVP.

    ``converted = (g, c)`` from :func:`_closure_converted`; the tangent of ``value``
    is ``rule(g, ins, t_ins, c, t_c)`` with ``t_*`` the tangents of ``inputs`` and
    ``c``. Nothing of the rule enters the primal program; reverse mode follows by
    transposition.
    """
    g, consts = converted

    @jax.custom_jvp
    def ident(v, ins, c):
        return v

    @ident.defjvp
    def _ident_jvp(primals, tangents):
        v, ins, c = primals
        _, t_ins, t_c = tangents
        return v, rule(g, ins, t_ins, c, t_c)

    return ident(jax.lax.stop_gradient(value), tuple(inputs), consts)


def _implicit_solution(converted, x_star, r_star, args, J, J_r, least_squares: bool):
    """A root ``x_star`` of ``f(x, args)`` and the rows ``r_star``, with derivatives.

    The implicit function theorem's. ``converted``: ``(f, r)`` as ``(g, c)``,
    ``g((x, args), c)`` (``_closure_converted``). The root's derivative with respect
    to ``args`` (and to any array ``g`` closes over) is ``dx = -J^-1 df``, ``df`` the
    derivative of ``f`` at fixed x and ``J = df/dx`` (LU, or the SVD pseudo-inverse
    for closed loops, whose redundant rows make J singular); the rows' is
    ``dr = dr_a + J_r dx``, ``dr_a`` from the same forward-mode pass and
    ``J_r = dr/dx``. ``J`` and ``J_r`` are the solver's last Jacobians (Newton's last
    evaluation, one converged step of at most the tolerance before ``x_star``: the
    derivatives are then exact to about the tolerance), so the derivative forms no
    Jacobian of the residual and traces its forward mode once, for both outputs. The
    solve is a dense JAX one, transposable for reverse mode and free of host
    callbacks (lineax's transposed solve always checks its result with one, which
    keeps a program out of JAX's persistent compilation cache); at a singular
    equilibrium (a bifurcation point) the LU derivatives are not finite.
    """

    def rule(g, ins, t_ins, c, t_c):
        x, a, J_, J_r_ = ins
        _, (df, dr_a) = jax.jvp(lambda a_, c_: g((x, a_), c_), (a, c), (t_ins[1], t_c))
        if least_squares:
            dx = -(jnp.linalg.pinv(J_) @ df)
        else:
            dx = -jnp.linalg.solve(J_, df)
        return dx, dr_a + J_r_ @ dx

    value = jax.lax.stop_gradient((x_star, r_star))
    ins = (value[0], args, *jax.lax.stop_gradient((J, J_r)))
    return _value_with_jvp(value, converted, ins, rule)


def _jacobian_and_values(f_aux, x):
    """``((J, J_aux), (f, aux))`` of ``f_aux(x) -> (f, aux)`` in one forward-mode pass.

    ``J = df/dx`` and ``J_aux = daux/dx`` (``aux`` an array: its tangents are those
    the pass computes for ``f`` anyway).
    """

    def f_and_out(x_):
        f, aux = f_aux(x_)
        return (f, aux), (f, aux)

    return jax.jacfwd(f_and_out, has_aux=True)(x)


def _has_law(contact, kind: str) -> bool:
    """Whether any of the contact's laws is of ``kind`` ("penalty", "barrier")."""
    laws = (contact.law, *contact.obstacle_laws)
    return any(law.kind == kind for law in laws)


def _penalty_stiffness(law) -> Array:
    """The law's k if it is a penalty, else 0 (continued and estimated: penalties)."""
    return law.stiffness if law.kind == "penalty" else jnp.zeros(())


STIFFNESS_FACTOR = 10.0
"""Largest factor between the contact stiffnesses of two continuation stages."""


def _softened(linkage: Linkage, s) -> Linkage:
    """The linkage's contact at a continuation stage ``s = (s_k, s_r, s_f)``.

    A penalty law's stiffness times ``s_k``; a barrier law's reach divided by
    ``s_r`` and its force scale ``k g_hat`` times ``s_f`` (a wider and gentler
    barrier: ``k`` times ``s_r s_f``). All ones: the user's laws.
    """
    s_k, s_r, s_f = s

    def scaled(law):
        if law.kind == "barrier":
            return eqx.tree_at(
                lambda l_: (l_.stiffness, l_.smoothing),
                law,
                (law.stiffness * s_r * s_f, law.smoothing / s_r),
            )
        return eqx.tree_at(lambda l_: l_.stiffness, law, law.stiffness * s_k)

    contact = linkage.contact
    contact = eqx.tree_at(lambda c: c.law, contact, scaled(contact.law))
    for i, law in enumerate(contact.obstacle_laws):
        contact = eqx.tree_at(lambda c, i=i: c.obstacle_laws[i], contact, scaled(law))
    return eqx.tree_at(lambda l_: l_.contact, linkage, contact)


def _barrier_force(law) -> Array:
    """The law's force scale ``k g_hat`` if it is a barrier, else 0."""
    return law.stiffness * law.smoothing if law.kind == "barrier" else jnp.zeros(())


def _row_stiffness(linkage: Linkage, n_rows: int, of=_penalty_stiffness) -> Array:
    """Each contact row's penalty stiffness [N/m] (or another value ``of`` its law).

    ``of(law)`` (default: the penalty's k, 0 for a barrier) times the length a rod
    sample stands for (obstacle rows, first), per point (rod pairs, tubes).
    """
    contact = linkage.contact
    parts = []
    if contact.obstacles:
        w = obstacle_samples(linkage).weight
        laws = [contact.obstacle_law(i) for i in range(len(contact.obstacles))]
        parts = [of(law) * w for law in laws]
    n_obs = sum(p.shape[0] for p in parts)
    parts.append(jnp.full((n_rows - n_obs,), of(contact.law)))
    return jnp.concatenate(parts)


def _stiffness_stages(linkage, data, q0, free, depth_cap, r_min, factor, skip):
    """``stages_of`` for :func:`_newton`: how many tenfold stiffness stages to take.

    A penalty contact that Newton's first steps meet at the depth cap (about
    ``depth_cap``) pushes back with k times that depth; where this is many times
    the load, the next step throws the body off and the iterations bounce. The
    load's penetration at the user's stiffness is estimated as
    ``max |F| / max_j sum_i k_i |dd_i/dq_j|`` (the load, ``F`` the residual at
    full load or the elastic force at the start, whichever is larger, carried by
    every sample at one depth); where it is below the target depth (ten depth
    caps, at most 5 % of the smallest radius), the solve starts at the stiffness
    that puts it there and multiplies it by at most ``factor`` per stage.

    A barrier law starts with its reach at 5 % of the smallest radius (where it is
    narrower) and its force scale ``k g_hat`` at most the load's (estimated as the
    penalty's, ``max_j sum_i k g_hat w_i |dd_i/dq_j|`` against ``max |F|``): a
    narrow barrier meets Newton's steps with a force that rises over the user's
    reach, and a strong one throws the body off. The stages narrow the reach and
    raise the force scale together (``s_r = s ** a``, ``s_f = s ** b``), the
    number of stages set by the largest of the three ratios.
    """
    nf = len(free)
    n = linkage.n_dof
    elastic = jax.lax.stop_gradient(jnp.abs(data.K @ q0)[free])
    target = jnp.minimum(10.0 * depth_cap, jnp.maximum(depth_cap, 0.05 * r_min))
    contact = linkage.contact
    reaches = [lw.smoothing for lw in (contact.law, *contact.obstacle_laws)
               if lw.kind == "barrier"]  # fmt: skip
    barrier_reach = jax.lax.stop_gradient(
        jnp.min(jnp.stack(reaches)) if reaches else jnp.inf
    )
    reach_target = jnp.where(jnp.isfinite(r_min), 0.05 * r_min, jnp.inf)
    log_factor = math.log(factor)

    def stages_of(f, aux, J_aux):
        del f
        r0 = jnp.where(jnp.isfinite(aux[:n]), aux[:n], 0.0)[free]
        load = jnp.maximum(
            jnp.max(jnp.abs(r0), initial=0.0), jnp.max(elastic, initial=0.0)
        )
        G = J_aux[n + skip :, :nf]
        G = jnp.where(jnp.isfinite(G), jnp.abs(G), 0.0)
        reach = jnp.max(_row_stiffness(linkage, G.shape[0]) @ G, initial=0.0)
        if skip:
            # Contacts between bodies (no penetration rows before the broad phase
            # sees them): one point carries the load, at the law's k per point.
            P = J_aux[n : n + skip, :nf].reshape(-1, 3, nf)
            P = jnp.where(jnp.isfinite(P), P, 0.0)
            lever = jnp.max(jnp.sqrt(jnp.sum(P * P, axis=1)), axis=0)
            k_pair = _penalty_stiffness(linkage.contact.law)
            reach = jnp.maximum(reach, jnp.max(k_pair * lever, initial=0.0))
        depth = load / jnp.where(reach > 0, reach, 1.0)
        s_k = jnp.where((reach > 0) & (load > 0), depth / target, 1.0)
        # A barrier starts with its reach at the target, where Newton meets a force
        # that grows over a distance like the radius's, not like the user's reach,
        # and with its force scale k g_hat at most the load's (a barrier far
        # stronger than the load throws the body off), both then raised to the
        # user's over the stages.
        force = jnp.max(_row_stiffness(linkage, G.shape[0], _barrier_force) @ G,
                        initial=0.0)  # fmt: skip
        s_r = jnp.where(
            jnp.isfinite(barrier_reach) & jnp.isfinite(reach_target),
            jnp.clip(barrier_reach / reach_target, 1e-12, 1.0),
            1.0,
        )
        s_f = jnp.where((force > 0) & (load > 0), load / force, 1.0)
        s_f = jnp.clip(s_f, 1e-12, 1.0)
        s0 = jnp.clip(jnp.minimum(s_k, jnp.minimum(s_r, s_f)), 1e-12, 1.0)
        m = jnp.ceil(-jnp.log(s0) / log_factor - 1e-9)
        # exponents: stage factor s gives s_r = s ** a, s_f = s ** b
        log_s0 = jnp.where(s0 < 1.0, jnp.log(s0), -1.0)
        a = jnp.where(s0 < 1.0, jnp.log(s_r) / log_s0, 0.0)
        b = jnp.where(s0 < 1.0, jnp.log(s_f) / log_s0, 0.0)
        return jax.lax.stop_gradient((jnp.maximum(m, 0.0), s0, a, b))

    return stages_of


def _newton(
    fn_aux,
    x0,
    args,
    *,
    n_inc,
    linear_solver,
    max_steps,
    rtol,
    atol,
    n_mult=0,
    max_step=jnp.inf,
    regularise=False,
    contact_rows=None,
    stages_of=None,
):
    """Newton's method over load increments lambda = k / n, k = 1 .. n, one loop.

    ``fn_aux(x, lam, s) -> (f, aux)``, ``s`` the contact stiffness factor. Each
    iteration evaluates f, its Jacobian and ``aux`` at the current x in one
    forward-mode pass (the only trace of the residual in the compiled program). The
    final increment has converged when ``|f| <= atol`` at the current x and the
    Newton step from it, or the one that led to it, is small
    (``|dx_i| <= atol + rtol |x_i|``); a small step from x is still taken, so the
    returned x is accurate to about its square while f, aux and the Jacobian returned
    are those at the last evaluated x (no evaluation only to confirm convergence). An
    intermediate increment (tolerances 1e-4, only a start for the next) ends with its
    first step within them. With ``n_inc = None`` a first evaluation at full load
    chooses the number of increments (``n_inc_of(f)``); when that is one, the same
    evaluation is the first Newton iteration. (Evaluations per solve: cable arm
    7.33 -> 5.46, manual hybrid 10 -> 8.)

    The last ``n_mult`` unknowns are Lagrange multipliers (closed loops): the first
    evaluation (at full load) then also sets them by least squares at ``x0``
    (``J_{r,mu} dmu = -r``) and is not an iteration, so that the first Newton step
    sees the constraint-curvature term of the tangent stiffness. Starting them at
    zero instead makes that step ignore the loop forces, and from a buckled guess of
    a clamped-clamped rod it jumped to the straight, unstable equilibrium. No
    coordinate moves by more than ``max_step`` per iteration (the step is scaled
    down, its direction kept). With ``regularise`` (contact scenes) a singular
    Jacobian takes a Levenberg-shifted step instead of failing. ``contact_rows =
    (start, depth, barrier, move)``: ``aux[start:]`` are contact penetrations d (after
    the significant points' positions, 3 rows each, where ``move = (distance,
    n_points)`` is not None: no point then moves more than that distance per step
    by the step's linear prediction,
    so that a rod cannot pass through another before the broad phase, whose
    candidates alone have penetration rows, has seen them near), and a
    step is shortened so that, by its linear prediction, no contact ends deeper
    than ``max(depth, 8 d)`` (a free body does not jump through what it touches,
    nor a just-touching rod through a thin one; a contact that must go deeper
    grows eightfold per iteration); with ``barrier`` no gap closes by more than
    half in one step (the fraction-to-boundary rule of interior-point methods,
    which keeps a barrier law's contacts apart). A step that made the residual
    grow halves the next (contact's kinks can make Newton cycle).

    Stiffness continuation (contact): ``stages_of(f, aux, J_aux) -> (m, s0, a,
    b)``, from the first evaluation (at full load and full stiffness), gives m
    stages after the load increments: the increments run at stage factor s0, then
    stage j = 1 .. m at ``s = s0 ** ((m - j) / m)``, the last at the user's laws
    (each warm-started from the last, the intermediate ones to the loose
    tolerances). ``fn_aux`` gets ``(s, s ** a, s ** b)``: the penalty laws'
    stiffness factor, a barrier's reach divisor and force-scale factor (see
    :func:`_softened`). A residual is also small when it is at the round-off level
    of its terms, ``|f_i| <= 4 eps sum_j |J_ij| (1 + |x_j|)``: a penetration
    computed from positions of size 1 carries an error of about eps, which a stiff
    law turns into a force that no step can remove.

    Returns ``(x, f, aux, (J, J_aux), steps, status)`` (``J_aux = daux/dx``), status
    0 converged, 1 out of steps, 2 non-finite values, 3 failed linear solve.
    """
    n_inc_given, n_inc_of = n_inc
    dtype = x0.dtype
    one = jnp.ones((), dtype)

    # Jitted: the shape probe below and the loop body share one trace.
    @jax.jit
    def evaluate(x, lam, s):
        return _jacobian_and_values(lambda x_: fn_aux(x_, lam, s), x)

    shapes = jax.eval_shape(evaluate, x0, one, (one, one, one))
    zeros = jax.tree_util.tree_map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)
    int_ = jnp.asarray(0).dtype
    # carry: k (0: probe at full load), n, x, steps in this increment, total steps,
    # last step small, status (-1 running), J, (f, aux)
    probe_first = n_inc_given is None or n_mult > 0 or stages_of is not None
    n_eq = x0.shape[0] - n_mult  # equilibrium rows (the rest: constraint errors)
    eps = jnp.finfo(dtype).eps
    init = (
        jnp.zeros((), dtype) if probe_first else one,
        (
            one if n_inc_given is None else jnp.asarray(n_inc_given, dtype),
            jnp.zeros((), dtype),  # stiffness stages m
            one,  # the first stiffness factor s0
            jnp.zeros((), dtype),  # exponents of a barrier's reach and force
            jnp.zeros((), dtype),
        ),
        x0,
        jnp.zeros((), int_),
        jnp.zeros((), int_),
        jnp.zeros((), bool),
        jnp.full((), -1, int_),
        zeros[0],
        zeros[1],
        (one, jnp.full((), jnp.inf, dtype)),  # step damping (contact): trust, |f|
    )

    def cond(c):
        return c[6] < 0

    def body(c):
        k, (n, m, s0, a, b), x, it, total, small, _, _, _, (trust, f_prev) = c
        probe = k == 0
        # load factor and stiffness factor of increment k (the probe: both full)
        lam = jnp.where(probe, one, jnp.minimum(k / n, 1.0))
        s = jnp.where(
            probe | (m == 0), one, s0 ** (jnp.clip(n + m - k, 0, m) / jnp.maximum(m, 1))
        )
        (J, J_aux), (f, aux) = evaluate(x, lam, (s, s**a, s**b))
        if n_mult:
            # Least-squares multipliers at x0; the residual the increments are
            # chosen from is the one left after them.
            J_rmu = jnp.where(jnp.isfinite(J[:n_eq, n_eq:]), J[:n_eq, n_eq:], 0.0)
            f_r = jnp.where(jnp.isfinite(f[:n_eq]), f[:n_eq], 0.0)
            dmu = jnp.linalg.lstsq(J_rmu, -f_r)[0]
            x = jnp.where(probe, x.at[n_eq:].add(dmu), x)
            f_probe = f.at[:n_eq].add(J_rmu @ dmu)
        else:
            f_probe = f
        if n_inc_given is None:
            n = jnp.where(probe, n_inc_of(f_probe), n)
        if stages_of is not None:
            m_new, s0_new, a_new, b_new = stages_of(f_probe, aux, J_aux)
            m = jnp.where(probe, m_new, m)
            s0 = jnp.where(probe, s0_new, s0)
            a = jnp.where(probe, a_new, a)
            b = jnp.where(probe, b_new, b)
        # With one increment at full stiffness the probe (full load at x0) is its
        # first iteration (not with multipliers: they were just reset).
        if not n_mult:
            k = jnp.where(probe & (n == 1) & (m == 0), one, k)
        iterate = k > 0
        last = k >= n + m
        tol_a = jnp.where(last, atol, 1e-4)
        tol_r = jnp.where(last, rtol, 1e-4)
        finite = jnp.all(jnp.isfinite(f)) & jnp.all(jnp.isfinite(J))
        Jf, ff = jnp.where(finite, J, 0.0), jnp.where(finite, f, 0.0)
        if regularise:
            # Contact: a body that floats free of its obstacles has no stiffness in
            # the directions contact will hold (a singular or nearly singular
            # tangent): Levenberg's shift, tiny against the stiffness, steps along
            # the load there (within the step caps) until contact holds it.
            # The shift falls with the residual (Levenberg-Marquardt's mu ~ |f|), so
            # that near the root the step is Newton's, whatever a stiff contact
            # makes of max |J|.
            shift = jnp.minimum(
                1e-9 * jnp.maximum(jnp.max(jnp.abs(Jf)), 1.0),
                jnp.maximum(jnp.max(jnp.abs(ff), initial=0.0), 1e-9),
            )
            dx = jnp.linalg.solve(Jf + shift * jnp.eye(Jf.shape[0], dtype=dtype), ff)
            solved = jnp.all(jnp.isfinite(dx))
        else:
            sol = lx.linear_solve(
                lx.MatrixLinearOperator(Jf), ff, linear_solver, throw=False
            )
            dx = sol.value
            solved = sol.result == lx.RESULTS.successful
        # Step cap: no coordinate moves more than max_step (scaled units, about rad)
        # in one iteration, the direction kept. Far from a root a full Newton step
        # can leave the basin of the equilibrium near the guess (a slightly buckled
        # guess of a clamped-clamped rod diverged); near a root steps are far below.
        dx = dx / jnp.maximum(jnp.max(jnp.abs(dx[:n_eq]), initial=0.0) / max_step, 1.0)
        if contact_rows is not None:
            start, depth, barrier, move = contact_rows
            J_aux_f = jnp.where(finite, J_aux, 0.0)
            if move is not None:
                distance, n_points = move
                n_p = 3 * n_points
                dp = (J_aux_f[start : start + n_p] @ dx).reshape(-1, 3)
                moved = jnp.max(jnp.sqrt(jnp.sum(dp * dp, axis=1)), initial=0.0)
                dx = dx / jnp.maximum(moved / distance, 1.0)
                start = start + n_p
            d = jnp.where(jnp.isfinite(aux[start:]), aux[start:], 0.0)
            deeper = -(J_aux_f[start:] @ dx)
            room = jnp.maximum(depth, 8.0 * d) - d  # > 0
            if barrier:  # a gap closes by at most half per step (interior points)
                room = jnp.where(d < 0, -0.5 * d, room)
            ratio = jnp.where(deeper > 0, deeper / room, 0.0)
            dx = dx / jnp.maximum(jnp.max(ratio, initial=0.0), 1.0)
        solved = solved & jnp.all(jnp.isfinite(dx))
        dx_small = jnp.max(jnp.abs(dx) / (tol_a + tol_r * jnp.abs(x)), initial=0.0) <= 1
        # the residual's round-off level (see above)
        f_floor = 4.0 * eps * jnp.max(jnp.abs(Jf) @ (1.0 + jnp.abs(x)), initial=0.0)
        f_small = jnp.max(jnp.abs(f), initial=0.0) <= jnp.maximum(tol_a, f_floor)
        # Final increment: converged when the residual here is within atol and so is
        # the Newton step from here (or the last step, which led here); a small step
        # from here is still taken (x then accurate to about its square), and f, aux,
        # J are those of this evaluation. An intermediate increment only starts the
        # next: it ends with its first step within the loose tolerances.
        ok = finite & solved & dx_small
        # A residual at round-off is converged whatever the step: at a singular
        # equilibrium (a fold of the load path) the Newton step is not small.
        f_tiny = jnp.max(jnp.abs(f), initial=0.0) <= 1e-3 * tol_a
        converged = iterate & last & (f_small & (small | ok) | f_tiny)
        advance = iterate & ~last & ok
        step = iterate & ~converged & finite & solved & (it < max_steps)
        step = step | advance | (converged & ok)
        status = jnp.select(
            [~iterate, converged, advance, ~finite, it >= max_steps, ~solved],
            [-1, 0, -1, 2, 1, 3],
            -1,
        ).astype(int_)
        f_norm = jnp.max(jnp.abs(f), initial=0.0)
        if regularise:
            # Contact's closest points and shares switch: Newton can cycle around
            # a kink of the tangent. A step that made |f| grow halves the next.
            grew = iterate & (f_norm > f_prev) & (f_prev > f_floor)  # not round-off
            trust = jnp.where(grew, 0.5 * trust, jnp.minimum(2.0 * trust, 1.0))
            dx = trust * dx
        return (
            jnp.where(~iterate | advance, k + 1, k),
            (n, m, s0, a, b),
            jnp.where(step, x - dx, x),
            jnp.where(step & ~advance, it + 1, 0),
            total + step.astype(int_),
            step & dx_small & ~advance,
            status,
            (J, J_aux),
            (f, aux),
            (trust, jnp.where(iterate & ~advance, f_norm, jnp.inf)),
        )

    _, _, x, _, total, _, status, Js, (f, aux), _ = lax.while_loop(cond, body, init)
    return x, f, aux, Js, total, status


@jit
def _solve_statics(
    linkage: Linkage,
    q0: Array,
    u: Array,
    *,
    t: ArrayLike = 0.0,
    solver: optx.AbstractRootFinder | optx.AbstractLeastSquaresSolver | None = None,
    load_steps: int | None = None,
    max_load_steps: int = 16,
    load_increment: float = 2.0,
    max_steps: int = 64,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    differentiable: bool = True,
) -> StaticsSolution:
    """Jitted core of :func:`solve_statics`, which never throws.

    ``q0`` ``(n_dof,)`` and ``u`` ``(n_inputs,)`` come checked from the wrapper.
    Without a host callback the compiled program can be kept in JAX's persistent
    compilation cache. ``differentiable=False`` (a call made outside any JAX trace,
    whose results no transformation can differentiate) leaves out the implicit
    derivatives' closure conversion: the same compiled arithmetic, one trace of
    the residual less (10-20 % of the trace).
    """
    if load_steps is not None and (not isinstance(load_steps, int) or load_steps < 1):
        raise ValueError(f"load_steps = {load_steps!r}: give an integer >= 1 or None.")
    if not isinstance(max_load_steps, int) or max_load_steps < 1:
        raise ValueError(f"max_load_steps = {max_load_steps!r}: give an integer >= 1.")
    n = linkage.n_dof
    qi, ui = linkage.prescribed
    free = free_coordinates(linkage)
    nf = len(free)
    n_c = linkage.n_constraints
    closed = n_c > 0
    linear_solver = lx.SVD() if closed else lx.AutoLinearSolver(well_posed=None)
    data = precompute(linkage)
    q_p0 = q0[qi]
    t = jnp.asarray(t, q0.dtype)

    def full(x, lam, u_, q_p0_=q_p0):
        q = jnp.zeros(n, x.dtype).at[free].set(x[:nf])
        if len(qi):
            q = q.at[qi].set(q_p0_ + lam * (u_[ui] - q_p0_))
        return q, x[nf:]

    # The linkage travels in the solver's args as its arrays only (cable paths and
    # anchors get gradients); functions and structure stay static.
    dyn, static = eqx.partition(linkage, eqx.is_array)

    # Every array the residual depends on travels in its args (none is closed over),
    # so that the solve can run on stop-gradient copies and the implicit derivative
    # sees them all. aux: the unscaled residual (all rows).
    def fn_aux(x, args):
        data_, lam, u_, dyn_, q_p0_, t_, s_ = args
        linkage_ = eqx.combine(dyn_, static)
        if s_ is not None and linkage_.contact is not None:
            linkage_ = _softened(linkage_, s_)
        q_p = q_p0_ + lam * (u_[ui] - q_p0_) if len(qi) else None
        return scaled_equilibrium(linkage_, data_, x, t_, lam, u_, q_p)

    def fn(x, args):
        return fn_aux(x, args)[0]

    def with_load(args_, lam, s_=None):
        """The residual's args from ``(data, u, dyn, q_p0, t)`` and the factors.

        ``lam`` the load factor, ``s_`` the contact stiffness factor (None: the
        user's laws).
        """
        data_, u_, dyn_, q_p0_, t_ = args_
        return (data_, lam, u_, dyn_, q_p0_, t_, s_)

    x0 = jnp.concatenate([q0[free], jnp.zeros(n_c, q0.dtype)])
    args = (data, u, dyn, q_p0, t)
    # no Newton step makes a contact deeper than this (or 8 times its depth)
    contact_cap = r_min = None
    if linkage.contact is not None:
        r_min = smallest_radius(linkage)
        contact_cap = 10.0 * linkage.contact.law.smoothing
        contact_cap = jnp.where(
            jnp.isfinite(r_min), jnp.maximum(contact_cap, 1e-3 * r_min), contact_cap
        )
    contact_cap = jax.lax.stop_gradient(contact_cap)
    one = jnp.ones((), q0.dtype)

    def n_inc_of(f_full_load):
        """Number of load increments from the scaled residual at full load."""
        r0 = jnp.where(jnp.isfinite(f_full_load), f_full_load, 0.0)
        size = jnp.max(jnp.abs(r0), initial=0.0) / load_increment
        if len(qi):  # prescribed jumps move whole mechanisms: a quarter increment
            jump = jnp.abs(u[ui] - q_p0)
            size = jnp.maximum(size, 4.0 * jnp.max(jump) / load_increment)
        return jax.lax.stop_gradient(jnp.clip(jnp.ceil(size), 1, max_load_steps))

    # rod pairs: no point moves more than half the smallest radius per step
    move, n_position_rows = None, 0
    if _limits_moves(linkage):
        n_points = jax.eval_shape(poses, data, q0).shape[0]
        move = (jax.lax.stop_gradient(0.5 * r_min), n_points)
        n_position_rows = 3 * n_points
    stages_of = None
    if linkage.contact is not None:
        stages_of = _stiffness_stages(
            linkage, data, q0, free, contact_cap, r_min, STIFFNESS_FACTOR,
            n_position_rows,
        )  # fmt: skip

    # The solve sees no gradients: they come from the implicit function theorem at
    # the converged solution (below).
    args_ng = jax.lax.stop_gradient(args)
    if solver is None:
        # Load increments and Newton iterations in one loop with one trace of the
        # residual and its Jacobian (the compile time is about that trace).
        x_star, f_star, r_star, (J, J_r), steps, status = _newton(
            lambda x, lam, s_: fn_aux(x, with_load(args_ng, lam, s_)),
            jax.lax.stop_gradient(x0),
            args_ng,
            n_inc=(load_steps, n_inc_of),
            linear_solver=linear_solver,
            max_steps=max_steps,
            rtol=rtol,
            atol=atol,
            n_mult=n_c,
            max_step=load_increment,
            regularise=linkage.contact is not None,
            contact_rows=None
            if linkage.contact is None
            else (n, contact_cap, _has_law(linkage.contact, "barrier"), move),
            stages_of=stages_of,
        )
        result = RESULTS.where(
            status == 0,
            RESULTS.successful,
            RESULTS.where(
                status == 1,
                RESULTS.max_steps_reached,
                RESULTS.where(
                    status == 3, RESULTS.singular, RESULTS.nonlinear_divergence
                ),
            ),
        )
    else:
        x_star, steps, result = _optx_load_steps(
            fn,
            solver,
            x0,
            args_ng,
            with_load,
            n_inc=(
                n_inc_of(fn(x0, with_load(args_ng, one)))
                if load_steps is None
                else jnp.asarray(load_steps, q0.dtype)
            ),
            max_steps=max_steps,
        )
        (J, J_r), (f_star, r_star) = _jacobian_and_values(
            lambda x_: fn_aux(x_, with_load(args_ng, one)), x_star
        )
        finite = jnp.all(jnp.isfinite(x_star)) & jnp.all(jnp.isfinite(r_star))
        result = RESULTS.where(
            ~finite & (result == RESULTS.successful),
            RESULTS.nonlinear_divergence,
            result,
        )
    if differentiable:
        # One closure conversion (a trace of the residual) for the root and the
        # rows, whose derivatives share one forward-mode pass.
        full_args = with_load(args, one)
        x_sol, r = _implicit_solution(
            _closure_converted(fn_aux, x_star, full_args),
            x_star,
            r_star,
            full_args,
            J,
            J_r,
            closed,
        )
        q, mu = full(x_sol, 1.0, u)
    else:  # the same values; nothing can differentiate a top-level call
        q, mu = full(x_star, 1.0, u)
        r = r_star
    e = f_star[nf:]
    rank = numerical_rank(J[nf:, :nf]) if closed else jnp.zeros((), dtype=int)
    eigenvalues, _, n_manifold = reduced_tangent_spectrum(
        J, nf, jax.lax.stop_gradient(_row_scale(data.K)[free])
    )
    contact = None
    if linkage.contact is not None:
        # the start and the solution: no centre line inside what it touches
        contact = state_from_data(linkage, data, q, None, t)
        start = contact_wrenches_and_penetrations(linkage, t, poses(data, q0))[1]
        deepest = jnp.maximum(
            jnp.max(contact.penetration, initial=-jnp.inf),
            jnp.max(start, initial=-jnp.inf),
        )
        deep = deepest > smallest_radius(jax.lax.stop_gradient(linkage))
        result = RESULTS.where(
            deep & (result == RESULTS.successful), RESULTS.contact_too_deep, result
        )
        result = RESULTS.where(contact.overflow, RESULTS.contact_overflow, result)
    stable, n_negative, lam_min = stability_summary(eigenvalues, n_manifold)
    stable = stable & (result == RESULTS.successful)  # no verdict on a failed solve
    return StaticsSolution(
        q=q,
        residual_norm=jnp.max(jnp.abs(r[free]), initial=0.0),
        num_steps=steps,
        result=result,
        efforts=r[qi],
        lam=mu,
        constraint_error=jnp.max(jnp.abs(e), initial=0.0),
        constraint_rank=rank,
        stable=stable,
        n_negative=n_negative,
        min_eigenvalue=lam_min,
        contact=contact,
    )


def _optx_load_steps(fn, solver, x0, args, with_load, *, n_inc, max_steps):
    """A user's optimistix solver over the load increments k / n (one while loop)."""

    def cond(carry):
        return carry[0] <= n_inc

    def body(carry):
        k, x, n_it, _ = carry
        sol = optx.root_find(
            fn, solver, x, with_load(args, k / n_inc), max_steps=max_steps, throw=False
        )
        return k + 1, sol.value, n_it + sol.stats["num_steps"], sol.result

    init = (
        jnp.ones((), x0.dtype),
        jax.lax.stop_gradient(x0),
        jnp.zeros((), dtype=jnp.asarray(0).dtype),
        optx.RESULTS.successful,
    )
    _, x, steps, res = lax.while_loop(cond, body, init)
    result = RESULTS.where(
        res == optx.RESULTS.successful,
        RESULTS.successful,
        RESULTS.where(
            res == optx.RESULTS.max_steps_reached,
            RESULTS.max_steps_reached,
            RESULTS.nonlinear_divergence,
        ),
    )
    return x, steps, result


def solve_statics(
    linkage: Linkage,
    q0: ArrayLike | None = None,
    u: ArrayLike | None = None,
    *,
    t: ArrayLike = 0.0,
    solver: optx.AbstractRootFinder | optx.AbstractLeastSquaresSolver | None = None,
    load_steps: int | None = None,
    max_load_steps: int = 16,
    load_increment: float = 2.0,
    max_steps: int = 64,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    throw: bool = True,
    warn_unstable: bool = True,
) -> StaticsSolution:
    """Solve the static equilibrium of ``linkage`` (the manual's ``statics``).

    Every solution reports its stability (``stable``, ``n_negative``,
    ``min_eigenvalue``: the tangent stiffness on the constraint manifold, from the
    last Newton Jacobian at no extra evaluation). Newton's method converges to the
    equilibrium whose basin holds ``q0``, stable or not: with closed loops the
    multipliers start from their least-squares values at ``q0`` (so the first step
    sees the loop forces' curvature) and no coordinate moves more than
    ``load_increment`` per iteration, which keeps a buckled guess on the buckled
    branch; a straight guess of a compressed rod still returns the straight,
    unstable equilibrium, flagged (and warned about outside ``jit``).

    Args:
        linkage: the model.
        q0: initial guess ``(n_dof,)``; default zeros (the reference configuration).
            With closed loops, a guess near an assembled configuration.
        u: actuation inputs ``(n_inputs,)`` in actuator order (see
            ``Linkage.input_slices``): joint forces, cable tensions (> 0 pulls), and
            for prescribed joints their coordinates; default zeros.
        t: time at which time-dependent loads are evaluated [s].
        solver: an optimistix root finder or least-squares solver; default
            sorojax's own Newton loop (tolerances ``rtol``, ``atol``) on the
            Jacobi-scaled residual (with closed loops: on the residual and the
            constraint errors, unknowns q and the multipliers, solved with an SVD so
            that redundant constraint rows, e.g. of a planar loop, give the
            minimum-norm multipliers instead of failing).
        load_steps: number of equal load increments; ``None`` (default) chooses it
            from the size of the Jacobi-scaled residual at ``q0`` (about the linear
            estimate of the largest coordinate change, e.g. a rotation in rad), so
            that each increment moves the coordinates by about ``load_increment``
            (prescribed coordinates by a quarter of it), capped at
            ``max_load_steps``. Under ``vmap`` the batch runs until its most-stepped
            member is done: where the loads are moderate, ``load_steps=1`` can be
            markedly faster (check ``result``).
        max_load_steps: cap of the automatic schedule.
        load_increment: target coordinate change per automatic increment.
        max_steps: maximum iterations per load step.
        rtol: relative tolerance of the default solver.
        atol: absolute tolerance of the default solver on the Jacobi-scaled residual
            (a coordinate tolerance: rad for rotations, m for joint translations).
        throw: raise ``RuntimeError`` if the solve fails (under an outer ``jit`` an
            equinox runtime error); use ``throw=False`` under ``vmap`` and read
            ``result``.
        warn_unstable: outside ``jit``/``vmap``, warn
            (:class:`~sorojax.UnstableEquilibriumWarning`) when the solve converged
            to an unstable equilibrium; inside them read ``stable``.

    Returns:
        A :class:`~sorojax.StaticsSolution` with q, the residual max-norm, the total
        iteration count, a result code, the efforts of prescribed joints, the
        closed-loop multipliers, constraint error and rank, and the stability
        report.

    Raises:
        ValueError: bad ``q0`` shape or ``load_steps`` < 1.
        RuntimeError: the solve failed and ``throw`` is True.
    """
    args, kwargs = _core_arguments(
        linkage, q0, u, t, solver, load_steps, max_load_steps, load_increment,
        max_steps, rtol, atol,
    )  # fmt: skip
    sol = _solve_statics(*args, **kwargs)
    bad = failed(sol.result)
    traced = isinstance(bad, jax.core.Tracer)
    if warn_unstable and not traced and not bad and not bool(sol.stable):
        warnings.warn(
            f"solve_statics converged to an UNSTABLE equilibrium: the tangent "
            f"stiffness on the constraint manifold has {int(sol.n_negative)} negative "
            f"eigenvalue(s) (smallest {float(sol.min_eigenvalue):.3e}, scaled by "
            "the diagonal stiffness). A stable one may lie nearby: try a q0 closer "
            "to the shape you expect (e.g. buckled), or trace the equilibrium path "
            "with sorojax.continuation. Pass warn_unstable=False to silence this.",
            UnstableEquilibriumWarning,
            stacklevel=2,
        )
    if not throw:
        return sol
    return throw_on_failure(
        sol,
        lambda message: (
            f"solve_statics did not converge: {message} Residual "
            f"{float(sol.residual_norm):.3e} after {int(sol.num_steps)} iterations. "
            "Try more max_steps, more load steps (load_steps=, load_increment=), a "
            "better q0, or throw=False to inspect the returned solution."
        ),
    )


def _check_settings(max_steps, rtol, atol, load_increment) -> None:
    """Refuse solver settings that cannot work (concrete values only)."""
    if not isinstance(max_steps, int | np.integer) or max_steps < 1:
        raise ValueError(f"max_steps = {max_steps!r}: give an integer >= 1.")
    check_tolerances(rtol, atol, "default 1e-10", "Newton can never stop")
    if is_concrete(load_increment) and not 0 < float(load_increment) < math.inf:
        raise ValueError(
            f"load_increment = {load_increment!r}: give the target coordinate change "
            "per automatic load increment, finite and > 0 (default 2)."
        )


def _core_arguments(
    linkage, q0, u, t, solver, load_steps, max_load_steps, load_increment,
    max_steps, rtol, atol,
) -> tuple[tuple, dict]:  # fmt: skip
    """:func:`solve_statics`' checks and the arguments of its compiled core."""
    top = _top_level()  # a call of its own, not inside a user's trace
    if top:  # a new hook object means a new program
        note_hooks(linkage, "solve_statics")
    # Defaults as arrays here, so that a call with and one without q0 or u share
    # one compiled program (and bad shapes fail before anything compiles).
    # (zeros made on the host: jnp.zeros would compile a program per size)
    q0 = _as_q(linkage, np.zeros(linkage.n_dof) if q0 is None else q0, "q0")
    check_finite("q0", q0, "give finite initial coordinates (default zeros)")
    u = as_inputs(linkage, None if u is None else jnp.asarray(u, float), q0.dtype)
    _check_settings(max_steps, rtol, atol, load_increment)
    kwargs = dict(
        t=jnp.asarray(t, dtype=float),
        solver=solver,
        load_steps=load_steps,
        max_load_steps=max_load_steps,
        load_increment=load_increment,
        max_steps=max_steps,
        rtol=rtol,
        atol=atol,
        differentiable=not top,
    )
    return (linkage, q0, u), kwargs


def prepare_statics(*args, **kwargs):
    """Compile the program of ``solve_statics(...)`` (same arguments) in a thread.

    :func:`sorojax.prepare` with :func:`solve_statics`: traced and lowered here,
    compiled in a worker thread; the later call with arguments of the same shapes
    and settings waits for it instead of compiling. Nothing is solved. Returns the
    compile's future (None inside a trace, or when the program is compiled or
    prepared already).
    """
    host_only = ("throw", "warn_unstable")  # the same program either way
    args, kwargs = _core_arguments(
        **_bound_arguments(solve_statics, args, kwargs, host_only)
    )
    return _solve_statics.prepare(*args, **kwargs)


solve_statics.prepare = prepare_statics
