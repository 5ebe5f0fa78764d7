"""Derived arrays of a linkage, computed once per solve from its primary parameters.

:func:`precompute` evaluates bases, reference strains and section matrices at every
significant point and Magnus node, the rigid inertias, and the constant K and D.
Solvers call it once, outside their iteration loops, and pass the result to the
kernels; because it is recomputed from the primary parameters on every call, a
changed parameter is never stale and ``jax.grad`` reaches E, radii, lengths and
masses.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._jit import traced_once
from ._basis import PaddedBasis
from ._layout import Layout
from ._link import RigidLink, SoftLink
from ._linkage import Linkage
from ._section import section_matrices

# Magnus nodes on a step, by the order of the step (DESIGN.md section 3): the 2-point
# Gauss-Legendre (Zanna) nodes of the 4th-order step and the 3-point nodes of the
# 6th-order one (:mod:`sorojax.kinematics._recursion`).
_NODES = {
    4: (0.5 - math.sqrt(3.0) / 6.0, 0.5 + math.sqrt(3.0) / 6.0),
    6: (0.5 - math.sqrt(15.0) / 10.0, 0.5, 0.5 + math.sqrt(15.0) / 10.0),
}
_C = math.sqrt(3.0) / 12.0  # 4th-order Magnus commutator weight: c = _C h^2
# Basis order from which a division's modes need the 6th-order step: the 4th-order
# step integrates a mode's Jacobian column with the 2-point Gauss rule (exact up to
# cubics), so from quartic modes on J^T W gains spurious components of order
# h^4 |d^4 Phi / dX^4| (the full circle under an end moment ended 3e-5 L from the
# exact tip at order 4, 3e-6 L at order 8: tests/test_magnus_accuracy.py).
HIGH_ORDER = 4
MIN_LEAVES = 32
"""The fewest leaves (4th-order steps) whose bases are also kept by their nonzero
entries (:class:`LeafBasis`), for the dynamics' kernels of many contact samples
(:mod:`sorojax.kinematics._leaves`). Below it the stacked kernels serve: they run
nearly as fast there (2-core CPU, 22 leaves: 41-48 against 38-43 us per evaluation)
and their programs compile about 0.5 s sooner (10-22 leaves)."""


def magnus_order(linkage: Linkage) -> int:
    """Order of the Magnus steps of ``linkage``: 4 or 6 (static).

    6 if any soft division's basis has order >= :data:`HIGH_ORDER`, else 4. One
    order per linkage keeps every step in one batch; the 4th-order step (2 nodes,
    one commutator) stays the cost of low-order models.
    """
    for link in linkage.links:
        if isinstance(link, SoftLink):
            for div in link.divisions:
                if div.basis.n_dof and div.basis.max_order >= HIGH_ORDER:
                    return 6
    return 4


class DivisionData(eqx.Module):
    """Per-division arrays (physical units; angular basis rows divided by length).

    Attributes:
        h: (n_steps,) step lengths between consecutive points [m].
        Phi_z: (n_steps, n_nodes, 6, n) basis at the Magnus nodes of each step (2
            Zanna points for 4th-order steps, 3 Gauss points for 6th-order ones).
        xi_ref_z: (n_steps, n_nodes, 6) reference strain at the Magnus nodes.
        Phi: (n_pts, 6, n) basis at the division's points.
        xi_ref: (n_pts, 6) reference strain at the points.
        Sigma: (n_pts, 6, 6) stiffness at the points.
        Upsilon: (n_pts, 6, 6) damping at the points.
        column_modes: each column's strain rows that may be nonzero (static, from
            the basis: :attr:`~sorojax.model.AbstractStrainBasis.column_modes`).
        locked: (n,) 1 at padded coordinates of a :class:`~sorojax.model.PaddedBasis`
            (their basis columns are zero), 0 elsewhere; None without padding.
        leaf_h, leaf_Phi_z, leaf_xi_ref_z: the leaves' own steps (from the chain
            point before each leaf to the leaf), as ``h``, ``Phi_z`` and
            ``xi_ref_z`` are the chain's; ``n_leaves`` rows (0 without leaves).
    """

    offset: int = eqx.field(static=True)
    n_dof: int = eqx.field(static=True)
    column_modes: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    h: Float[Array, " n_steps"]
    Phi_z: Float[Array, "n_steps n_nodes 6 n"]
    xi_ref_z: Float[Array, "n_steps n_nodes 6"]
    Phi: Float[Array, "n_pts 6 n"]
    xi_ref: Float[Array, "n_pts 6"]
    Sigma: Float[Array, "n_pts 6 6"]
    Upsilon: Float[Array, "n_pts 6 6"]
    locked: Float[Array, " n"] | None = None
    leaf_h: Float[Array, " n_leaves"] | None = None
    leaf_Phi_z: Float[Array, "n_leaves n_nodes 6 n"] | None = None
    leaf_xi_ref_z: Float[Array, "n_leaves n_nodes 6"] | None = None


class LinkData(eqx.Module):
    """Per-link arrays.

    Attributes:
        placement: pose of the link base in the parent's tip frame.
        joint_Phi: (6, n_j) joint basis.
        g_i: joint -> body start (rod start or CM).
        g_f: body end (rod end or CM) -> tip.
        divisions: per-division data (empty for a rigid link).
    """

    soft: bool = eqx.field(static=True)
    parent: int = eqx.field(static=True)
    joint_offset: int = eqx.field(static=True)
    placement: Float[Array, "4 4"]
    joint_Phi: Float[Array, "6 n_j"]
    g_i: Float[Array, "4 4"]
    g_f: Float[Array, "4 4"]
    divisions: tuple[DivisionData, ...]


class LeafBasis(eqx.Module):
    """The leaves' strain bases by their nonzero entries (many contact samples).

    A leaf's step lies in one division, whose columns are nonzero on few strain rows
    (a polynomial basis: one row each). Slot ``s`` holds, for every leaf, the entries
    on strain row ``row[s]`` at the step's nodes of one column of the leaf's
    division: column ``dof[s][k]`` of the linkage for the leaves of
    ``segments[k]`` (-1: none there, the entries are zero). Products with the bases
    then cost the nonzero entries only, where the full-width ``Phi_t`` has
    ``n_dof x 6`` entries per node.

    Attributes:
        values: ``(n_slots, n_nodes, n_leaves)`` the entries.
        row: the strain row of each slot (static).
        segments: ``((start, stop), ...)``: the leaves of each division that has
            leaves, contiguous in leaf order (static).
        dof: for each slot, its column in each segment (static).
    """

    values: Float[Array, "n_slots n_nodes n_leaves"]
    row: tuple[int, ...] = eqx.field(static=True)
    segments: tuple[tuple[int, int], ...] = eqx.field(static=True)
    dof: tuple[tuple[int, ...], ...] = eqx.field(static=True)

    def _coordinates(self, x, s: int):
        """Slot ``s``'s coordinate of ``x`` for every leaf: a scalar where it is one."""
        cols = self.dof[s]
        if len(set(cols)) == 1:
            return x[max(cols[0], 0)]
        idx = np.concatenate(
            [
                np.full(b - a, max(j, 0))
                for (a, b), j in zip(self.segments, cols, strict=True)
            ]
        )
        return x[idx][None]  # against the (n_nodes, n_leaves) entries

    def strains(self, x, xi_ref=None):
        """Rows ``(n_nodes, 6, n_leaves)``: the strains at the nodes for ``x``.

        ``xi_ref``: the reference strains to add (None: the rates, for ``x = qd``).
        """
        nz, n = self.values.shape[1:]
        per_row = [None] * 6
        for s, r in enumerate(self.row):
            term = self.values[s] * self._coordinates(x, s)
            per_row[r] = term if per_row[r] is None else per_row[r] + term
        zero = jnp.zeros((nz, n), self.values.dtype)
        rows = [zero if t is None else t for t in per_row]
        if xi_ref is not None:  # row by row: one kernel with the stack
            rows = [t + xi_ref[:, r] for r, t in enumerate(rows)]
        return jnp.stack(rows, axis=1)

    def columns(self, n_dof: int):
        """The bases' columns at each node, ``(n_nodes, 6, n_dof, n_leaves)``.

        Built from the entries (zero where a column has none); faster to form than
        to read the full-width ``Phi_t`` transposed.
        """
        nz, n = self.values.shape[1:]
        zero = jnp.zeros((n_dof, n), self.values.dtype)
        P = [[zero] * 6 for _ in range(nz)]
        for s, r in enumerate(self.row):
            for z in range(nz):
                col = zero
                for (a, b), j in zip(self.segments, self.dof[s], strict=True):
                    if j >= 0:
                        col = col.at[j, a:b].set(self.values[s, z, a:b])
                P[z][r] = P[z][r] + col
        return jnp.stack([jnp.stack(rows) for rows in P])

    def transpose(self, Z, n_dof: int):
        """``sum Phi^T Z`` over the leaves' nodes for covectors ``Z``.

        ``Z``: one ``(6, n)`` array per node (rows over the leaves).
        """
        if not self.row:
            return jnp.zeros(n_dof, Z[0].dtype)
        P = jnp.stack(
            [
                sum(self.values[s, z] * Zz[r] for z, Zz in enumerate(Z))
                for s, r in enumerate(self.row)
            ]
        )
        n = Z[0].shape[-1]
        if len(self.segments) == 1:
            S = jnp.sum(P, axis=1, keepdims=True)
        else:  # sums over each division's leaves: a product with their indicators
            ind = np.zeros((n, len(self.segments)))
            for k, (a, b) in enumerate(self.segments):
                ind[a:b, k] = 1.0
            S = P @ ind
        # each coordinate's slots (one for a polynomial basis), gathered: no scatter
        flat = [[] for _ in range(n_dof)]
        for s, cols in enumerate(self.dof):
            for k, j in enumerate(cols):
                if j >= 0:
                    flat[j].append(s * len(self.segments) + k)
        width = max(1, max(len(f) for f in flat))
        pad = S.size  # the appended zero
        idx = np.array([f + [pad] * (width - len(f)) for f in flat]).T
        S = jnp.concatenate([S.reshape(-1), jnp.zeros(1, S.dtype)])
        return jnp.sum(S[idx], axis=0)


def _leaf_basis(divisions) -> LeafBasis:
    """:class:`LeafBasis` of the divisions that have leaves (4th-order steps)."""
    segments, start = [], 0
    per_div = []  # per division: its columns on each strain row
    for dd in divisions:
        m = dd.leaf_h.shape[0]
        segments.append((start, start + m))
        start += m
        modes = dd.column_modes
        per_div.append([[j for j, on in enumerate(modes) if r in on] for r in range(6)])
    values, row, dof = [], [], []
    for r in range(6):
        for k in range(max(len(cols[r]) for cols in per_div)):
            blocks, cols_k = [], []
            for dd, cols in zip(divisions, per_div, strict=True):
                m = dd.leaf_h.shape[0]
                if k < len(cols[r]):
                    blocks.append(dd.leaf_Phi_z[:, :, r, cols[r][k]].T)
                    cols_k.append(dd.offset + cols[r][k])
                else:
                    blocks.append(jnp.zeros((dd.leaf_Phi_z.shape[1], m)))
                    cols_k.append(-1)
            values.append(jnp.concatenate(blocks, axis=1))
            row.append(r)
            dof.append(tuple(cols_k))
    nz = divisions[0].leaf_Phi_z.shape[1]
    return LeafBasis(
        values=jnp.stack(values) if values else jnp.zeros((0, nz, start)),
        row=tuple(row),
        segments=tuple(segments),
        dof=tuple(dof),
    )


class GroupBasis(eqx.Module):
    """The chain steps' bases on their own group's columns (several groups).

    A step acts through the coordinates of one group (a joint's, or a division's),
    so its basis is ``(n_nodes, 6, width)`` on those columns where the full-width
    ``Phi_z`` has ``n_dof``: products with the bases cost O(steps x width) instead
    of O(steps x n_dof), which is O(n_dof^2) for a rod of many divisions.

    Attributes:
        values: ``(n_steps, n_nodes, 6, width)`` the bases (zero past a group's
            width).
        cols: ``(n_steps, width)`` each entry's column (``n_dof``: padding), static.
        segments: ``((first, stop), ...)`` each group's steps (contiguous), static:
            the groups of the composite mass matrix too
            (:mod:`sorojax.dynamics._composite`).
        src: ``(n_dof,)`` each column's entry in the flat ``(n_groups x width)``
            group sums and the mass matrix's rows of blocks (``n_groups x width``:
            none), static.
    """

    values: Float[Array, "n_steps n_nodes 6 width"]
    cols: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    segments: tuple[tuple[int, int], ...] = eqx.field(static=True)
    src: tuple[int, ...] = eqx.field(static=True)

    def coordinates(self, x):
        """``(n_steps, width)``: each step's group's entries of ``x`` (zero padded)."""
        return jnp.concatenate([x, jnp.zeros(1, x.dtype)])[np.array(self.cols)]

    def strains(self, x):
        """``(n_steps, n_nodes, 6)``: the bases times ``x`` (no reference strain)."""
        return jnp.einsum("szak,sk->sza", self.values, self.coordinates(x))

    def transpose(self, Z):
        """``sum_s Phi[s]^T Z[s]`` for node covectors ``Z`` ``(n_steps, n_nodes, 6)``.

        Each step's covector on its group's columns, summed over the group's steps
        (a difference of prefix sums) and gathered into the coordinates: no scatter.
        """
        y = jnp.einsum("szak,sza->sk", self.values, Z)
        c = jnp.concatenate([jnp.zeros_like(y[:1]), jnp.cumsum(y, axis=0)])
        first, stop = (np.array(x, int) for x in zip(*self.segments, strict=True))
        flat = (c[stop] - c[first]).reshape(-1)
        return jnp.concatenate([flat, jnp.zeros(1, y.dtype)])[np.array(self.src)]


MIN_GROUPS = 2
"""Fewest coordinate groups (joints with coordinates, divisions with steps) for
which the chain's steps keep :class:`GroupBasis` and the dynamics forms the mass
matrix from composite inertias (:mod:`sorojax.dynamics._composite`); with one
group the full-width products cost the same."""

MIN_GROUP_DOF = 24
"""Fewest coordinates for :class:`GroupBasis`, which also needs the widest group to
hold at most half of them. One evaluation of a free rod of order-3 divisions (11
coordinates each) on a floor, 2-core CPU: 17 coordinates (2 groups) 61-64 against
54-57 us the Jacobians' way, 28: 107-112 against 126-131, 61: 319-327 against
552-573, 116: 686-760 against 2387; the crawler's 6 coordinates and their forward
derivatives ran 10-20 % slower."""


def _group_basis(links: list, n: int, nz: int) -> GroupBasis | None:
    """:class:`GroupBasis` of the chain's steps, in :func:`_step_data`'s order.

    None below :data:`MIN_GROUPS` groups or :data:`MIN_GROUP_DOF` coordinates, or
    where one group holds more than half of the coordinates.
    """
    parts = []  # (bases (m, nz, 6, k), first column)
    for ld in links:
        jn = ld.joint_Phi.shape[1]
        if jn:
            parts.append(
                (jnp.broadcast_to(ld.joint_Phi, (1, nz, 6, jn)), ld.joint_offset)
            )
        for dd in ld.divisions if ld.soft else ():
            if dd.h.shape[0]:
                parts.append((dd.Phi_z, dd.offset))
    width = max((P.shape[3] for P, _ in parts), default=0)
    if (
        sum(P.shape[3] > 0 for P, _ in parts) < MIN_GROUPS
        or n < MIN_GROUP_DOF
        or 2 * width > n
    ):
        return None
    values, cols, segments, src, start = [], [], [], np.full(n, -1), 0
    for g, (P, o) in enumerate(parts):
        m, k = P.shape[0], P.shape[3]
        values.append(jnp.pad(P, ((0, 0), (0, 0), (0, 0), (0, width - k))))
        cols.append(
            np.broadcast_to(
                np.where(np.arange(width) < k, o + np.arange(width), n), (m, width)
            )
        )
        segments.append((start, start + m))
        src[o : o + k] = g * width + np.arange(k)
        start += m
    src[src < 0] = len(parts) * width
    return GroupBasis(
        values=jnp.concatenate(values),
        cols=tuple(map(tuple, np.concatenate(cols).tolist())),
        segments=tuple(segments),
        src=tuple(src.tolist()),
    )


class StepData(eqx.Module):
    """Every Magnus step of the linkage in one batch, full column width.

    In link order: a link's joint (if it has coordinates: one step with ``h = 1``,
    ``c = 0`` and every node's basis the joint basis, so that ``Omega = Phi_j q_j``
    exactly, at either order), then the steps of its divisions. Batching them keeps
    the traced program's size independent of the number of divisions and joints.

    The chain's steps store the bases step first (``Phi_z``, ``xi_ref_z``); the
    leaves' (:mod:`sorojax.kinematics._leaves`, many contact samples) store them
    with the step axis last (``Phi_t``, ``xi_ref_t``); :meth:`strains`,
    :meth:`basis` and :meth:`basis_transpose` read either.

    Attributes:
        order: Magnus order of every step, 4 (2 Zanna nodes) or 6 (3 Gauss nodes),
            see :func:`magnus_order`.
        h: (n_steps,) step lengths [m] (1 for joints).
        c: (n_steps,) 4th-order commutator weights ``sqrt(3) h^2 / 12`` (0 for
            joints; unused by 6th-order steps).
        Phi_z: (n_steps, n_nodes, 6, n_dof) bases at the Magnus nodes, zero outside
            the step's own columns (None for leaves).
        xi_ref_z: (n_steps, n_nodes, 6) reference strains at the Magnus nodes (None
            for leaves).
        Phi_t: the same bases as an ``(n_dof, n_nodes * 6 * n_steps)`` matrix
            (leaves only, else None).
        xi_ref_t: (n_nodes, 6, n_steps) the reference strains (leaves only).
        compact: the leaves' bases by their nonzero entries (4th-order leaves only,
            else None): :class:`LeafBasis`.
        group: the chain steps' bases on their groups' columns (at least
            :data:`MIN_GROUPS` groups and :data:`MIN_GROUP_DOF` coordinates, else
            None): :class:`GroupBasis`.
    """

    order: int = eqx.field(static=True)
    h: Float[Array, " n_steps"]
    c: Float[Array, " n_steps"]
    Phi_z: Float[Array, "n_steps n_nodes 6 n_dof"] | None = None
    xi_ref_z: Float[Array, "n_steps n_nodes 6"] | None = None
    Phi_t: Float[Array, "n_dof n_basis"] | None = None
    xi_ref_t: Float[Array, "n_nodes 6 n_steps"] | None = None
    compact: LeafBasis | None = None
    group: GroupBasis | None = None

    def strains(self, x, ref: bool = True):
        """Strains ``(n_steps, n_nodes, 6)`` at the nodes for coordinates ``x``.

        ``ref``: with the reference strains (``False``: the rates for ``x = qd``).
        """
        if self.group is not None:
            xi = self.group.strains(x)
            return xi + self.xi_ref_z if ref else xi
        if self.Phi_z is not None:
            xi = jnp.einsum("szan,n->sza", self.Phi_z, x)
            return xi + self.xi_ref_z if ref else xi
        xi = (x @ self.Phi_t).reshape(self.xi_ref_t.shape)
        return jnp.transpose(xi + self.xi_ref_t if ref else xi, (2, 0, 1))

    def basis(self, V=None):
        """``Phi_z`` ``(n_steps, n_nodes, 6, n_dof)``, or ``Phi_z V`` (k columns)."""
        if self.Phi_z is not None:
            return (
                self.Phi_z if V is None else jnp.einsum("szan,nk->szak", self.Phi_z, V)
            )
        P = self.Phi_t if V is None else V.T @ self.Phi_t
        P = P.reshape((P.shape[0],) + self.xi_ref_t.shape)
        return jnp.transpose(P, (3, 1, 2, 0))

    def basis_transpose(self, Z):
        """``sum_s Phi_z[s]^T Z[s]`` for node covectors ``Z`` (n_steps, n_nodes, 6)."""
        if self.group is not None:
            return self.group.transpose(Z)
        if self.Phi_z is not None:
            return jnp.einsum("szan,sza->n", self.Phi_z, Z)
        return self.Phi_t @ jnp.transpose(Z, (1, 2, 0)).reshape(-1)


def _step_data(links: list, n: int, order: int, leaves: bool = False) -> StepData:
    """The chain's steps (joints and divisions), or with ``leaves`` the leaves'."""
    nz = len(_NODES[order])
    h, c, Phi_z, xr, with_leaves = [], [], [], [], []
    for ld in links:
        jo, jn = ld.joint_offset, ld.joint_Phi.shape[1]
        if jn and not leaves:
            P = jnp.zeros((6, n)).at[:, jo : jo + jn].set(ld.joint_Phi)
            h.append(jnp.ones(1))
            c.append(jnp.zeros(1))
            Phi_z.append(jnp.stack([P] * nz)[None])
            xr.append(jnp.zeros((1, nz, 6)))
        for dd in ld.divisions if ld.soft else ():
            if leaves:
                dh, dP, dx = dd.leaf_h, dd.leaf_Phi_z, dd.leaf_xi_ref_z
            else:
                dh, dP, dx = dd.h, dd.Phi_z, dd.xi_ref_z
            m, o = dh.shape[0], dd.offset
            if not m:
                continue
            h.append(dh)
            c.append(_C * dh * dh)
            if leaves:  # the step axis last (StepData.Phi_t)
                with_leaves.append(dd)
                dP = jnp.transpose(dP, (3, 1, 2, 0))
                Phi_z.append(jnp.zeros((n, nz, 6, m)).at[o : o + dd.n_dof].set(dP))
                xr.append(jnp.transpose(dx, (1, 2, 0)))
            else:
                Phi_z.append(jnp.zeros((m, nz, 6, n)).at[..., o : o + dd.n_dof].set(dP))
                xr.append(dx)
    if not h:
        return StepData(
            order=order,
            h=jnp.zeros(0),
            c=jnp.zeros(0),
            Phi_z=jnp.zeros((0, nz, 6, n)),
            xi_ref_z=jnp.zeros((0, nz, 6)),
        )
    if leaves:
        return StepData(
            order=order,
            h=jnp.concatenate(h),
            c=jnp.concatenate(c),
            Phi_t=jnp.concatenate(Phi_z, axis=-1).reshape(n, -1),
            xi_ref_t=jnp.concatenate(xr, axis=-1),
            compact=(
                _leaf_basis(with_leaves)
                if order == 4
                and sum(d.leaf_h.shape[0] for d in with_leaves) >= MIN_LEAVES
                else None
            ),
        )
    return StepData(
        order=order,
        h=jnp.concatenate(h),
        c=jnp.concatenate(c),
        Phi_z=jnp.concatenate(Phi_z),
        xi_ref_z=jnp.concatenate(xr),
        group=_group_basis(links, n, nz),
    )


class LinkageData(eqx.Module):
    """Everything the kernels need, derived from a :class:`Linkage`.

    Attributes:
        n_dof: number of coordinates.
        links: per-link data.
        point_weight: (n_points,) quadrature weight [m] at soft rod points, 1 at rigid
            centres of mass, 0 elsewhere.
        point_M: (n_points, 6, 6) inertia density (rod points) or inertia (CM).
        mass_points: indices of the points that carry mass (positive quadrature
            weight or a rigid centre of mass), static: the mass matrix sums over
            these only (contact samples and load points carry none).
        K: (n_dof, n_dof) generalised stiffness.
        D: (n_dof, n_dof) generalised damping.
        gravity: (3,) gravitational acceleration.
        steps: every Magnus step of the chain (joints and divisions) in one batch.
        leaf_steps: the leaves' own steps (see :mod:`sorojax.model._layout`), in
            the order of ``leaf_points``.
        leaf_points: point index of every leaf, static.
        leaf_parents: point index of the chain point each leaf hangs from, static.
        locked: (n_dof,) 1 at the padding coordinates of size-class models
            (:func:`~sorojax.size_class`), 0 elsewhere; None (static) when no
            division is padded. ``K`` holds them at zero with the mean diagonal
            stiffness of the other coordinates, the mass matrix gives them their
            mean diagonal inertia (:func:`lock_padding`).
    """

    n_dof: int = eqx.field(static=True)
    links: tuple[LinkData, ...]
    steps: StepData
    point_weight: Float[Array, " n_points"]
    point_M: Float[Array, "n_points 6 6"]
    K: Float[Array, "n_dof n_dof"]
    D: Float[Array, "n_dof n_dof"]
    gravity: Float[Array, "3"]
    locked: Float[Array, " n_dof"] | None = None
    mass_points: tuple[int, ...] = eqx.field(static=True, default=())
    leaf_steps: StepData | None = None
    leaf_points: tuple[int, ...] = eqx.field(static=True, default=())
    leaf_parents: tuple[int, ...] = eqx.field(static=True, default=())


def lock_padding(A: Array, locked: Array | None) -> Array:
    """``A`` (K or M) with the mean of its own diagonal at the padded coordinates.

    ``A`` is returned unchanged without padding (``locked`` None).

    The padded rows and columns of K and M are zero (their basis columns are), so
    the padded coordinates are decoupled; this gives each a stiffness and an inertia
    whose ratio lies within the model's own range (a diagonal-weighted mean of
    ``K_ii / M_ii``), so that they neither stiffen the dynamics nor add a slow mode,
    and they stay exactly at rest at zero under every load.
    """
    if locked is None:
        return A
    free = 1.0 - locked
    mean = jnp.sum(jnp.diag(A) * free) / jnp.maximum(jnp.sum(free), 1.0)
    # 1 where the others have none (e.g. only free joints): never a zero pivot
    return A + jnp.diag(locked * jnp.where(mean > 0, mean, 1.0))


def _scale_rows(L) -> Array:
    """Row scaling making q dimensionless: angular rows / L, linear rows * 1."""
    one = jnp.ones_like(L)
    return jnp.stack([one / L] * 3 + [one] * 3)


def _precompute(linkage: Linkage) -> LinkageData:
    """:func:`precompute`'s body (traced once per linkage structure)."""
    lay: Layout = linkage.layout
    n = lay.n_dof
    n_pts = lay.n_points
    order = magnus_order(linkage)
    nodes = _NODES[order]
    nz = len(nodes)
    K = jnp.zeros((n, n))
    D = jnp.zeros((n, n))
    weight = np.zeros(n_pts)
    w_dyn = [None] * n_pts  # traced weights (depend on lengths)
    M_pts: list = [None] * n_pts
    carries = np.zeros(n_pts, dtype=bool)  # the point has a positive mass weight
    links = []
    leaf_points: list[int] = []
    leaf_parents: list[int] = []
    padded: list = []  # (offset, locked) of padded divisions
    for i, (link, ll) in enumerate(zip(linkage.links, lay.links, strict=True)):
        j = link.joint
        jo, jn = ll.joint_offset, ll.joint_n_dof
        if jn:
            K = K.at[jo : jo + jn, jo : jo + jn].add(j.stiffness)
            D = D.at[jo : jo + jn, jo : jo + jn].add(j.damping)
        divs = []
        if isinstance(link, SoftLink):
            mat = link.material
            G = mat.G
            for div, dl in zip(link.divisions, ll.divisions, strict=True):
                L = div.length
                padded_div = isinstance(div.basis, PaddedBasis)
                if padded_div:
                    # a size class's empty division (length 0, every column off)
                    # scales by 1 instead of 1/0 (its basis is zero: 0 * inf = nan)
                    S = _scale_rows(jnp.where(L > 0, L, 1.0))[None, :, None]
                else:
                    S = _scale_rows(L)[None, :, None]
                X1 = dl.X1
                chain = np.flatnonzero(~dl.leaf)  # the chain's points
                Xc = X1[chain]
                # each leaf's step starts at the chain point before it
                leaf = np.flatnonzero(dl.leaf)
                start = Xc[np.searchsorted(chain, leaf) - 1]
                for k, parent in zip(
                    leaf, chain[np.searchsorted(chain, leaf) - 1], strict=True
                ):
                    leaf_points.append(dl.first_point + int(k))
                    leaf_parents.append(dl.first_point + int(parent))
                a = np.concatenate([Xc[:-1], start])
                b = np.concatenate([Xc[1:], X1[leaf]])
                Xz = np.stack([a + (b - a) * z for z in nodes], 1)
                n_steps = len(Xc) - 1
                Xall = jnp.asarray(np.concatenate([X1, Xz.reshape(-1)]))
                Phi_all = S * jax.vmap(div.basis)(Xall)
                xr_all = jax.vmap(div.reference_strain)(Xall)
                Phi, Phi_z = Phi_all[: len(X1)], Phi_all[len(X1) :]
                Phi_z = Phi_z.reshape(len(a), nz, 6, dl.n_dof)
                xr = xr_all[: len(X1)]
                xr_z = xr_all[len(X1) :].reshape(len(a), nz, 6)
                Sigma, Ms, Ups = jax.vmap(
                    lambda x, sec=div.section, m=mat, G=G: section_matrices(
                        sec, x, m.E, G, m.rho, m.eta, m.poisson
                    )
                )(jnp.asarray(X1))
                wL = jnp.asarray(dl.w) * L
                o, nd = dl.offset, dl.n_dof
                locked = 1.0 - div.basis.active if padded_div else None
                if padded_div:
                    padded.append((o, locked))
                if nd:
                    Kd = jnp.einsum("p,pai,pab,pbj->ij", wL, Phi, Sigma, Phi)
                    Dd = jnp.einsum("p,pai,pab,pbj->ij", wL, Phi, Ups, Phi)
                    K = K.at[o : o + nd, o : o + nd].add(Kd)
                    D = D.at[o : o + nd, o : o + nd].add(Dd)
                for k in range(len(X1)):
                    w_dyn[dl.first_point + k] = wL[k]
                    carries[dl.first_point + k] = bool(dl.w[k] > 0)
                    M_pts[dl.first_point + k] = Ms[k]
                divs.append(
                    DivisionData(
                        offset=dl.offset,
                        n_dof=dl.n_dof,
                        column_modes=div.basis.column_modes,
                        h=jnp.asarray(np.diff(Xc)) * L,
                        Phi_z=Phi_z[:n_steps],
                        xi_ref_z=xr_z[:n_steps],
                        Phi=Phi,
                        xi_ref=xr,
                        Sigma=Sigma,
                        Upsilon=Ups,
                        locked=locked,
                        leaf_h=jnp.asarray(X1[leaf] - start) * L,
                        leaf_Phi_z=Phi_z[n_steps:],
                        leaf_xi_ref_z=xr_z[n_steps:],
                    )
                )
        else:
            assert isinstance(link, RigidLink)
            weight[ll.cm_point] = 1.0
            carries[ll.cm_point] = True
            M_pts[ll.cm_point] = link.spatial_inertia()
        links.append(
            LinkData(
                soft=ll.soft,
                parent=ll.parent,
                joint_offset=jo,
                placement=linkage.placements[i],
                joint_Phi=j.basis(),
                g_i=link.g_i,
                g_f=link.g_f,
                divisions=tuple(divs),
            )
        )
    locked = None
    if padded:
        locked = jnp.zeros(n)
        for o, lk in padded:
            locked = locked.at[o : o + lk.shape[0]].set(lk)
        K = lock_padding(K, locked)
    zero6 = jnp.zeros((6, 6))
    point_M = jnp.stack([zero6 if m is None else m for m in M_pts])
    point_weight = jnp.stack(
        [jnp.asarray(weight[p]) if w_dyn[p] is None else w_dyn[p] for p in range(n_pts)]
    )
    return LinkageData(
        n_dof=n,
        links=tuple(links),
        steps=_step_data(links, n, order),
        point_weight=point_weight,
        point_M=point_M,
        K=K,
        D=D,
        gravity=linkage.gravity,
        locked=locked,
        mass_points=tuple(int(p) for p in np.flatnonzero(carries)),
        leaf_steps=_step_data(links, n, order, leaves=True) if leaf_points else None,
        leaf_points=tuple(leaf_points),
        leaf_parents=tuple(leaf_parents),
    )


@traced_once
def precompute(linkage: Linkage) -> LinkageData:
    """Evaluate all derived arrays of ``linkage`` (see the module docstring).

    Traced once per linkage structure (:func:`sorojax._jit.traced_once`): inside a
    trace its equations go into the calling program as if traced there, and every
    later program of the same model (statics, dynamics, kinematics queries) reuses
    that jaxpr: ~80 ms of tracing per program for the manual's 17-DoF hybrid, ~8 ms
    from the cache. Called outside any trace it is one compiled program.
    """
    return _precompute(linkage)
