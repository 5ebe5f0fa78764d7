"""Closed-loop constraints e(q) = 0, their Jacobian A = de/dq and the bias Adot qd.

For a closed-loop joint between frame A (tip of link A times g_A) and frame B (tip of
link B, or the world, times g_B) the relative pose is ``g = g_B^-1 g_A`` and the
errors are ``Phi_p^T log(g)`` (DESIGN.md section 2), ``Phi_p`` the orthonormal
complement of the joint's free directions: zero exactly when g lies in the joint's
motion set ``exp(span Phi)`` (R, P, H, C, A, S, N). For the joints whose free
directions split into rotations and translations along fixed axes (R, P, C, A, S, N)
the cheaper ``(sin(theta) n, p)`` (skew part of R, and p) has the same zero set near
assembly and the same first-order behaviour, and is used instead of the log (whose
nested derivatives triple the compile time of the statics Newton). The universal
joint's motions are products ``R_u(a) R_v(b)``, not exponentials of the span, so its
errors are the exact ``(u . R v, p)``: the two free axes stay perpendicular and the
centres coincide.
A and Adot qd come either from forward-mode autodiff of e (:func:`constraint_terms`,
the reference the tests compare with) or, in the dynamics, from the body Jacobians,
twists and their rates that the mass matrix needs anyway
(:func:`constraint_terms_from_kinematics`); tests check that both agree.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._jit import jit
from ..kinematics._api import _as_q
from ..lie import Ad_inv, ad, hat, log_se3
from ..model._joint import perpendicular_pair
from ..model._linkage import Linkage
from ..model._precompute import LinkageData, precompute
from ._wrench_recursion import poses_with_records


def _inv(g):
    R, p = g[:3, :3], g[:3, 3]
    out = jnp.eye(4, dtype=g.dtype)
    return out.at[:3, :3].set(R.T).at[:3, 3].set(-R.T @ p)


def _frames(linkage: Linkage, c, g):
    """Poses of a closure's frames A and B (world) from the point poses."""
    gA = g[linkage.tip_point(c.link_A)] @ c.g_A
    gB = c.g_B if c.link_B == 0 else g[linkage.tip_point(c.link_B)] @ c.g_B
    return gA, gB


def _closure_error(c, rel) -> Array:
    """Errors of one closed-loop joint from the relative pose ``g_B^-1 g_A``."""
    R, p = rel[:3, :3], rel[:3, 3]
    if c.kind == "U":
        u, v = perpendicular_pair(np.asarray(c.axis))
        return jnp.concatenate([(u @ R @ v)[None], p])
    if c.kind == "H":
        return jnp.asarray(c.constrained_basis()).T @ log_se3(rel)
    w = 0.5 * jnp.stack([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return jnp.asarray(c.constrained_basis()).T @ jnp.concatenate([w, p])


def closure_errors_from_poses(linkage: Linkage, g) -> Array:
    """Errors of all closed-loop joints, ``(n_constraints,)``, from point poses."""
    out = []
    for c in linkage.closed_loops:
        gA, gB = _frames(linkage, c, g)
        out.append(_closure_error(c, _inv(gB) @ gA))
    if not out:
        return jnp.zeros((0,), g.dtype)
    return jnp.concatenate(out)


def _loop_terms(c, rel, A_side, B_side):
    """``(e, A, Adot qd)`` of one loop.

    From its relative pose and the ``(J, eta, etadot)`` of its two frames (see
    :func:`constraint_terms_from_kinematics`).
    """
    JA, eA, edA = A_side
    JB, eB, edB = B_side
    Ai = Ad_inv(rel)
    xi = eA - Ai @ eB
    xid = edA - Ai @ edB + ad(xi) @ (Ai @ eB)
    eye = jnp.eye(4, dtype=rel.dtype)
    one = jnp.ones((), rel.dtype)
    err = functools.partial(_closure_error, c)
    e, D = _error_and_derivative(c, rel)
    X = hat(xi)

    def along(s):
        return err(rel @ (eye + s * X + (0.5 * s * s) * (X @ X)))

    def rate(s):
        return jax.jvp(along, (s,), (one,))[1]

    second = jax.jvp(rate, (jnp.zeros((), rel.dtype),), (one,))[1]
    return e, D @ (JA - Ai @ JB), D @ xid + second


def _error_and_derivative(c, rel):
    """``(e, D)``: a loop's errors at ``rel`` and their derivative along ``rel exp(z)``.

    ``D`` is ``(n_c, 6)`` at z = 0, z the body twist of frame A relative to B.
    """
    eye = jnp.eye(4, dtype=rel.dtype)

    def f(z):
        e = _closure_error(c, rel @ (eye + hat(z)))
        return e, e

    D, e = jax.jacfwd(f, has_aux=True)(jnp.zeros(6, rel.dtype))
    return e, D


def closure_errors_and_wrenches(linkage: Linkage, g, mu):
    """``(e, W)``: closure errors and the body wrenches of ``A^T mu``.

    With ``A = D (J_A - Ad(rel)^-1 J_B)`` per loop (see
    :func:`constraint_terms_from_kinematics`; ``J_A = Ad(g_A)^-1 J_tip`` for a
    frame offset ``g_A``), ``A^T mu = sum_p J_p^T W_p`` with ``f = D^T mu`` acting
    at tip A as ``Ad(g_A)^-T f`` and at tip B as ``-Ad(g_B)^-T Ad(rel)^-T f``
    (equal and opposite): the multipliers' generalised force without forming A,
    mapped by the same backward recursion as the other loads.
    """
    W = jnp.zeros((g.shape[0], 6), g.dtype)
    errors, k = [], 0
    for c in linkage.closed_loops:
        gA, gB = _frames(linkage, c, g)
        rel = _inv(gB) @ gA
        e, D = _error_and_derivative(c, rel)
        errors.append(e)
        f = D.T @ mu[k : k + e.shape[0]]
        k += e.shape[0]
        W = W.at[linkage.tip_point(c.link_A)].add(Ad_inv(c.g_A).T @ f)
        if c.link_B != 0:
            fB = -(Ad_inv(c.g_B).T @ (Ad_inv(rel).T @ f))
            W = W.at[linkage.tip_point(c.link_B)].add(fB)
    if not errors:
        return jnp.zeros((0,), g.dtype), W
    return jnp.concatenate(errors), W


def constraint_terms_from_kinematics(linkage: Linkage, g, J, eta, etadot, rows=None):
    """``(e, A, Adot qd)`` from the point poses, body Jacobians, twists and rates.

    For each loop, ``rel = g_B^-1 g_A`` moves with the body twist
    ``xi = eta_A - Ad(rel)^-1 eta_B`` (frames A and B: the tips times their constant
    offsets), so ``A = D (J_A - Ad(rel)^-1 J_B)`` with ``D`` the derivative of the
    loop's errors along ``rel exp(z)`` at z = 0 (a 6-column forward-mode Jacobian of
    a 4x4 kernel). In time, with qdd = 0,
    ``xidot = etadot_A - Ad(rel)^-1 etadot_B + ad(xi) Ad(rel)^-1 eta_B`` and
    ``Adot qd = D xidot + d^2/ds^2 e(rel exp(s xi))`` at s = 0 (exact with the
    second-order expansion of exp). Everything comes from the kinematic pass the
    mass matrix needs; no derivative of the whole kinematics is taken. ``rows``:
    each point's row in ``J`` and ``etadot`` (default: a row per point), as in
    :class:`~sorojax.kinematics._recursion.PointRates`.
    """

    def side(link, offset):
        """``(J, eta, etadot)`` of a loop frame (zero for the world)."""
        if link == 0:
            zero6 = jnp.zeros(6, dtype=g.dtype)
            return jnp.zeros_like(J[0]), zero6, zero6
        i = linkage.tip_point(link)
        r = i if rows is None else int(rows[i])
        T = Ad_inv(offset)
        return T @ J[r], T @ eta[i], T @ etadot[r]

    terms = []
    for c in linkage.closed_loops:
        gA, gB = _frames(linkage, c, g)
        rel = _inv(gB) @ gA
        terms.append(_loop_terms(c, rel, side(c.link_A, c.g_A), side(c.link_B, c.g_B)))
    if not terms:
        z = jnp.zeros((0,), g.dtype)
        return z, jnp.zeros((0, J.shape[-1]), g.dtype), z
    return tuple(jnp.concatenate(parts) for parts in zip(*terms, strict=True))


def closure_errors_from_data(linkage: Linkage, data: LinkageData, q) -> Array:
    """``e(q)`` (forward pose pass only, no Jacobians)."""
    return closure_errors_from_poses(linkage, poses_with_records(data, q)[0])


def constraint_jacobian_from_data(linkage: Linkage, data: LinkageData, q) -> Array:
    """``A = de/dq``, ``(n_constraints, n_dof)``."""
    return jax.jacfwd(lambda q_: closure_errors_from_data(linkage, data, q_))(q)


def constraint_terms(linkage: Linkage, data: LinkageData, q, qd):
    """``(e, A, Adot qd)`` at ``(q, qd)``; ``Adot qd = d^2/ds^2 e(q + s qd)`` at 0."""

    def e(q_):
        return closure_errors_from_data(linkage, data, q_)

    def Aqd(q_):
        return jax.jvp(e, (q_,), (qd,))[1]

    ev, A = e(q), jax.jacfwd(e)(q)
    bias = jax.jvp(Aqd, (q,), (qd,))[1]
    return ev, A, bias


def numerical_rank(A, rtol: float = 1e-9) -> Array:
    """Rank of ``A`` from its singular values above ``rtol`` times the largest."""
    if A.shape[0] == 0:
        return jnp.zeros((), dtype=int)
    s = jnp.linalg.svd(A, compute_uv=False)
    return jnp.sum(s > rtol * jnp.maximum(s[0], 1e-300))


@jit
def closure_errors(linkage: Linkage, q: ArrayLike) -> Float[Array, " n_constraints"]:
    """Closed-loop constraint errors e(q) (rad and m), joint by joint."""
    q = _as_q(linkage, q)
    return closure_errors_from_data(linkage, precompute(linkage), q)


@jit
def constraint_jacobian(
    linkage: Linkage, q: ArrayLike
) -> Float[Array, "n_constraints n_dof"]:
    """``A(q) = de/dq`` (redundant rows show in ``numerical_rank(A)``)."""
    q = _as_q(linkage, q)
    return constraint_jacobian_from_data(linkage, precompute(linkage), q)
