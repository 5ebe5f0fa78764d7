"""Forward kinematics and body Jacobians by the 4th-order Magnus / Zanna recursion.

DESIGN.md section 3 (Renda et al. 2020; Mathew et al. 2022). Between consecutive
significant points X_a -> X_a + h with xi_1, xi_2 at the Zanna points
X_a + h (1/2 -+ sqrt(3)/6):

    Omega  = h/2 (xi_1 + xi_2) + sqrt(3) h^2/12 ad(xi_1) xi_2
    dOmega = h/2 (Phi_1 + Phi_2) + sqrt(3) h^2/12 (ad(xi_1) Phi_2 - ad(xi_2) Phi_1)
    g_{a+1} = g_a exp(Omega),  J_{a+1} = Ad(exp(Omega))^-1 (J_a + T(Omega) dOmega).

A lumped joint is the same step with Omega = Phi_j q_j. Links run in topological order
(a Python loop over the static tree); the points of a division are vectorised
(see :func:`_division_scan`).
Jacobian columns are full width (n_dof) so that trees compose without bookkeeping.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array, Float

from ..lie import Ad_inv, ad, hat3
from ..model._precompute import DivisionData, LinkageData
from ._step import Ad_inv_Rp, exp_and_tangent, pose

_C = math.sqrt(3.0) / 12.0


def _joint_step(g, J, Phi, kernel, V_j, rates=None):
    """One lumped-joint step (pose and Jacobian), ``kernel`` its ``(R, p, T[, Td])``.

    ``rates = (eta, etadot_v, qd_j)`` also carries the twist and its velocity-product
    rate through the step (see :func:`_division_scan`).
    """
    R, p, T = (k[0] for k in kernel[:3])
    J = J + T @ (Phi @ V_j)
    Ai = Ad_inv_Rp(R, p)
    if rates is None:
        return g @ pose(R, p), Ai @ J, None
    eta, etadot, qd_j = rates
    Od = Phi @ qd_j
    y = Ai @ (T @ Od)
    eta1 = Ai @ eta + y
    etadot1 = Ai @ (etadot + kernel[3][0] @ Od) + ad(eta1) @ y
    return g @ pose(R, p), Ai @ J, (eta1, etadot1)


def _Ad(g):
    """Ad(g) of a 4x4 pose, angular first: [[R, 0], [hat(p) R, R]]."""
    R, p = g[:3, :3], g[:3, 3]
    Z = jnp.zeros((3, 3), dtype=g.dtype)
    return jnp.block([[R, Z], [hat3(p) @ R, R]])


def _prefix_poses(E):
    """Relative poses ``G_a = E_0 E_1 ... E_{a-1}`` (``G_0 = I``), log-depth scan."""
    G = lax.associative_scan(jnp.matmul, E)
    eye = jnp.eye(4, dtype=E.dtype)[None]
    return jnp.concatenate([eye, G])


def division_twists(dd: DivisionData, q, qd=None):
    """Magnus twists of every step of a division, with what their Jacobians need.

    Returns ``(Omega, Od, aux)``: ``Omega`` ``(m, 6)``; with ``qd``, ``Od = dOmega qd``
    ``(m, 6)`` (else None); ``aux = (xi1, xi2, ad1, ad2, Odd)`` (``Odd`` None without
    ``qd``), see :func:`_division_scan`.
    """
    o, n = dd.offset, dd.n_dof
    q_d = q[o : o + n]
    xi = jnp.einsum("szan,n->sza", dd.Phi_z, q_d) + dd.xi_ref_z
    xi1, xi2 = xi[:, 0], xi[:, 1]
    c = _C * dd.h * dd.h
    ad1, ad2 = jax.vmap(ad)(xi1), jax.vmap(ad)(xi2)
    Omega = 0.5 * dd.h[:, None] * (xi1 + xi2) + c[:, None] * jnp.einsum(
        "sab,sb->sa", ad1, xi2
    )
    Od = Odd = None
    if qd is not None:
        xid = jnp.einsum("szan,n->sza", dd.Phi_z, qd[o : o + n])
        xid1, xid2 = xid[:, 0], xid[:, 1]
        Od = 0.5 * dd.h[:, None] * (xid1 + xid2) + c[:, None] * (
            jnp.einsum("sab,sb->sa", ad1, xid2) - jnp.einsum("sab,sb->sa", ad2, xid1)
        )
        Odd = 2.0 * c[:, None] * jnp.einsum("sab,sb->sa", jax.vmap(ad)(xid1), xid2)
    return Omega, Od, (xi1, xi2, ad1, ad2, Odd)


def batched_kernels(Omegas: list, Ods: list | None = None) -> list:
    """``exp_and_tangent`` (and, with ``Ods``, its rate) of every step in one call.

    ``Omegas``: a list of ``(m_i, 6)`` twists (divisions, joints); returns a list of
    ``(R, p, T)`` or ``(R, p, T, Tdot)`` per entry. One vectorised kernel for the
    whole linkage keeps the compiled program small: its size (and compile time)
    no longer grows with the number of divisions and joints.
    """
    if not Omegas:
        return []
    sizes = np.cumsum([O.shape[0] for O in Omegas])[:-1]
    Om = jnp.concatenate(Omegas)
    if Ods is None:
        out = jax.vmap(exp_and_tangent)(Om)
    else:
        (R, p, T), (_, _, Td) = jax.vmap(
            lambda O, dO: jax.jvp(exp_and_tangent, (O,), (dO,))
        )(Om, jnp.concatenate(Ods))
        out = (R, p, T, Td)
    parts = [jnp.split(x, sizes) for x in out]
    return list(zip(*parts, strict=True))


def step_kernels(data: LinkageData, q, qd=None) -> tuple[list, list]:
    """Kernels of every joint and division step of the linkage, in one call.

    Every step's twist depends on q alone, so all of them are formed first
    (:func:`division_twists`, joint twists ``Phi_j q_j``) and go through one
    :func:`batched_kernels` call. Returns ``(kernels, twists)``: the kernels in link
    order (a link's joint, if it has coordinates, then its divisions) and the
    divisions' :func:`division_twists`.
    """
    Omegas, Ods, twists = [], [], []
    for ld in data.links:
        nj = ld.joint_Phi.shape[1]
        if nj:
            sl = slice(ld.joint_offset, ld.joint_offset + nj)
            Omegas.append((ld.joint_Phi @ q[sl])[None])
            if qd is not None:
                Ods.append((ld.joint_Phi @ qd[sl])[None])
        for dd in ld.divisions if ld.soft else ():
            tw = division_twists(dd, q, qd)
            twists.append(tw)
            Omegas.append(tw[0])
            if qd is not None:
                Ods.append(tw[1])
    return batched_kernels(Omegas, None if qd is None else Ods), twists


def _division_scan(g0, J0, dd: DivisionData, V, kernel, twists, rates=None):
    """Poses and Jacobians at every point of one division (first point included).

    Vectorised over the division's steps: every Magnus twist depends on q alone, so
    all exp(Omega_a) and T(Omega_a) are evaluated at once; the only sequential part is
    the prefix product of the step poses (an associative scan, log depth). In the
    frame of the division's first point the Jacobian recursion is a prefix sum,

        Ad(G_a) J_a = J_0 + sum_{b<a} Ad(G_b) T_b dOmega_b,

    with G_a the pose of point a relative to the first point. ``J`` here is the
    Jacobian times the column block ``V`` (identity: the Jacobian; ``qd``: twists).

    With ``rates = (eta_0, etadot_0, qd)`` (and ``V`` the identity) the twists
    ``eta_a = J_a qd`` and their velocity-product rates ``etadot_a = Jdot_a qd`` come
    from the same prefix sums, differentiated in time: with ``y_b = T_b Omegadot_b``,
    ``V_b = eta_b - Ad(G_b)^-1 eta_0`` (the body twist of point b relative to the
    first point) and ``d/dt Ad(G) x = Ad(G) (xdot + ad(G^-1 Gdot) x)``,

        etadot_a = Ad(G_a)^-1 (etadot_0 + sum_{b<a} Ad(G_b) (ydot_b + ad(V_b) y_b))
                   + ad(Ad(G_a)^-1 eta_0) eta_a,

    ``ydot_b = Tdot_b Omegadot_b + T_b Omegaddot_b``, ``Omegadot = dOmega qd``,
    ``Omegaddot = 2 sqrt(3) h^2/12 ad(Phi_1 qd) (Phi_2 qd)`` (qdd = 0) and ``Tdot`` a
    forward-mode derivative of the elementwise kernel only: no derivative of the
    prefix product is taken.

    ``kernel``: the steps' ``(R, p, T[, Tdot])`` and ``twists`` their
    :func:`division_twists` (both from the batched pass of :func:`_tree_pass`).
    """
    o, n = dd.offset, dd.n_dof
    c = _C * dd.h * dd.h
    _, Od, (_, _, ad1, ad2, Odd) = twists
    if rates is None:
        R, p, T = kernel[:3]
    else:
        eta0, etadot0, qd = rates
        R, p, T, Td = kernel
    E = jax.vmap(pose)(R, p)
    G = _prefix_poses(E)  # (m + 1, 4, 4)
    gs = jnp.einsum("ab,pbc->pac", g0, G)
    Ginv = jax.vmap(lambda g: Ad_inv_Rp(g[:3, :3], g[:3, 3]))(G)
    Js = jnp.broadcast_to(J0, (G.shape[0],) + J0.shape)
    if n:
        AdG = jax.vmap(_Ad)(G[:-1])  # (m, 6, 6)
        P1, P2 = dd.Phi_z[:, 0], dd.Phi_z[:, 1]
        dOmega = 0.5 * dd.h[:, None, None] * (P1 + P2) + c[:, None, None] * (
            jnp.einsum("sab,sbn->san", ad1, P2) - jnp.einsum("sab,sbn->san", ad2, P1)
        )
        dOmega = jnp.einsum("san,nk->sak", dOmega, V[o : o + n])
        S = jnp.einsum("sab,sbc,sck->sak", AdG, T, dOmega)  # (m, 6, k)
        Js = Js + jnp.concatenate([jnp.zeros_like(S[:1]), jnp.cumsum(S, axis=0)])
    Js = jnp.einsum("pab,pbn->pan", Ginv, Js)
    if rates is None:
        return gs, Js, None
    eta = jnp.einsum("pai,i->pa", Js, qd)
    Ge0 = jnp.einsum("pab,b->pa", Ginv, eta0)  # Ad(G_a)^-1 eta_0
    if n:
        y = jnp.einsum("sab,sb->sa", T, Od)
        yd = jnp.einsum("sab,sb->sa", Td, Od) + jnp.einsum("sab,sb->sa", T, Odd)
        Vb = eta[:-1] - Ge0[:-1]
        inc = yd + jnp.einsum("sab,sb->sa", jax.vmap(ad)(Vb), y)
        inc = jnp.einsum("sab,sb->sa", AdG, inc)
        acc = etadot0[None] + jnp.concatenate(
            [jnp.zeros_like(inc[:1]), jnp.cumsum(inc, 0)]
        )
    else:
        acc = jnp.broadcast_to(etadot0, (G.shape[0], 6))
    etadot = jnp.einsum("pab,pb->pa", Ginv, acc) + jnp.einsum(
        "pab,pb->pa", jax.vmap(ad)(Ge0), eta
    )
    return gs, Js, (eta, etadot)


def poses_and_jacobians(
    data: LinkageData, q: Float[Array, " n_dof"], V: Array | None = None
) -> tuple[Float[Array, "n_points 4 4"], Float[Array, "n_points 6 k"]]:
    """Poses ``g`` (world frame) and body Jacobians ``J`` at every significant point.

    Args:
        data: precomputed linkage (:func:`sorojax.model.precompute`).
        q: generalised coordinates, shape ``(n_dof,)``.
        V: optional ``(n_dof, k)`` block: return ``J @ V`` instead of ``J``, at cost
            O(points k) instead of O(points n_dof) (``V = qd[:, None]`` gives twists).

    Returns:
        ``(g, J)``: ``(n_points, 4, 4)`` and ``(n_points, 6, n_dof)``; ``J`` maps qd to
        the body twist (angular first) at each point, in the point's own frame.
    """
    g, J, _ = _tree_pass(data, q, V, None)
    return g, J


def kinematics_and_rates(
    data: LinkageData, q: Float[Array, " n_dof"], qd: Float[Array, " n_dof"]
) -> tuple[Array, Array, Array, Array]:
    """``(g, J, eta, Jdot qd)`` at every significant point in one pass.

    The twists ``eta = J qd`` and their velocity-product rates ``Jdot qd`` (the
    acceleration of each point's body frame when qdd = 0) follow the recursion in
    time (:func:`_division_scan`); only the elementwise step kernel is differentiated.

    Returns:
        ``(n_points, 4, 4)``, ``(n_points, 6, n_dof)``, ``(n_points, 6)``,
        ``(n_points, 6)``.
    """
    g, J, (eta, etadot) = _tree_pass(data, q, None, qd)
    return g, J, eta, etadot


def _tree_pass(data: LinkageData, q, V, qd):
    """Poses, Jacobians (times ``V``) and, when ``qd`` is given, twists and rates."""
    n = data.n_dof
    dtype = q.dtype
    V = jnp.eye(n, dtype=dtype) if V is None else V
    k = V.shape[1]
    zero6 = jnp.zeros(6, dtype=dtype)
    tips: list = []
    gs, Js, etas, etadots = [], [], [], []

    def append(g, J, r, batched=False):
        gs.append(g if batched else g[None])
        Js.append(J if batched else J[None])
        if r is not None:
            etas.append(r[0] if batched else r[0][None])
            etadots.append(r[1] if batched else r[1][None])

    def transport(g, J, r, h):
        """Through a constant transform ``h``."""
        A = Ad_inv(h)
        return g @ h, A @ J, None if r is None else (A @ r[0], A @ r[1])

    kernels, twists = step_kernels(data, q, qd)
    kernels, twists_it = iter(kernels), iter(twists)

    for ld in data.links:
        if ld.parent == 0:
            g, J = jnp.eye(4, dtype=dtype), jnp.zeros((6, k), dtype=dtype)
            r = None if qd is None else (zero6, zero6)
        else:
            g, J, r = tips[ld.parent - 1]
        g, J, r = transport(g, J, r, ld.placement)
        nj = ld.joint_Phi.shape[1]
        if nj:
            sl = slice(ld.joint_offset, ld.joint_offset + nj)
            rj = None if qd is None else (r[0], r[1], qd[sl])
            g, J, r = _joint_step(g, J, ld.joint_Phi, next(kernels), V[sl], rj)
        append(g, J, r)
        g, J, r = transport(g, J, r, ld.g_i)
        if ld.soft:
            for dd in ld.divisions:
                rd = None if qd is None else (r[0], r[1], qd)
                gd, Jd, r_all = _division_scan(
                    g, J, dd, V, next(kernels), next(twists_it), rd
                )
                append(gd, Jd, r_all, batched=True)
                g, J = gd[-1], Jd[-1]
                r = None if r_all is None else (r_all[0][-1], r_all[1][-1])
        else:
            append(g, J, r)
        g, J, r = transport(g, J, r, ld.g_f)
        append(g, J, r)
        tips.append((g, J, r))
    rates = None if qd is None else (jnp.concatenate(etas), jnp.concatenate(etadots))
    return jnp.concatenate(gs), jnp.concatenate(Js), rates


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
