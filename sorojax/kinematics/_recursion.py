"""Forward kinematics and body Jacobians by the Magnus / Zanna recursion.

DESIGN.md section 3 (Renda et al. 2020; Mathew et al. 2022). Between consecutive
significant points X_a -> X_a + h with xi_1, xi_2 at the Zanna points
X_a + h (1/2 -+ sqrt(3)/6):

    Omega  = h/2 (xi_1 + xi_2) + sqrt(3) h^2/12 ad(xi_1) xi_2
    dOmega = h/2 (Phi_1 + Phi_2) + sqrt(3) h^2/12 (ad(xi_1) Phi_2 - ad(xi_2) Phi_1)
    g_{a+1} = g_a exp(Omega),  J_{a+1} = Ad(exp(Omega))^-1 (J_a + T(Omega) dOmega).

That is the 4th-order step. A linkage with a division of basis order >= 4 uses the
6th-order step instead (3 Gauss nodes, :func:`sorojax.kinematics._step.magnus6`,
dOmega applied by :func:`~sorojax.kinematics._step.magnus6_apply` and its transpose),
because the 4th-order one
integrates the Jacobian columns of such modes with an error that becomes the floor
of the statics (tests/test_magnus_accuracy.py); the choice is static
(``data.steps.order``) and the rest of the recursion is the same.

A lumped joint is the same step with Omega = Phi_j q_j, and a constant transform
(placement, g_i, g_f) a step with a fixed exp(Omega) and dOmega = 0. Every twist and
exp/tangent kernel of the linkage is evaluated in one batch (:func:`steps`); each
link is one chain of steps whose poses, Jacobians and twist rates relative to the
chain's start are prefix products and prefix sums, evaluated for all links in one
padded batch (:func:`chain_terms`); a Python loop over the static tree then only
carries the links' tips, and every point is composed with its link's start in one
batch. The compiled program's size no longer grows with the number of divisions and
joints, only the short tree loop does. Jacobian columns are full width (n_dof) so
that trees compose without bookkeeping.
"""

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jaxtyping import Array, Float

from ..lie import Ad, Ad_inv, ad
from ..model._precompute import LinkageData
from . import _leaves
from ._step import ad_apply as _ad_apply
from ._step import ad_apply_many as _ad_apply_many
from ._step import ad_transpose_apply as _ad_transpose_apply
from ._step import (
    exp_and_tangent,
    exp_and_tangent_many,
    magnus6,
    magnus6_apply,
    magnus6_apply_transpose,
    tangent_apply,
)


def _Ad(R, p):
    """:func:`sorojax.lie.Ad` of stacks of poses given as ``(R, p)``."""
    return jnp.vectorize(Ad, signature="(4,4)->(6,6)")(_pose(R, p))


def _Ad_inv(R, p):
    """:func:`sorojax.lie.Ad_inv` of stacks of poses given as ``(R, p)``."""
    return jnp.vectorize(Ad_inv, signature="(4,4)->(6,6)")(_pose(R, p))


class Steps(NamedTuple):
    """Every Magnus step of the linkage (flat, in :class:`StepData` order).

    ``R, p, T``: exp(Omega) and the tangent operator; ``xi1, xi2``: strains at the
    Zanna points (4th-order steps); ``xi``: strains at the 3 nodes
    ``(n_steps, 3, 6)`` (6th-order steps); with velocities also ``Td_Od`` ((dT/dt)
    Od, ``(n_steps, 6)``), ``Od`` (dOmega/dt) and ``Odd`` (its velocity-product
    part, qdd = 0).
    """

    R: Array
    p: Array
    T: Array
    xi1: Array | None
    xi2: Array | None
    Td_Od: Array | None = None
    Od: Array | None = None
    Odd: Array | None = None
    xi: Array | None = None


def steps(data: LinkageData, q, qd=None, st=None, many: bool = True) -> Steps:
    """Twists and exp/tangent kernels of every step of the linkage in one batch.

    ``st``: the steps to evaluate (default ``data.steps``, the chain's;
    ``data.leaf_steps`` for the leaves').

    ``Omega = h/2 (xi_1 + xi_2) + c ad(xi_1) xi_2`` (``c = 0`` for joints) for all
    steps at once, then one vectorised :func:`exp_and_tangent` (with its forward-mode
    rate when ``qd`` is given). 6th-order steps: :func:`magnus6`, the rates by
    forward mode (``Od = dOmega[xid]``, ``Odd = d^2 Omega[xid, xid]``, as the
    4th-order ``Od`` and ``Odd`` are). Without ``qd``, ``many`` takes the kernel
    whose derivative serves many tangents at once (:func:`exp_and_tangent_many`:
    statics' Newton tangent, kinematics queries); ``many=False`` the plain one,
    cheaper for a single tangent or cotangent (the dynamics).
    """
    st = data.steps if st is None else st
    xi = st.strains(q)
    if st.order == 6:
        return _steps6(st, xi, qd, many)
    xi1, xi2 = xi[:, 0], xi[:, 1]
    h, c = st.h[:, None], st.c[:, None]
    Omega = 0.5 * h * (xi1 + xi2) + c * _ad_apply(xi1, xi2)
    if qd is None:
        R, p, T = (exp_and_tangent_many if many else jax.vmap(exp_and_tangent))(Omega)
        return Steps(R, p, T, xi1, xi2)
    xid = st.strains(qd, ref=False)
    Od = _omega_rate4(st, xi1, xi2, xid)
    Odd = 2.0 * c * _ad_apply(xid[:, 0], xid[:, 1])
    R, p, T = jax.vmap(exp_and_tangent)(Omega)
    return Steps(R, p, T, xi1, xi2, _tangent_rate(Omega, Od), Od, Odd)


def _steps6(st, xi, qd, many: bool = True) -> Steps:
    """:func:`steps` for 6th-order steps, from the strains ``xi`` at the nodes."""
    Omega = magnus6(xi, st.h)
    if qd is None:
        R, p, T = (exp_and_tangent_many if many else jax.vmap(exp_and_tangent))(Omega)
        return Steps(R, p, T, None, None, xi=xi)
    xid = st.strains(qd, ref=False)

    def rates(x):
        return jax.jvp(lambda y: magnus6(y, st.h), (x,), (xid,))[1]

    Od, Odd = jax.jvp(rates, (xi,), (xid,))
    R, p, T = jax.vmap(exp_and_tangent)(Omega)
    return Steps(R, p, T, None, None, _tangent_rate(Omega, Od), Od, Odd, xi)


def _tangent_rate(Omega, Od):
    """``(dT/dt) Od`` of every step, ``dT/dt`` the derivative of T(Omega) along Od.

    The forward derivative of :func:`tangent_apply` (a few cross products), not the
    6 x 6 derivative of T read by one product.
    """
    return jax.vmap(
        lambda O, dO: jax.jvp(lambda O_: tangent_apply(O_, dO), (O,), (dO,))[1]
    )(Omega, Od)


def step_jacobians(data: LinkageData, k: Steps, V, st=None) -> Array:
    """``dOmega V`` of every step: ``(n_steps, 6, cols)`` (``V`` None: identity).

    ``st``: the steps ``k`` were made from (default ``data.steps``).
    """
    st = data.steps if st is None else st
    return dOmega(st, k, st.basis(V))


def dOmega(st, k: Steps, P) -> Array:
    """``dOmega P`` of the steps ``st`` (made into ``k``): ``(n_steps, 6, cols)``.

    ``P``: bases at the steps' nodes, ``(n_steps, n_nodes, 6, cols)``.
    """
    if st.order == 6:
        dO = magnus6_apply(k.xi, st.h, jnp.swapaxes(P, -1, -2))
        return jnp.swapaxes(dO, -1, -2)
    P1, P2 = P[:, 0], P[:, 1]
    h, c = st.h[:, None, None], st.c[:, None, None]
    ad1, ad2 = jax.vmap(ad)(k.xi1), jax.vmap(ad)(k.xi2)
    return 0.5 * h * (P1 + P2) + c * (ad1 @ P2 - ad2 @ P1)


def step_rates(st, k: Steps, qd) -> Array:
    """``dOmega qd`` of the steps ``st`` (made into ``k``): ``(n_steps, 6)``.

    :func:`step_jacobians` of the one column ``qd``, by cross products (as
    :func:`steps` forms its rates) instead of a 6 x 6 matrix per step.
    """
    xid = st.strains(qd, ref=False)
    if st.order == 6:
        return magnus6_apply(k.xi, st.h, xid[..., None, :])[..., 0, :]
    return _omega_rate4(st, k.xi1, k.xi2, xid)


def _omega_rate4(st, xi1, xi2, xid) -> Array:
    """``dOmega`` of 4th-order steps along the node strain rates ``xid``.

    ``h/2 (xid_1 + xid_2) + c (ad(xi_1) xid_2 - ad(xi_2) xid_1)``, ``xid`` of shape
    ``(n, 2, 6)``, by cross products.
    """
    xid1, xid2 = xid[:, 0], xid[:, 1]
    h, c = st.h[:, None], st.c[:, None]
    a12, a21 = _ad_apply_many([(xi1, xid2), (xi2, xid1)])
    return 0.5 * h * (xid1 + xid2) + c * (a12 - a21)


def step_jacobians_transpose(data: LinkageData, k: Steps, z, st=None) -> Array:
    """``sum_s dOmega_s^T z_s`` for wrenches ``z`` ``(n_steps, 6)``: ``(n_dof,)``.

    With ``dOmega = h/2 (P1 + P2) + c (ad(xi_1) P2 - ad(xi_2) P1)`` this is
    ``sum_s P1^T (h/2 z - c ad(xi_2)^T z) + P2^T (h/2 z + c ad(xi_1)^T z)``: one
    product with the constant strain bases and no ``(n_steps, 6, n_dof)`` array (the
    contraction of that array, fused with its making, cost most of a residual under
    ``vmap`` on CPU). 6th-order steps likewise, with the nodes' covectors from
    :func:`magnus6_apply_transpose`. ``st``: as in :func:`step_jacobians`.
    """
    st = data.steps if st is None else st
    if st.order == 6:
        Z = magnus6_apply_transpose(k.xi, st.h, z)
        return st.basis_transpose(Z)
    h, c = st.h[:, None], st.c[:, None]
    Z1 = 0.5 * h * z - c * _ad_transpose_apply(k.xi2, z)
    Z2 = 0.5 * h * z + c * _ad_transpose_apply(k.xi1, z)
    return st.basis_transpose(jnp.stack([Z1, Z2], axis=1))


class ChainLayout(NamedTuple):
    """Static layout of the per-link chains (numpy index arrays, built at trace time).

    Link ``l``'s chain is its steps in order: placement (constant), joint (if it has
    coordinates), ``g_i`` (constant), the steps of its divisions, ``g_f`` (constant).
    Prefix index ``a`` of a chain is the point after its first ``a`` steps (``a = 0``:
    the parent's tip). Attributes: ``idx_Rp``, ``idx_rate`` ``(n_links, m)`` sources
    of every slot's ``(R, p)`` and of its other step arrays in the arrays that
    :func:`chain_terms` builds (constant steps and padding take identities / zeros);
    ``point_link``, ``point_slot`` ``(n_points,)`` the chain and prefix index of every
    significant point; ``tip_slot`` ``(n_links,)``; ``step_link``, ``step_slot``
    ``(n_steps,)`` the chain and slot of every real step; ``m`` the longest chain.

    Points are the chain's (``core``: their point indices, in order); leaves (see
    :mod:`sorojax.model._layout`) hang from chain points: ``leaf_row`` is the row
    (in ``core``) of each leaf's chain point, ``leaf_first``, ``leaf_stop``
    ``(n_core,)`` the range of leaves hanging from each chain point, ``order``
    ``(n_points,)`` the row of every point in ``concatenate([core rows, leaf
    rows])`` and ``row`` ``(n_points,)`` each point's row in ``core`` (-1: a leaf).
    """

    idx_Rp: np.ndarray
    idx_rate: np.ndarray
    point_link: np.ndarray
    point_slot: np.ndarray
    tip_slot: np.ndarray
    step_link: np.ndarray
    step_slot: np.ndarray
    m: int
    core: np.ndarray
    leaf_row: np.ndarray
    leaf_first: np.ndarray
    leaf_stop: np.ndarray
    order: np.ndarray
    row: np.ndarray


def chain_layout(data: LinkageData) -> ChainLayout:
    """The :class:`ChainLayout` of ``data`` (static: from shapes only)."""
    n_links = len(data.links)
    n_steps = data.steps.h.shape[0]
    pad = n_steps + 3 * n_links  # identity slot, after the real and constant steps
    rows_Rp, rows_rate, pl, ps, tips = [], [], [], [], []
    s = 0
    for i, ld in enumerate(data.links):
        Rp, rate = [n_steps + 3 * i], [pad]  # placement
        if ld.joint_Phi.shape[1]:
            Rp.append(s)
            rate.append(s)
            s += 1
        pl.append(i)
        ps.append(len(Rp))  # joint point
        Rp.append(n_steps + 3 * i + 1)  # g_i
        rate.append(pad)
        if ld.soft:
            for dd in ld.divisions:
                m = dd.h.shape[0]
                first = len(Rp)
                Rp.extend(range(s, s + m))
                rate.extend(range(s, s + m))
                s += m
                pl.extend([i] * (m + 1))
                ps.extend(range(first, first + m + 1))
        else:
            pl.append(i)
            ps.append(len(Rp))  # centre of mass
        Rp.append(n_steps + 3 * i + 2)  # g_f
        rate.append(pad)
        pl.append(i)
        ps.append(len(Rp))  # tip
        tips.append(len(Rp))
        rows_Rp.append(Rp)
        rows_rate.append(rate)
    m = max(len(r) for r in rows_Rp)
    idx_Rp = np.full((n_links, m), pad)
    idx_rate = np.full((n_links, m), pad)
    for i, (a, b) in enumerate(zip(rows_Rp, rows_rate, strict=True)):
        idx_Rp[i, : len(a)] = a
        idx_rate[i, : len(b)] = b
    step_link, step_slot = np.zeros(n_steps, int), np.zeros(n_steps, int)
    for i, row in enumerate(rows_rate):
        for a, src in enumerate(row):
            if src < n_steps:
                step_link[src], step_slot[src] = i, a
    n_points = data.point_weight.shape[0]
    leaves = np.asarray(data.leaf_points, int)
    is_leaf = np.zeros(n_points, bool)
    is_leaf[leaves] = True
    core = np.flatnonzero(~is_leaf)
    row = np.full(n_points, -1)
    row[core] = np.arange(len(core))
    leaf_row = row[np.asarray(data.leaf_parents, int)]
    order = np.empty(n_points, int)
    order[core] = np.arange(len(core))
    order[leaves] = len(core) + np.arange(len(leaves))
    rows = np.arange(len(core))
    return ChainLayout(
        idx_Rp,
        idx_rate,
        np.array(pl, int),
        np.array(ps, int),
        np.array(tips, int),
        step_link,
        step_slot,
        m,
        core,
        leaf_row,
        np.searchsorted(leaf_row, rows),
        np.searchsorted(leaf_row, rows, side="right"),
        order,
        row,
    )


def _gather(x, idx, fill, extra: int):
    """Rows ``idx`` of ``x`` extended by ``extra`` rows of ``fill``."""
    pad = jnp.broadcast_to(jnp.asarray(fill, x.dtype), (extra,) + x.shape[1:])
    return jnp.concatenate([x, pad])[idx]


@functools.partial(jax.custom_jvp, nondiff_argnums=(2,))
def _prefix_poses(R, p, sequential: bool = False):
    """Poses ``G_a = E_0 ... E_{a-1}`` relative to each chain's first point.

    ``R, p``: ``(n_chains, m, ...)``; returns ``(R_G, p_G)`` of shape
    ``(n_chains, m + 1, ...)`` (``G_0 = I``), by a log-depth associative scan, or
    with ``sequential`` by a ``lax.scan`` along the chains (one composition in the
    program instead of one per level). Its derivative is a prefix sum
    (:func:`_prefix_poses_jvp`), not the scan's own: differentiated, the scan
    repeats its small products once per level or step, for every tangent.
    """

    def compose(a, b):
        Ra, pa = a
        Rb, pb = b
        return Ra @ Rb, pa + jnp.einsum("...ab,...b->...a", Ra, pb)

    if sequential:

        def step(G, E):
            G = compose(G, E)
            return G, G

        first = (R[:, 0], p[:, 0])
        rest = (jnp.moveaxis(R[:, 1:], 1, 0), jnp.moveaxis(p[:, 1:], 1, 0))
        _, (RG, pG) = lax.scan(step, first, rest)
        RG = jnp.concatenate([R[:, :1], jnp.moveaxis(RG, 0, 1)], axis=1)
        pG = jnp.concatenate([p[:, :1], jnp.moveaxis(pG, 0, 1)], axis=1)
    else:
        RG, pG = lax.associative_scan(compose, (R, p), axis=1)
    eye = jnp.broadcast_to(jnp.eye(3, dtype=R.dtype), R[:, :1].shape)
    return (
        jnp.concatenate([eye, RG], axis=1),
        jnp.concatenate([jnp.zeros_like(p[:, :1]), pG], axis=1),
    )


@_prefix_poses.defjvp
def _prefix_poses_jvp(sequential, primals, tangents):
    """Tangents of the prefix poses as one prefix sum.

    With ``G_{a+1} = G_a E_a``, ``dG_a = sum_{b<a} G_b dE_b E_{b+1} ... E_{a-1} =
    S_a G_a``, ``S_a = sum_{b<a} G_b dE_b G_{b+1}^-1``: in blocks,
    ``S = [[A, c], [0, 0]]`` with ``A_b = R_b dR_b R_{b+1}^T`` and
    ``c_b = R_b dp_b - A_b p_{b+1}`` (``R, p`` of ``G``), so ``dR_G = S_A R_G`` and
    ``dp_G = S_A p_G + S_c``. Exact for any tangents ``dR, dp`` (not only those
    of rotations), linear in them and batched over all steps.
    """
    R, p = primals
    dR, dp = tangents
    RG, pG = _prefix_poses(R, p, sequential)
    A = RG[:, :-1] @ dR @ jnp.swapaxes(RG[:, 1:], -1, -2)
    c = jnp.einsum("nsab,nsb->nsa", RG[:, :-1], dp)
    c = c - jnp.einsum("nsab,nsb->nsa", A, pG[:, 1:])
    SA, Sc = _cumsum0(A), _cumsum0(c)
    dRG = SA @ RG
    dpG = jnp.einsum("nsab,nsb->nsa", SA, pG) + Sc
    return (RG, pG), (dRG, dpG)


def _cumsum0(x):
    """Prefix sums along axis 1 with a leading zero: ``(n, m) -> (n, m + 1)``."""
    return jnp.concatenate([jnp.zeros_like(x[:, :1]), jnp.cumsum(x, axis=1)], axis=1)


class ChainTerms(NamedTuple):
    """Per-chain quantities relative to each chain's first point (padded).

    ``RG, pG``: poses of the points relative to the first; ``Ginv``: their
    Ad^-1 (None for poses only: the backward wrench sweep uses R and p);
    ``relJ = Ad(G_a)^-1 sum_{b<a} Ad(G_b) T_b dOmega_b V``; with velocities
    ``rel_eta`` (the twist of point a relative to the first, in its own frame) and
    ``rel_etadot`` (its velocity-product rate), see :func:`chain_terms`.
    """

    RG: Array
    pG: Array
    Ginv: Array | None
    relJ: Array | None
    rel_eta: Array | None = None
    rel_etadot: Array | None = None


def _fixed_transforms(data: LinkageData):
    """``(R, p)`` of every link's placement, g_i and g_f: ``(3 n_links, ...)``."""
    G = jnp.stack([h for ld in data.links for h in (ld.placement, ld.g_i, ld.g_f)])
    return G[:, :3, :3], G[:, :3, 3]


def chain_terms(
    data: LinkageData, k: Steps, lay: ChainLayout, dOmegaV=None
) -> ChainTerms:
    """Poses, Jacobian and twist increments of every link's chain, all at once.

    Along a chain the pose is a prefix product and, in the frame of the chain's
    first point, the Jacobian recursion is a prefix sum,

        Ad(G_a) J_a = J_0 + sum_{b<a} Ad(G_b) T_b dOmega_b,

    so ``J_a = Ad(G_a)^-1 J_0 + relJ_a``. With velocities, ``y_b = T_b Omegadot_b``
    and ``d/dt Ad(G) x = Ad(G) (xdot + ad(G^-1 Gdot) x)`` give the twists
    ``eta_a = Ad(G_a)^-1 eta_0 + rel_eta_a`` and their velocity-product rates

        etadot_a = Ad(G_a)^-1 etadot_0 + rel_etadot_a + ad(Ad(G_a)^-1 eta_0) eta_a,
        rel_etadot_a = Ad(G_a)^-1 sum_{b<a} Ad(G_b) (ydot_b + ad(rel_eta_b) y_b),

    with ``ydot_b = Tdot_b Omegadot_b + T_b Omegaddot_b``. Nothing here depends on
    the chain's first point (the parent's tip), so every link is evaluated in one
    batch; :func:`_tree_pass` composes them along the tree. Constant transforms and
    padding are steps with zero dOmega (padding: identities).
    """
    n_links = len(data.links)
    dtype = k.R.dtype
    eye3, eye6 = jnp.eye(3, dtype=dtype), jnp.eye(6, dtype=dtype)
    Rf, pf = _fixed_transforms(data)
    R = _gather(jnp.concatenate([k.R, Rf]), lay.idx_Rp, eye3, 1)
    p = _gather(jnp.concatenate([k.p, pf]), lay.idx_Rp, 0.0, 1)
    # Poses only (statics, kinematics queries): one composition in a loop compiles
    # faster than the scan's levels (statics of a 30-DoF rod: 2.99 -> 2.62 s, warm
    # 11.8 -> 9.6 ms); the rates pass (dynamics) keeps the log-depth scan, which ran
    # 21% faster there.
    pose_only = dOmegaV is None and k.Od is None
    RG, pG = _prefix_poses(R, p, sequential=pose_only)
    if pose_only:
        return ChainTerms(RG, pG, None, None)
    Ginv = _Ad_inv(RG, pG)
    AdG = _Ad(RG[:, :-1], pG[:, :-1])
    extra = 3 * n_links + 1
    T = _gather(k.T, lay.idx_rate, eye6, extra)
    relJ = None
    if dOmegaV is not None:
        S = AdG @ T @ _gather(dOmegaV, lay.idx_rate, 0.0, extra)
        relJ = Ginv @ _cumsum0(S)
    if k.Od is None:
        return ChainTerms(RG, pG, Ginv, relJ)
    Od = _gather(k.Od, lay.idx_rate, 0.0, extra)
    y = jnp.einsum("nsab,nsb->nsa", T, Od)
    yd = _gather(k.Td_Od, lay.idx_rate, 0.0, extra)
    yd = yd + jnp.einsum("nsab,nsb->nsa", T, _gather(k.Odd, lay.idx_rate, 0.0, extra))
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


def link_base_poses(data: LinkageData, ct: ChainTerms, lay: ChainLayout) -> Array:
    """Pose of every link's chain start (its parent's tip): ``(n_links, 4, 4)``."""
    tips_rel = _pose(
        ct.RG[np.arange(len(data.links)), lay.tip_slot],
        ct.pG[np.arange(len(data.links)), lay.tip_slot],
    )
    eye = jnp.eye(4, dtype=tips_rel.dtype)
    bases, tips = [], []
    for i, ld in enumerate(data.links):
        base = eye if ld.parent == 0 else tips[ld.parent - 1]
        bases.append(base)
        tips.append(tips_rel[i] if ld.parent == 0 else base @ tips_rel[i])
    return jnp.stack(bases)


def poses(data: LinkageData, q: Float[Array, " n_dof"]) -> Float[Array, "n_points 4 4"]:
    """World poses of all significant points (no Jacobians traced)."""
    lay = chain_layout(data)
    ct = chain_terms(data, steps(data, q), lay)
    g = point_poses(ct, lay, link_base_poses(data, ct, lay))
    return with_leaves(lay, g, leaf_poses(lay, g, leaf_steps(data, q)))


def point_poses(ct: ChainTerms, lay: ChainLayout, bases) -> Array:
    """World poses of the chain's points from the links' base poses (``lay.core``)."""
    rel = _pose(
        ct.RG[lay.point_link, lay.point_slot], ct.pG[lay.point_link, lay.point_slot]
    )
    return bases[lay.point_link] @ rel


def to_step_end(R, p, x):
    """``Ad(E)^-1 x`` for twists ``x`` (angular first) and steps ``E = (R, p)``.

    That is ``(R^T w, R^T (v + w x p))``, batched over the leading axis.
    """
    w, v = x[..., :3], x[..., 3:]
    out = jnp.concatenate([w, v + jnp.cross(w, p)], axis=-1).reshape(-1, 2, 3)
    return jnp.einsum("lba,lkb->lka", R, out).reshape(x.shape)


def from_step_end(R, p, W):
    """``Ad(E)^-T W`` for wrenches ``W`` (moment first) at steps' ends ``E = (R, p)``.

    The same wrench at the step's start: ``(R m + p x R f, R f)``, batched over
    the leading axes.
    """
    Rw = jnp.einsum("...ab,...kb->...ka", R, W.reshape(W.shape[:-1] + (2, 3)))
    m, f = Rw[..., 0, :], Rw[..., 1, :]
    return jnp.concatenate([m + jnp.cross(p, f), f], axis=-1)


def to_step_end_wrench(R, p, W):
    """``Ad(E)^T W`` for wrenches ``W`` (moment first) and poses ``E = (R, p)``.

    A wrench given at a step's start, in the frame of its end:
    ``(R^T (m - p x f), R^T f)``; the inverse of :func:`from_step_end`. Batched
    over the leading axes.
    """
    m, f = W[..., :3], W[..., 3:]
    out = jnp.stack([m - jnp.cross(p, f), f], axis=-2)
    return jnp.einsum("...ba,...kb->...ka", R, out).reshape(W.shape)


def leaf_steps(data: LinkageData, q, qd=None, many: bool = True) -> Steps | None:
    """The leaves' own steps (None without leaves): see :func:`steps`."""
    if not data.leaf_points:
        return None
    return steps(data, q, qd, st=data.leaf_steps, many=many)


def leaf_poses(lay: ChainLayout, g_core, kl: Steps | None) -> Array | None:
    """World poses of the leaves: their chain point's pose times their step's."""
    if kl is None:
        return None
    return g_core[lay.leaf_row] @ _pose(kl.R, kl.p)


def with_leaves(lay: ChainLayout, core, leaves) -> Array:
    """Rows of the chain's points and of the leaves, in point order."""
    if leaves is None:
        return core
    return jnp.concatenate([core, leaves])[lay.order]


def leaf_sums(lay: ChainLayout, y) -> Array:
    """``(n_core, ...)``: the sum of the leaves' rows ``y`` at each one's chain point.

    Leaves of one chain point are consecutive, so each sum is a difference of two
    prefix sums (gathers only: a scatter-add is slow under ``vmap``).
    """
    c = jnp.concatenate([jnp.zeros_like(y[:1]), jnp.cumsum(y, axis=0)])
    return c[lay.leaf_stop] - c[lay.leaf_first]


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
    time (:func:`chain_terms`); only the elementwise step kernel is differentiated.

    Returns:
        ``(n_points, 4, 4)``, ``(n_points, 6, n_dof)``, ``(n_points, 6)``,
        ``(n_points, 6)``.
    """
    g, J, (eta, etadot) = _tree_pass(data, q, None, qd)
    return g, J, eta, etadot


def _tangent_apply(T, x):
    """``T x`` for tangent operators ``T`` and twists ``x``.

    ``T`` is block lower triangular (:func:`~sorojax.kinematics._step.exp_and_tangent`).
    """
    a, b = x[..., :3], x[..., 3:]
    Ts = T[..., :3, :3]
    top = jnp.einsum("lab,lb->la", Ts, a)
    bottom = jnp.einsum("lab,lb->la", T[..., 3:, :3], a) + jnp.einsum(
        "lab,lb->la", Ts, b
    )
    return jnp.concatenate([top, bottom], axis=-1)


def tangent_transpose_apply(T, y):
    """``T^T y`` for tangent operators ``T`` and wrenches ``y``.

    See :func:`_tangent_apply`.
    """
    m, f = y[..., :3], y[..., 3:]
    Ts = T[..., :3, :3]
    top = jnp.einsum("lba,lb->la", Ts, m) + jnp.einsum("lba,lb->la", T[..., 3:, :3], f)
    return jnp.concatenate([top, jnp.einsum("lba,lb->la", Ts, f)], axis=-1)


class PointRates(NamedTuple):
    """The dynamics' kinematics: Jacobians and rates at the chain's points only.

    ``g`` ``(n_points, 4, 4)`` and ``eta`` ``(n_points, 6)`` at every point; ``J``
    ``(n_core, 6, n_dof)`` and ``etadot`` ``(n_core, 6)`` at the chain's points
    (``chain_layout(data).core``: leaves carry no mass, and their wrenches reach the
    coordinates through their chain points, :func:`~sorojax.dynamics.
    _wrench_recursion.leaf_wrenches`); ``leaves``: the leaves' steps (a
    :class:`~sorojax.kinematics._leaves.LeafRecord` where those kernels apply),
    None when ``J`` and ``etadot`` have a row per point (no leaves;
    :func:`point_jacobians` gives every point's ``J``); ``records``: the chain's
    :class:`Steps` and :class:`ChainTerms` ``(k, ct)`` (for the mass matrix from
    composite inertias and the backward wrench sweep); ``leaf_frames``: the leaves'
    world frames and twists component by component (a
    :class:`~sorojax.kinematics._leaves.LeafFrames`, where the leaves' kernels apply);
    ``core``: ``(g, eta)`` at the chain's points only (with leaves; see
    :func:`point_rows`).
    """

    g: Array
    eta: Array
    J: Array
    etadot: Array
    leaves: Steps | None
    records: tuple | None = None
    leaf_frames: tuple | None = None
    core: tuple | None = None


def point_rows(data: LinkageData, pr: PointRates, idx: np.ndarray) -> tuple:
    """``(g[idx], eta[idx])`` for static point indices ``idx``.

    Read from the chain's own rows (``pr.core``) where every point of ``idx`` is
    one: then the poses and twists of every point, leaves included, need not be
    formed for them.
    """
    idx = np.asarray(idx, dtype=int)
    if pr.core is not None:
        row = chain_layout(data).row[idx]
        if np.all(row >= 0):
            return pr.core[0][row], pr.core[1][row]
    return pr.g[idx], pr.eta[idx]


def rows_of(data: LinkageData, pr: PointRates) -> np.ndarray:
    """Each point's row in ``pr.J`` and ``pr.etadot`` (-1: none, a leaf's)."""
    if pr.leaves is None:  # a row per point
        return np.arange(pr.g.shape[0])
    return chain_layout(data).row


def point_jacobians(data: LinkageData, pr: PointRates) -> Array:
    """Every point's Jacobian ``(n_points, 6, n_dof)``, leaves included.

    From :func:`point_rates`' (chain points only): a leaf's is its chain point's
    carried through its own step, ``J_l = Ad(G_l)^-1 (J_c + T_l dOmega_l)``, all
    leaves in one batch. For a caller that needs the leaves' Jacobians (the
    contacts' tangent in ROS34PW2's W) but not their rates.
    """
    if pr.leaves is None:
        return pr.J
    lay = chain_layout(data)
    kl = pr.leaves
    if isinstance(kl, _leaves.LeafRecord):  # many leaves: component by component
        J_l = _leaves.leaf_jacobians(data, kl, pr.J[lay.leaf_row])
        return with_leaves(lay, pr.J, J_l)
    rel = kl.T @ step_jacobians(data, kl, None, st=data.leaf_steps)
    return with_leaves(lay, pr.J, _Ad_inv(kl.R, kl.p) @ (pr.J[lay.leaf_row] + rel))


def point_rates(data: LinkageData, q, qd) -> PointRates:
    """:class:`PointRates` at ``(q, qd)``.

    :func:`kinematics_and_rates` without the leaves' Jacobians and rates: a leaf
    costs its step, its pose and its twist.
    """
    g, J, (eta, etadot), (k, ct, lay) = _tree_pass(data, q, None, qd, core_only=True)
    if _leaves.applies(data):  # many leaves: component by component
        g_l, eta_l, rec, frames = _leaves.leaf_rates(data, lay, q, qd, g, eta)
        return PointRates(
            with_leaves(lay, g, g_l),
            with_leaves(lay, eta, eta_l),
            J,
            etadot,
            rec,
            (k, ct),
            frames,
            (g, eta),
        )
    kl = leaf_steps(data, q, many=False)  # in dynamics: derivatives of one tangent
    if kl is None:
        return PointRates(g, eta, J, etadot, None, (k, ct))
    Od = step_rates(data.leaf_steps, kl, qd)
    eta_l = to_step_end(kl.R, kl.p, eta[lay.leaf_row] + _tangent_apply(kl.T, Od))
    g_all = with_leaves(lay, g, leaf_poses(lay, g, kl))
    eta_all = with_leaves(lay, eta, eta_l)
    return PointRates(g_all, eta_all, J, etadot, kl, (k, ct), None, (g, eta))


def rest_rates(data: LinkageData, q) -> PointRates:
    """:class:`PointRates` at rest (``qd = 0``): poses and the chain's Jacobians only.

    The twists and their rates are zeros, not computed: for the mass matrix and the
    loops' constraint rows at a configuration (the projection of a start's
    velocities), without the rates' columns.
    """
    g, J, _, (k, ct, lay) = _tree_pass(data, q, None, None, core_only=True)
    kl = leaf_steps(data, q)
    if kl is not None:
        g = with_leaves(lay, g, leaf_poses(lay, g, kl))
    z = jnp.zeros((g.shape[0], 6), q.dtype)
    return PointRates(g, z, J, z[: J.shape[0]], kl, (k, ct))


def _tree_pass(data: LinkageData, q, V, qd, core_only: bool = False):
    """Poses, Jacobians (times ``V``) and, when ``qd`` is given, twists and rates.

    One batch for every step (:func:`steps`) and every link's chain
    (:func:`chain_terms`); the loop over the static tree only carries the tips
    (one pose product and one 6 x 6 product per link), and every point is then
    composed with its link's base in one batch; then every leaf from its chain
    point, in one batch. When every link starts at the ground (a single rod, say)
    the bases are zero and a point's terms are its chain's own. Returns ``(g, J,
    rates)`` with ``rates = (eta, etadot)`` (None without ``qd``); ``core_only``:
    the chain's points only, and the records ``(k, ct, lay)`` as a fourth item.
    """
    dtype = q.dtype
    cols = data.n_dof if V is None else V.shape[1]
    lay = chain_layout(data)
    k = steps(data, q, qd)
    ct = chain_terms(data, k, lay, step_jacobians(data, k, V))
    rates = qd is not None
    g_pts = point_poses(ct, lay, link_base_poses(data, ct, lay))
    pl, ps = lay.point_link, lay.point_slot
    if all(ld.parent == 0 for ld in data.links):
        J = ct.relJ[pl, ps]
        eta = ct.rel_eta[pl, ps] if rates else None
        etadot = ct.rel_etadot[pl, ps] if rates else None
    else:
        J, eta, etadot = _tree_compose(data, ct, lay, cols, rates, dtype)
    if core_only:
        return g_pts, J, (eta, etadot), (k, ct, lay)
    kl = leaf_steps(data, q, qd)
    if kl is not None:
        # a leaf is one step from its chain point: the chain's formulas with a
        # chain of one step (chain_terms) and the chain point's [J | eta | etadot]
        Gi = _Ad_inv(kl.R, kl.p)
        st = data.leaf_steps
        rel = kl.T @ step_jacobians(data, kl, V, st=st)
        X = J[lay.leaf_row]
        if rates:
            y = jnp.einsum("lab,lb->la", kl.T, kl.Od)
            yd = kl.Td_Od + jnp.einsum("lab,lb->la", kl.T, kl.Odd)
            rel = jnp.concatenate([rel, y[..., None], yd[..., None]], axis=-1)
            X = jnp.concatenate(
                [X, eta[lay.leaf_row][..., None], etadot[lay.leaf_row][..., None]],
                axis=-1,
            )
        Xl = _compose(Gi, X, Gi @ rel, cols, rates)
        g_pts = with_leaves(lay, g_pts, leaf_poses(lay, g_pts, kl))
        J = with_leaves(lay, J, Xl[..., :cols])
        if rates:
            eta = with_leaves(lay, eta, Xl[..., cols])
            etadot = with_leaves(lay, etadot, Xl[..., cols + 1])
    return g_pts, J, (eta, etadot) if rates else None


def _tree_compose(
    data: LinkageData, ct: ChainTerms, lay: ChainLayout, cols, rates, dtype
):
    """``(J, eta, etadot)`` at the chain's points of a tree (see :func:`_tree_pass`).

    The loop over the links carries each link's tip ``[J | eta | etadot]`` to its
    children's start; every point is then composed with its link's start.
    """
    n_links = len(data.links)
    rows = np.arange(n_links)
    tip_Gi = ct.Ginv[rows, lay.tip_slot]
    tip_rel = ct.relJ[rows, lay.tip_slot]
    if rates:
        tip_rel = jnp.concatenate(
            [
                tip_rel,
                ct.rel_eta[rows, lay.tip_slot][..., None],
                ct.rel_etadot[rows, lay.tip_slot][..., None],
            ],
            axis=-1,
        )
    width = cols + (2 if rates else 0)
    zero = jnp.zeros((6, width), dtype=dtype)
    base_X, tips = [], []
    for i, ld in enumerate(data.links):
        if ld.parent == 0:
            X0, X = zero, tip_rel[i]
        else:
            X0 = tips[ld.parent - 1]
            X = _compose(tip_Gi[i], X0, tip_rel[i], cols, rates)
        base_X.append(X0)
        tips.append(X)
    pl, ps = lay.point_link, lay.point_slot
    rel = ct.relJ[pl, ps]
    if rates:
        rel = jnp.concatenate(
            [rel, ct.rel_eta[pl, ps][..., None], ct.rel_etadot[pl, ps][..., None]],
            axis=-1,
        )
    X = _compose(ct.Ginv[pl, ps], jnp.stack(base_X)[pl], rel, cols, rates)
    if not rates:
        return X, None, None
    return X[..., :cols], X[..., cols], X[..., cols + 1]


def _compose(Gi, X0, rel, cols: int, rates: bool):
    """``[J | eta | etadot]`` at points from their chain start's (batched or not).

    ``J = Gi J0 + relJ``, ``eta = Gi eta0 + rel_eta``, ``etadot = Gi etadot0 +
    rel_etadot + ad(Gi eta0) eta`` (see :func:`chain_terms`).
    """
    Y = Gi @ X0
    X = Y + rel
    if not rates:
        return X
    eta = X[..., cols]
    etadot = X[..., cols + 1] + _ad_apply(Y[..., cols], eta)
    return jnp.concatenate([X[..., : cols + 1], etadot[..., None]], axis=-1)


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
