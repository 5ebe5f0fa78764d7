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
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array, Float

from ..lie import Ad_inv, ad
from ..model._precompute import LinkageData
from ._step import exp_and_tangent

_C = math.sqrt(3.0) / 12.0


def _ad_apply(a, b):
    """``ad(a) b`` for stacks of twists (angular first), by cross products."""
    w, v = a[..., :3], a[..., 3:]
    x, y = b[..., :3], b[..., 3:]
    return jnp.concatenate(
        [jnp.cross(w, x), jnp.cross(v, x) + jnp.cross(w, y)], axis=-1
    )


def _Ad(R, p):
    """Ad(g) for stacks of (R, p), angular first: [[R, 0], [hat(p) R, R]]."""
    Z = jnp.zeros_like(R)
    top = jnp.concatenate([R, Z], axis=-1)
    bottom = jnp.concatenate([hat3_batched(p) @ R, R], axis=-1)
    return jnp.concatenate([top, bottom], axis=-2)


def _Ad_inv(R, p):
    """Ad(g)^-1 for stacks of (R, p): [[R^T, 0], [-R^T hat(p), R^T]]."""
    Rt = jnp.swapaxes(R, -1, -2)
    Z = jnp.zeros_like(R)
    top = jnp.concatenate([Rt, Z], axis=-1)
    bottom = jnp.concatenate([-Rt @ hat3_batched(p), Rt], axis=-1)
    return jnp.concatenate([top, bottom], axis=-2)


def hat3_batched(p):
    """hat(p) for a stack of 3-vectors ``(..., 3) -> (..., 3, 3)``."""
    z = jnp.zeros_like(p[..., 0])
    x, y, w = p[..., 0], p[..., 1], p[..., 2]
    return jnp.stack(
        [
            jnp.stack([z, -w, y], axis=-1),
            jnp.stack([w, z, -x], axis=-1),
            jnp.stack([-y, x, z], axis=-1),
        ],
        axis=-2,
    )


class Steps(NamedTuple):
    """Every Magnus step of the linkage (flat, in :class:`StepData` order).

    ``R, p, T``: exp(Omega) and the tangent operator; ``xi1, xi2``: strains at the
    Zanna points; with velocities also ``Td`` (dT/dt), ``Od`` (dOmega/dt) and
    ``Odd`` (its velocity-product part, qdd = 0).
    """

    R: Array
    p: Array
    T: Array
    xi1: Array
    xi2: Array
    Td: Array | None = None
    Od: Array | None = None
    Odd: Array | None = None


def steps(data: LinkageData, q, qd=None) -> Steps:
    """Twists and exp/tangent kernels of every step of the linkage in one batch.

    ``Omega = h/2 (xi_1 + xi_2) + c ad(xi_1) xi_2`` (``c = 0`` for joints) for all
    steps at once, then one vectorised :func:`exp_and_tangent` (with its forward-mode
    rate when ``qd`` is given).
    """
    st = data.steps
    xi = jnp.einsum("szan,n->sza", st.Phi_z, q) + st.xi_ref_z
    xi1, xi2 = xi[:, 0], xi[:, 1]
    h, c = st.h[:, None], st.c[:, None]
    Omega = 0.5 * h * (xi1 + xi2) + c * _ad_apply(xi1, xi2)
    if qd is None:
        R, p, T = jax.vmap(exp_and_tangent)(Omega)
        return Steps(R, p, T, xi1, xi2)
    xid = jnp.einsum("szan,n->sza", st.Phi_z, qd)
    xid1, xid2 = xid[:, 0], xid[:, 1]
    Od = 0.5 * h * (xid1 + xid2) + c * (_ad_apply(xi1, xid2) - _ad_apply(xi2, xid1))
    Odd = 2.0 * c * _ad_apply(xid1, xid2)
    (R, p, T), (_, _, Td) = jax.vmap(
        lambda O, dO: jax.jvp(exp_and_tangent, (O,), (dO,))
    )(Omega, Od)
    return Steps(R, p, T, xi1, xi2, Td, Od, Odd)


def step_jacobians(data: LinkageData, k: Steps, V) -> Array:
    """``dOmega V`` of every step: ``(n_steps, 6, cols)`` (``V`` None: identity)."""
    st = data.steps
    P = st.Phi_z if V is None else jnp.einsum("szan,nk->szak", st.Phi_z, V)
    P1, P2 = P[:, 0], P[:, 1]
    h, c = st.h[:, None, None], st.c[:, None, None]
    ad1, ad2 = jax.vmap(ad)(k.xi1), jax.vmap(ad)(k.xi2)
    return 0.5 * h * (P1 + P2) + c * (ad1 @ P2 - ad2 @ P1)


def chain_layout(data: LinkageData) -> tuple[list, int]:
    """Chains of consecutive steps in :class:`StepData` order and the longest one.

    Returns ``([(link, division or None for the joint, first step, n_steps)], m)``.
    """
    out, s = [], 0
    for i, ld in enumerate(data.links):
        if ld.joint_Phi.shape[1]:
            out.append((i, None, s, 1))
            s += 1
        for j, dd in enumerate(ld.divisions if ld.soft else ()):
            m = dd.h.shape[0]
            out.append((i, j, s, m))
            s += m
    return out, max((ch[3] for ch in out), default=0)


def _by_chain(x, layout, fill):
    """Flat per-step array -> ``(n_chains, m_max, ...)``, padded with ``fill``."""
    chains, m = layout
    n = x.shape[0]
    idx = np.full((len(chains), m), n)
    for k, (_, _, s, mk) in enumerate(chains):
        idx[k, :mk] = np.arange(s, s + mk)
    pad = jnp.broadcast_to(jnp.asarray(fill, x.dtype), (1,) + x.shape[1:])
    return jnp.concatenate([x, pad])[idx]


def _prefix_poses(R, p):
    """Poses ``G_a = E_0 ... E_{a-1}`` relative to each chain's first point.

    ``R, p``: ``(n_chains, m, ...)``; returns ``(R_G, p_G)`` of shape
    ``(n_chains, m + 1, ...)`` (``G_0 = I``), by a log-depth associative scan.
    """

    def compose(a, b):
        Ra, pa = a
        Rb, pb = b
        return Ra @ Rb, pa + jnp.einsum("...ab,...b->...a", Ra, pb)

    RG, pG = lax.associative_scan(compose, (R, p), axis=1)
    eye = jnp.broadcast_to(jnp.eye(3, dtype=R.dtype), R[:, :1].shape)
    return (
        jnp.concatenate([eye, RG], axis=1),
        jnp.concatenate([jnp.zeros_like(p[:, :1]), pG], axis=1),
    )


def _cumsum0(x):
    """Prefix sums along axis 1 with a leading zero: ``(n, m) -> (n, m + 1)``."""
    return jnp.concatenate([jnp.zeros_like(x[:, :1]), jnp.cumsum(x, axis=1)], axis=1)


class ChainTerms(NamedTuple):
    """Per-chain quantities relative to each chain's first point (padded).

    ``RG, pG``: poses of the points relative to the first; ``Ginv``: their
    Ad^-1; ``relJ = Ad(G_a)^-1 sum_{b<a} Ad(G_b) T_b dOmega_b V``; with velocities
    ``rel_eta`` (the twist of point a relative to the first, in its own frame) and
    ``rel_etadot`` (its velocity-product rate), see :func:`chain_terms`.
    """

    RG: Array
    pG: Array
    Ginv: Array
    relJ: Array | None
    rel_eta: Array | None = None
    rel_etadot: Array | None = None


def chain_terms(data: LinkageData, k: Steps, layout, dOmegaV=None) -> ChainTerms:
    """Poses, Jacobian and twist increments of every chain, all chains at once.

    Along a chain the pose is a prefix product and, in the frame of the chain's
    first point, the Jacobian recursion is a prefix sum,

        Ad(G_a) J_a = J_0 + sum_{b<a} Ad(G_b) T_b dOmega_b,

    so ``J_a = Ad(G_a)^-1 J_0 + relJ_a``. With velocities, ``y_b = T_b Omegadot_b``
    and ``d/dt Ad(G) x = Ad(G) (xdot + ad(G^-1 Gdot) x)`` give the twists
    ``eta_a = Ad(G_a)^-1 eta_0 + rel_eta_a`` and their velocity-product rates

        etadot_a = Ad(G_a)^-1 etadot_0 + rel_etadot_a + ad(Ad(G_a)^-1 eta_0) eta_a,
        rel_etadot_a = Ad(G_a)^-1 sum_{b<a} Ad(G_b) (ydot_b + ad(rel_eta_b) y_b),

    with ``ydot_b = Tdot_b Omegadot_b + T_b Omegaddot_b``. Nothing here depends on
    the chain's first point (its pose, Jacobian, twist), so every chain of the
    linkage is evaluated in one batch; :func:`_tree_pass` composes them along the
    tree. Padding steps are identities with zero twist rates.
    """
    eye3, eye6 = jnp.eye(3, dtype=k.R.dtype), jnp.eye(6, dtype=k.R.dtype)
    R = _by_chain(k.R, layout, eye3)
    p = _by_chain(k.p, layout, 0.0)
    RG, pG = _prefix_poses(R, p)
    Ginv = _Ad_inv(RG, pG)
    AdG = _Ad(RG[:, :-1], pG[:, :-1])
    if dOmegaV is None and k.Od is None:
        return ChainTerms(RG, pG, Ginv, None)
    T = _by_chain(k.T, layout, eye6)
    relJ = None
    if dOmegaV is not None:
        S = AdG @ T @ _by_chain(dOmegaV, layout, 0.0)
        relJ = Ginv @ _cumsum0(S)
    if k.Od is None:
        return ChainTerms(RG, pG, Ginv, relJ)
    Od = _by_chain(k.Od, layout, 0.0)
    y = jnp.einsum("nsab,nsb->nsa", T, Od)
    yd = jnp.einsum("nsab,nsb->nsa", _by_chain(k.Td, layout, 0.0), Od) + jnp.einsum(
        "nsab,nsb->nsa", T, _by_chain(k.Odd, layout, 0.0)
    )
    rel_eta = jnp.einsum(
        "nsab,nsb->nsa", Ginv, _cumsum0(jnp.einsum("nsab,nsb->nsa", AdG, y))
    )
    inc = jnp.einsum("nsab,nsb->nsa", AdG, yd + _ad_apply(rel_eta[:, :-1], y))
    rel_etadot = jnp.einsum("nsab,nsb->nsa", Ginv, _cumsum0(inc))
    return ChainTerms(RG, pG, Ginv, relJ, rel_eta, rel_etadot)


def _pose(R, p):
    """4x4 poses from stacks of R and p."""
    top = jnp.concatenate([R, p[..., None]], axis=-1)
    bottom = jnp.broadcast_to(
        jnp.asarray([0.0, 0.0, 0.0, 1.0], dtype=R.dtype), R.shape[:-2] + (1, 4)
    )
    return jnp.concatenate([top, bottom], axis=-2)


def chain_poses(ct: ChainTerms, chain: int, m: int, g0):
    """World poses of the ``m + 1`` points of chain ``chain`` from its start ``g0``."""
    return jnp.einsum(
        "ab,pbc->pac", g0, _pose(ct.RG[chain, : m + 1], ct.pG[chain, : m + 1])
    )


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
    """Poses, Jacobians (times ``V``) and, when ``qd`` is given, twists and rates.

    One batch for every step (:func:`steps`) and every chain (:func:`chain_terms`);
    the Python loop over the static tree only composes each chain with the pose,
    Jacobian and twist at its first point (a few small products per chain).
    """
    n = data.n_dof
    dtype = q.dtype
    k_cols = n if V is None else V.shape[1]
    zero6 = jnp.zeros(6, dtype=dtype)
    layout = chain_layout(data)
    k = steps(data, q, qd)
    ct = chain_terms(data, k, layout, step_jacobians(data, k, V))
    chain_of = {(ch[0], ch[1]): c for c, ch in enumerate(layout[0])}
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

    def run_chain(c, m, g, J, r):
        """Poses, Jacobians and rates at the ``m + 1`` points of chain ``c``."""
        Gi = ct.Ginv[c, : m + 1]
        gc = chain_poses(ct, c, m, g)
        Jc = jnp.einsum("pab,bk->pak", Gi, J) + ct.relJ[c, : m + 1]
        if r is None:
            return gc, Jc, None
        Ge0 = jnp.einsum("pab,b->pa", Gi, r[0])
        eta = Ge0 + ct.rel_eta[c, : m + 1]
        etadot = (
            jnp.einsum("pab,b->pa", Gi, r[1])
            + ct.rel_etadot[c, : m + 1]
            + _ad_apply(Ge0, eta)
        )
        return gc, Jc, (eta, etadot)

    for i, ld in enumerate(data.links):
        if ld.parent == 0:
            g, J = jnp.eye(4, dtype=dtype), jnp.zeros((6, k_cols), dtype=dtype)
            r = None if qd is None else (zero6, zero6)
        else:
            g, J, r = tips[ld.parent - 1]
        g, J, r = transport(g, J, r, ld.placement)
        if ld.joint_Phi.shape[1]:
            gc, Jc, rc = run_chain(chain_of[(i, None)], 1, g, J, r)
            g, J = gc[-1], Jc[-1]
            r = None if rc is None else (rc[0][-1], rc[1][-1])
        append(g, J, r)
        g, J, r = transport(g, J, r, ld.g_i)
        if ld.soft:
            for j, dd in enumerate(ld.divisions):
                gd, Jd, rd = run_chain(chain_of[(i, j)], dd.h.shape[0], g, J, r)
                append(gd, Jd, rd, batched=True)
                g, J = gd[-1], Jd[-1]
                r = None if rd is None else (rd[0][-1], rd[1][-1])
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
