"""Forward kinematics and body Jacobians by the 4th-order Magnus / Zanna recursion.

DESIGN.md section 3 (Renda et al. 2020; Mathew et al. 2022). Between consecutive
significant points X_a -> X_a + h with xi_1, xi_2 at the Zanna points
X_a + h (1/2 -+ sqrt(3)/6):

    Omega  = h/2 (xi_1 + xi_2) + sqrt(3) h^2/12 ad(xi_1) xi_2
    dOmega = h/2 (Phi_1 + Phi_2) + sqrt(3) h^2/12 (ad(xi_1) Phi_2 - ad(xi_2) Phi_1)
    g_{a+1} = g_a exp(Omega),  J_{a+1} = Ad(exp(Omega))^-1 (J_a + T(Omega) dOmega).

A lumped joint is the same step with Omega = Phi_j q_j. Links run in topological order
(a Python loop over the static tree); points inside a division run in ``lax.scan``.
Jacobian columns are full width (n_dof) so that trees compose without bookkeeping.
"""

import math

import jax
import jax.numpy as jnp
from jax import lax
from jaxtyping import Array, Float

from ..lie import Ad_inv, ad
from ..model._precompute import DivisionData, LinkageData
from ._step import Ad_inv_Rp, exp_and_tangent, pose

_C = math.sqrt(3.0) / 12.0


def _joint_step(g, J, Phi, q_j, offset):
    R, p, T = exp_and_tangent(Phi @ q_j)
    J = J.at[:, offset : offset + Phi.shape[1]].add(T @ Phi)
    return g @ pose(R, p), Ad_inv_Rp(R, p) @ J


def magnus_omega(h, P, r, q_d):
    """4th-order Magnus twist of one step, with the strains at its two Zanna points.

    Args:
        h: step length [m].
        P: (2, 6, n) basis at the Zanna points.
        r: (2, 6) reference strain at the Zanna points.
        q_d: (n,) the division's coordinates.

    Returns:
        ``(Omega, xi1, xi2)``.
    """
    xi1 = P[0] @ q_d + r[0]
    xi2 = P[1] @ q_d + r[1]
    Omega = 0.5 * h * (xi1 + xi2) + _C * h * h * (ad(xi1) @ xi2)
    return Omega, xi1, xi2


def _division_scan(g0, J0, dd: DivisionData, q):
    """Poses and Jacobians at every point of one division (first point included)."""
    o, n = dd.offset, dd.n_dof
    q_d = q[o : o + n]

    def step(carry, x):
        g, J = carry
        h, P, r = x
        Omega, xi1, xi2 = magnus_omega(h, P, r, q_d)
        c = _C * h * h
        R, p, T = exp_and_tangent(Omega)
        g = g @ pose(R, p)
        if n:
            dOmega = 0.5 * h * (P[0] + P[1]) + c * (ad(xi1) @ P[1] - ad(xi2) @ P[0])
            J = J.at[:, o : o + n].add(T @ dOmega)
        J = Ad_inv_Rp(R, p) @ J
        return (g, J), (g, J)

    _, (gs, Js) = lax.scan(step, (g0, J0), (dd.h, dd.Phi_z, dd.xi_ref_z))
    gs = jnp.concatenate([g0[None], gs])
    Js = jnp.concatenate([J0[None], Js])
    return gs, Js


def poses_and_jacobians(
    data: LinkageData, q: Float[Array, " n_dof"]
) -> tuple[Float[Array, "n_points 4 4"], Float[Array, "n_points 6 n_dof"]]:
    """Poses ``g`` (world frame) and body Jacobians ``J`` at every significant point.

    Args:
        data: precomputed linkage (:func:`sorojax.model.precompute`).
        q: generalised coordinates, shape ``(n_dof,)``.

    Returns:
        ``(g, J)``: ``(n_points, 4, 4)`` and ``(n_points, 6, n_dof)``; ``J`` maps qd to
        the body twist (angular first) at each point, in the point's own frame.
    """
    n = data.n_dof
    dtype = q.dtype
    tips: list = []
    gs, Js = [], []
    for ld in data.links:
        if ld.parent == 0:
            g_p, J_p = jnp.eye(4, dtype=dtype), jnp.zeros((6, n), dtype=dtype)
        else:
            g_p, J_p = tips[ld.parent - 1]
        g = g_p @ ld.placement
        J = Ad_inv(ld.placement) @ J_p
        nj = ld.joint_Phi.shape[1]
        if nj:
            q_j = q[ld.joint_offset : ld.joint_offset + nj]
            g, J = _joint_step(g, J, ld.joint_Phi, q_j, ld.joint_offset)
        gs.append(g[None])
        Js.append(J[None])
        g = g @ ld.g_i
        J = Ad_inv(ld.g_i) @ J
        if ld.soft:
            for dd in ld.divisions:
                gd, Jd = _division_scan(g, J, dd, q)
                gs.append(gd)
                Js.append(Jd)
                g, J = gd[-1], Jd[-1]
        else:
            gs.append(g[None])
            Js.append(J[None])
        g = g @ ld.g_f
        J = Ad_inv(ld.g_f) @ J
        gs.append(g[None])
        Js.append(J[None])
        tips.append((g, J))
    return jnp.concatenate(gs), jnp.concatenate(Js)


def strains(data: LinkageData, q: Float[Array, " n_dof"]) -> Float[Array, "n_points 6"]:
    """Screw strain at every significant point.

    Rod points: ``xi = Phi q + xi_ref`` [1/m angular, - linear]; joint points: the joint
    twist ``Phi_j q_j``; centres of mass and tips: zero.
    """
    out = []
    for ld in data.links:
        nj = ld.joint_Phi.shape[1]
        q_j = q[ld.joint_offset : ld.joint_offset + nj]
        out.append((ld.joint_Phi @ q_j)[None])
        if ld.soft:
            for dd in ld.divisions:
                q_d = q[dd.offset : dd.offset + dd.n_dof]
                out.append(jnp.einsum("pij,j->pi", dd.Phi, q_d) + dd.xi_ref)
        else:
            out.append(jnp.zeros((1, 6), q.dtype))
        out.append(jnp.zeros((1, 6), q.dtype))
    return jnp.concatenate(out)


def jacobians_dot(data: LinkageData, q, qd) -> Float[Array, "n_points 6 n_dof"]:
    """Time derivatives of the body Jacobians, ``dJ/dt = (dJ/dq) qd`` (forward mode)."""
    return jax.jvp(lambda q_: poses_and_jacobians(data, q_)[1], (q,), (qd,))[1]
