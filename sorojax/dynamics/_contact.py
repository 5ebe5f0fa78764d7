"""Contact forces as body wrenches at the significant points, and their report.

The contact law, obstacles and shapes are described in :mod:`sorojax.model._contact`.
Each contact gives a force ``f`` (world frame) at a point ``x_c`` on the robot's
surface; the body-frame wrench ``(a x f_b, f_b)`` with ``a`` the arm from the sample's
centre-line point (so that friction exerts a moment) is added at that significant
point and mapped to the coordinates with the other loads, by ``J^T`` or the backward
wrench recursion. A rod-rod contact at the closest points of two segments is split
between each segment's end points with the linear weights of its closest point
(statically equivalent; the velocity of the contact point is interpolated with the
same weights, so the map is power-consistent and damping and friction only dissipate).

Everything is a pure function of the poses (and twists): ``jax.grad`` flows through
it; the force law is continuously differentiable, so Newton's tangent and the
gradients are continuous (they jump in their second derivative at touch-down).
"""

import functools
import math
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float

from .._jit import jit
from .._results import RESULTS
from ..kinematics._api import _as_q
from ..kinematics._leaves import _add, _cross, _dot, _mat_vec
from ..model._contact import (
    Contact,
    Plane,
    _safe_norm,
    contact_links,
    pair_capacity,
    soft_radius,
)
from ..model._linkage import Linkage
from ..model._precompute import precompute


# ------------------------------------------------------------------ sample tables
class Samples(NamedTuple):
    """Contact samples: spheres at (or rigidly offset from) significant points."""

    point: np.ndarray  # (n,) significant point index (static)
    link: np.ndarray  # (n,) 1-based link number (static)
    weight: Array  # (n,) length the sample stands for [m] (rods), 1 (rigid points)
    radius: Array  # (n,) [m]
    offset: Array  # (n, 3) centre in the point's body frame [m]


class Segments(NamedTuple):
    """Segments joining consecutive samples of one soft link (static indices)."""

    start: np.ndarray  # (m,) index into the link's samples
    end: np.ndarray  # (m,)
    arc: np.ndarray  # (m,) arc length of the midpoint [m] (NaN if traced)


def _division_samples(linkage: Linkage, contact: Contact, link_number: int):
    """Per-division sample points of a soft link: (points, weights, radii, X1s)."""
    layout = linkage.layout.links[link_number - 1]
    link = linkage.links[link_number - 1]
    cells = dict(contact.cells)[link_number]
    out = []
    for div, dl, n in zip(link.divisions, layout.divisions, cells, strict=True):
        X1 = np.arange(n + 1) / n
        idx = np.asarray(
            [dl.first_point + int(np.argmin(np.abs(dl.X1 - x))) for x in X1]
        )
        w = np.full(n + 1, 1.0 / n)
        w[0] = w[-1] = 0.5 / n
        weight = div.length * jnp.asarray(w)
        radius = jnp.stack(
            [soft_radius(contact, link_number, div, float(x)) for x in X1]
        )
        out.append((idx, weight, radius.astype(weight.dtype), X1))
    return out


def link_samples(linkage: Linkage, link_number: int) -> Samples:
    """A link's contact samples: a soft link's centre-line samples, a rigid shape's."""
    lay = linkage.layout.links[link_number - 1]
    if lay.soft:
        return rod_samples(linkage, link_number)[0]
    o, r = linkage.contact.shape_of(link_number).points()
    n = o.shape[0]
    return Samples(
        np.full(n, lay.cm_point), np.full(n, link_number), jnp.ones(n, o.dtype), r, o
    )


def obstacle_samples(linkage: Linkage) -> Samples:
    """The samples checked against the obstacles, link by link."""
    contact = linkage.contact
    assert contact is not None
    parts = [link_samples(linkage, i) for i in contact_links(contact, linkage.links)]
    if not parts:
        z = jnp.zeros((0,))
        return Samples(np.zeros(0, int), np.zeros(0, int), z, z, jnp.zeros((0, 3)))
    return Samples(
        np.concatenate([p.point for p in parts]),
        np.concatenate([p.link for p in parts]),
        jnp.concatenate([p.weight for p in parts]),
        jnp.concatenate([p.radius for p in parts]),
        jnp.concatenate([p.offset for p in parts]),
    )


def rod_samples(linkage: Linkage, link_number: int) -> tuple[Samples, Segments]:
    """A soft link's samples and the segments between consecutive ones."""
    contact = linkage.contact
    assert contact is not None
    parts = _division_samples(linkage, contact, link_number)
    link = linkage.links[link_number - 1]
    starts, ends, arcs = [], [], []
    base, s0 = 0, 0.0
    for (idx, _, _, X1), div in zip(parts, link.divisions, strict=True):
        m = len(idx) - 1
        starts.append(base + np.arange(m))
        ends.append(base + np.arange(1, m + 1))
        try:
            L = float(div.length)
        except (TypeError, jax.errors.ConcretizationTypeError):
            L = math.nan
        mid = 0.5 * (X1[:-1] + X1[1:])
        arcs.append(s0 + L * mid)
        s0 += L
        base += len(idx)
    samples = Samples(
        np.concatenate([p[0] for p in parts]),
        np.full(base, link_number),
        jnp.concatenate([p[1] for p in parts]),
        jnp.concatenate([p[2] for p in parts]),
        jnp.zeros((base, 3)),
    )
    return samples, Segments(
        np.concatenate(starts), np.concatenate(ends), np.concatenate(arcs)
    )


# -------------------------------------------------------------------- the report
class ContactState(eqx.Module):
    """Every candidate contact of a configuration (inactive ones have zero force).

    Rows: first each obstacle against each sample (obstacle by obstacle, samples in
    link order), then each rod-rod or self-contact segment pair.

    Attributes:
        point: (n, 3) contact point on the robot's surface (link A's for pairs)
            [m, world].
        normal: (n, 3) unit normal pointing into the robot (into link A) [world].
        penetration: (n,) overlap [m] (negative: the gap).
        normal_force: (n,) elastic plus damping normal force [N] (weighted: per
            sample, the law per length times the sample's length).
        force: (n, 3) total contact force on the robot (on link A) [N, world].
        slip: (n, 3) tangential velocity of the robot's surface relative to the
            obstacle (to link B) [m/s, world].
        link_number: link number of each row (link A for pairs); static.
        obstacle_index: obstacle index of each row (0-based), -1 for rod-rod
            pairs; static.
        energy: elastic contact energy [J].
        overflow: whether more segment pairs could touch than the broad phase
            holds (``Contact.pair_capacity``): then some contacts are missing.
    """

    point: Float[Array, "n 3"]
    normal: Float[Array, "n 3"]
    penetration: Float[Array, " n"]
    normal_force: Float[Array, " n"]
    force: Float[Array, "n 3"]
    slip: Float[Array, "n 3"]
    link_number: tuple[int, ...] = eqx.field(static=True)
    obstacle_index: tuple[int, ...] = eqx.field(static=True)
    energy: Float[Array, ""]
    overflow: Bool[Array, ""]

    @property
    def link(self) -> np.ndarray:
        """(n,) link number of each row (link A for pairs)."""
        return np.asarray(self.link_number, dtype=int)

    @property
    def obstacle(self) -> np.ndarray:
        """(n,) obstacle index of each row (0-based), -1 for rod-rod pairs."""
        return np.asarray(self.obstacle_index, dtype=int)

    @property
    def active(self) -> Array:
        """(n,) True where the law acts: overlap, or a barrier's force across a gap."""
        return (self.penetration > 0) | (self.normal_force != 0)

    def total_force(self) -> Array:
        """(3,) resultant contact force on the robot [N, world] (pairs cancel)."""
        return jnp.sum(jnp.where((self.obstacle >= 0)[:, None], self.force, 0.0), 0)


# ------------------------------------------------------------------------- kernels
# 3 x 3 products of many small vectors as products and sums, not einsums: XLA
# fuses them with the elementwise work around them, where each einsum would be a
# matrix-product kernel of its own.
def _rotate(R, v):
    """``R v`` for 3 x 3 matrices ``R`` (..., 3, 3) and vectors ``v`` (..., 3)."""
    return (
        R[..., 0] * v[..., 0, None]
        + R[..., 1] * v[..., 1, None]
        + R[..., 2] * v[..., 2, None]
    )


def _rotate_back(R, v):
    """``R^T v`` for 3 x 3 matrices ``R`` (..., 3, 3) and vectors ``v`` (..., 3)."""
    return (
        R[..., 0, :] * v[..., 0, None]
        + R[..., 1, :] * v[..., 1, None]
        + R[..., 2, :] * v[..., 2, None]
    )


def _law_forces(
    law, d, n, v_rel, weight, friction: bool, axis=None, comp=-1, keep=False
):
    """Force on the robot (world) from penetration, normal and relative velocity.

    ``axis``: (n, 3) body axes of anisotropic friction (``law.forward_friction``).
    ``comp``: the vectors' component axis: -1 for ``(n, 3)`` stacks, 0 for ``(3,
    n)`` rows (:func:`_obstacle_rows`). ``keep`` (isotropic friction): the
    weighted normal force and friction's viscous coefficient are stored
    (:func:`_stored`) and the force formed from them, rather than the law computed
    again for each of the force's components.
    """

    def dot(a, b):
        return jnp.sum(a * b, axis=comp)

    def times(c, v):  # scalars (n,) times vectors
        return jnp.expand_dims(c, comp) * v

    vn = dot(v_rel, n)
    vt = v_rel - times(vn, n)
    f_el = law.normal_force(d)
    fn = f_el - law.damping * law.ramp(d) * vn
    cf = jnp.zeros_like(fn)  # friction's viscous coefficient
    if friction:
        speed2 = dot(vt, vt)
        speed = jnp.sqrt(speed2 + law.stick_speed_squared(f_el))
        mu = law.friction_coefficient(jnp.sqrt(speed2 + 1e-30))
        cf = mu * f_el / speed
    if keep:
        assert axis is None, "keep: isotropic friction only"
        S = _stored(jnp.stack([weight * fn, weight * cf]), d)
        return times(S[0], n) - times(S[1], vt), S[0], vt
    f = times(fn, n)
    if friction:
        resist = times(cf, vt)
        if law.forward_friction is not None and axis is not None:
            # the slip along the body axis (in the tangent plane) meets mu_f forward
            e = axis - times(dot(axis, n), n)
            e = e / jnp.expand_dims(jnp.maximum(_safe_norm(e, axis=comp), 1e-12), comp)
            v_ax = dot(vt, e)
            w = 0.5 * (1.0 + jnp.tanh(v_ax / law.stick_velocity))
            mu_ax = w * law.forward_friction + (1.0 - w) * mu
            resist = resist + times((mu_ax - mu) * f_el * v_ax / speed, e)
        f = f - resist
    return times(weight, f), weight * fn, vt


def _point_wrenches(R, p, x_c, f):
    """Body wrenches at points (R, p) of forces ``f`` at ``x_c`` (world)."""
    a_b = _rotate_back(R, x_c - p)
    f_b = _rotate_back(R, f)
    return jnp.concatenate([jnp.cross(a_b, f_b), f_b], axis=-1)


def _world_points(g, eta, samples: Samples):
    """Sample centres, their rotation, angular and linear velocities (world)."""
    R = g[samples.point, :3, :3]
    p = g[samples.point, :3, 3]
    x = p + _rotate(R, samples.offset)
    if eta is None:
        z = jnp.zeros_like(x)
        return R, p, x, z, z
    w_b = eta[samples.point, :3]
    v_b = eta[samples.point, 3:] + jnp.cross(w_b, samples.offset)
    return R, p, x, _rotate(R, w_b), _rotate(R, v_b)


def _against_obstacle(ob, t, x, w, v, radius):
    """``(n, d, x_c, v_rel)`` of spheres against obstacle ``ob`` at time ``t``.

    The spheres: centres ``x``, spins ``w``, velocities ``v`` (world). ``n``: unit
    normal out of the obstacle; ``d``: penetration; ``x_c``: the spheres' surface
    points towards it; ``v_rel``: their velocity relative to the obstacle there.
    """
    G, Gd = ob.frame(t)
    RG, pG = G[:3, :3], G[:3, 3]
    RG, pG, Gd = RG[None], pG[None], Gd[None]  # one frame for every sphere
    xl = _rotate_back(RG, x - pG)
    phi, grad = jax.vmap(jax.value_and_grad(ob.distance))(xl)
    n = _rotate(RG, grad)
    n = n / jnp.maximum(_safe_norm(n), 1e-12)[:, None]
    x_c = x - radius[:, None] * n
    v_obs = _rotate(Gd[:, :3, :3], _rotate_back(RG, x_c - pG)) + Gd[:, :3, 3]
    return n, radius - phi, x_c, v + jnp.cross(w, x_c - x) - v_obs


def _obstacle_terms(contact: Contact, samples: Samples, g, eta, t, friction: bool):
    """Per obstacle: loads (see :func:`_contact`) and report rows of every sample."""
    R, p, x, w, v = _world_points(g, eta, samples)
    loads, rows = [], []
    for k, ob in enumerate(contact.obstacles):
        law = contact.obstacle_law(k)
        n, d, x_c, v_rel = _against_obstacle(ob, t, x, w, v, samples.radius)
        f, fn, vt = _law_forces(
            law, d, n, v_rel, samples.weight, friction, axis=R[:, :, 0]
        )
        loads.append((samples.point, x_c, f))
        energy = jnp.sum(samples.weight * law.potential(d))
        rows.append((x_c, n, d, fn, f, vt, energy))
    return loads, rows


def _obstacle_rows(contact: Contact, samples: Samples, frames, t, chain):
    """The obstacles' wrenches ``(6, n)`` on samples, component by component.

    ``frames``: the samples' positions and velocities, in the world and in the
    frames of their chain points, where their wrenches are given
    (:class:`~sorojax.kinematics._leaves.LeafFrames`); ``chain``: ``(g_c, row)``,
    the chain points' poses ``(n_core, 4, 4)`` and each sample's chain point
    (static). The contact of :func:`_obstacle_terms` (friction included) and
    :func:`_point_wrenches` with every quantity a row
    over the samples (each kernel a loop over them, :mod:`sorojax.kinematics.
    _leaves`). A static plane meets each sample in its chain point's frame (its
    normal and height turned into each chain point's frame, then read by its
    samples; the wrench ``((p - r n) x f, f)`` about the frame's origin is then the
    row): no sample's world frame, position, velocity or wrench is formed for
    it. Any other obstacle meets them in the world, one gradient of its distance
    per sample: its forces ``f`` at the contact points ``x_c`` are summed in the
    world as the wrench ``((x_c - o) x f, f)`` about the chain point ``o``, then
    turned into its frame.
    """
    R, o = frames.R, frames.o
    r = samples.radius[None]
    sums = {True: None, False: None}  # (m, f) in the chain points' frames, world
    for k, ob in enumerate(contact.obstacles):
        G, Gd = ob.frame(t)
        RG, pG = G[:3, :3], G[:3, 3:]
        plane = isinstance(ob, Plane)
        local = plane and ob.motion is None
        if plane:  # one normal for every sample: no per-sample gradient
            n_w = RG @ ob.normal
            n_w = n_w / jnp.maximum(_safe_norm(n_w), 1e-12)
            height = -jnp.dot(ob.point, ob.normal)  # phi = n_w . (x - pG) + height
        if local:
            x, w, v = frames.p, frames.w_c, frames.v_c
            g_c, row = chain
            Rc, oc = g_c[:, :3, :3], g_c[:, :3, 3]
            n_c = [sum(Rc[:, j, i] * n_w[j] for j in range(3)) for i in range(3)]
            h_c = height + sum((oc[:, j] - pG[j, 0]) * n_w[j] for j in range(3))
            n_h = jnp.stack(n_c + [h_c])[:, row]
            n = n_h[:3]
            phi = jnp.sum(x * n, axis=0) + n_h[3]
        elif plane:
            x, w, v = frames.x, frames.w, frames.v
            n = n_w[:, None]
            phi = jnp.sum((x - pG) * n, axis=0) + height
        else:
            x, w, v = frames.x, frames.w, frames.v
            xl = jnp.stack(_mat_vec(RG, x - pG, transpose=True))
            phi, grad = jax.vmap(
                jax.value_and_grad(ob.distance), in_axes=1, out_axes=(0, 1)
            )(xl)
            n = jnp.stack(_mat_vec(RG, grad))
            n = n / jnp.maximum(_safe_norm(n, axis=0), 1e-12)[None]
        x_c = x - r * n
        v_rel = v + jnp.stack(_cross(w, x_c - x))
        if ob.motion is not None:  # the obstacle's own velocity at x_c
            xo = jnp.stack(_mat_vec(RG, x_c - pG, transpose=True))
            v_rel = v_rel - (jnp.stack(_mat_vec(Gd[:3, :3], xo)) + Gd[:3, 3:])
        f, _, _ = _law_forces(
            contact.obstacle_law(k),
            r[0] - phi,
            n,
            v_rel,
            samples.weight,
            True,
            axis=frames.axis_c if local else frames.axis,
            comp=0,
        )
        m = jnp.stack(_cross(x_c if local else x_c - o, f))
        old = sums[local]
        sums[local] = (m, f) if old is None else (old[0] + m, old[1] + f)
    rows = [jnp.concatenate(sums[True])] if sums[True] is not None else []
    if sums[False] is not None:
        m_w, f_w = sums[False]
        rows.append(jnp.stack(_mat_vec(R, m_w, True) + _mat_vec(R, f_w, True)))
    return sum(rows[1:], rows[0])


def segment_closest(p0, p1, q0, q1):
    """Parameters (s, u) in [0, 1] of the closest points of segments p0p1 and q0q1.

    ``p0, p1, q0, q1``: ``(..., 3)`` points.
    """
    rows = ([x[..., i] for i in range(3)] for x in (p0, p1, q0, q1))
    return _segment_closest(*rows)[:2]


def _segment_closest(p0, p1, q0, q1):
    """``(s, u, s_line, u_line, parallel)``: closest points of segments and lines.

    The points' components are lists of three rows (any shape, one entry per
    segment pair). ``s_line``, ``u_line`` are the lines' (unclamped) parameters;
    the segments' own when the segments are parallel. The divisions by ``a``,
    ``e`` and the determinant are products by their reciprocals, stored (each is
    read by several rows, a kernel of its own otherwise).
    """
    d1 = [y - x for x, y in zip(p0, p1, strict=True)]
    d2 = [y - x for x, y in zip(q0, q1, strict=True)]
    r = [x - y for x, y in zip(p0, q0, strict=True)]

    a, e, b, c, f = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2), _dot(d1, r), _dot(d2, r)
    den = a * e - b * b
    parallel = den <= 1e-12 * a * e
    inv = _stored(
        1.0
        / jnp.stack([
            jnp.where(a > 0, a, 1.0),
            jnp.where(e > 0, e, 1.0),
            jnp.where(parallel, 1.0, den),
        ]),
        den,
    )  # fmt: skip
    inv_a, inv_e, inv_den = inv[0], inv[1], inv[2]
    s_line = jnp.where(parallel, 0.0, (b * f - c * e) * inv_den)
    u_line = (b * s_line + f) * inv_e
    s = jnp.where(a > 0, jnp.clip(s_line, 0.0, 1.0), 0.0)
    u = (b * s + f) * inv_e
    s = jnp.where(
        u < 0,
        jnp.clip(-c * inv_a, 0.0, 1.0),
        jnp.where(u > 1, jnp.clip((b - c) * inv_a, 0.0, 1.0), s),
    )
    u = jnp.clip(u, 0.0, 1.0)
    s = jnp.where(a > 0, s, 0.0)
    u = jnp.where(e > 0, u, 0.0)
    s_line = jnp.where(parallel, s, s_line)
    u_line = jnp.where(parallel, (b * s + f) * inv_e, u_line)
    return s, u, s_line, u_line, parallel


PAIR_RAMP = 0.25  # half-width of the shares' ramps at shared vertices [segment]


def _vertex_share(x, first, last):
    """Share of a segment pair's contact along one rod (x: the line parameter).

    1 inside the segment, ramping smoothly to 1/2 at a vertex shared with the next
    segment (and to 0 a ramp's width beyond it), so that two straight neighbours' shares
    add up to 1 and a crossing at a vertex is counted once; no ramp at the rod's
    two ends.
    """

    def smoothstep(y):  # 0 below -PAIR_RAMP, 1 above, h(y) + h(-y) = 1, C1
        z = jnp.clip(0.5 + y / (2 * PAIR_RAMP), 0.0, 1.0)
        return z * z * (3.0 - 2.0 * z)

    lo = jnp.where(first, 1.0, smoothstep(x))
    hi = jnp.where(last, 1.0, smoothstep(1.0 - x))
    return lo * hi


def _pair_list(linkage: Linkage):
    """Static list of (link A, link B, index pairs) for rod pairs and self-contact."""
    contact = linkage.contact
    out = []
    soft = [lay.soft for lay in linkage.layout.links]
    for a, b in contact.rod_pairs:
        if not (soft[a - 1] and soft[b - 1]):
            continue  # a rigid shape against a rod: _sphere_rod_terms
        sa, ga = rod_samples(linkage, a)
        sb, gb = rod_samples(linkage, b)
        ia, ib = np.meshgrid(
            np.arange(len(ga.start)), np.arange(len(gb.start)), indexing="ij"
        )
        out.append((sa, ga, sb, gb, ia.ravel(), ib.ravel()))
    for a in contact.self_contact:
        sa, ga = rod_samples(linkage, a)
        m = len(ga.start)
        ia, ib = np.triu_indices(m, k=1)
        r_max = (
            float(np.max(np.asarray(jax.lax.stop_gradient(sa.radius))))
            if not isinstance(sa.radius, jax.core.Tracer)
            else math.nan
        )
        if math.isfinite(r_max) and np.all(np.isfinite(ga.arc)):
            keep = np.abs(ga.arc[ia] - ga.arc[ib]) > 2.5 * 2 * r_max
        else:
            keep = (ib - ia) > 2
        out.append((sa, ga, sa, ga, ia[keep], ib[keep]))
    return out


def pair_link_b(linkage: Linkage) -> np.ndarray:
    """Link B of every pair row of :class:`ContactState` (rod pairs, then tubes)."""
    out = [
        np.full(_capacity(linkage.contact, e), e[2].link[0])
        for e in _pair_list(linkage)
    ]
    for rod, body, _ in sphere_rod_pairs(linkage):
        n_body = len(link_samples(linkage, body).point)
        n_seg = len(rod_samples(linkage, rod)[1].start)
        out.append(np.full(n_body * n_seg, rod))
    return np.concatenate(out) if out else np.zeros(0, int)


def _join_indices(parts):
    """Index arrays joined: static (NumPy) where every part is, else traced."""
    if all(isinstance(p, np.ndarray) for p in parts):
        return np.concatenate(parts)
    return jnp.concatenate([jnp.asarray(p) for p in parts])


def _add_rows(W, points, values):
    """``W.at[points].add(values)``: a gather where ``points`` are static, distinct.

    XLA's CPU backend runs a scatter as a loop over its rows (a thousand contact
    samples: a thousand iterations in every evaluation); when each point receives one
    value (samples against one obstacle) the sum is a gather of the values, each
    point's own or a zero row. Repeated or traced points take the scatter (for a few
    dozen loads it measured faster than a gather per repetition).
    """
    if not isinstance(points, np.ndarray) or len(np.unique(points)) < len(points):
        return W.at[points].add(values)
    src = np.full(W.shape[0], len(points))
    src[points] = np.arange(len(points))
    return W + jnp.concatenate([values, jnp.zeros_like(values[:1])])[src]


def _take(static, idx):
    """``static[idx]``: a static table at static or traced indices."""
    return static[idx] if isinstance(idx, np.ndarray) else jnp.asarray(static)[idx]


def _capacity(contact: Contact, entry) -> int:
    """The narrow phase's rows of one :func:`_pair_list` entry (static)."""
    sa, ga, sb, gb, ia, _ = entry
    n_seg = len(ga.start) + (0 if sa is sb else len(gb.start))
    return pair_capacity(contact, len(ia), n_seg)


def _first_true(c, k: int):
    """``idx``: indices of a mask's first ``k`` True entries, from its prefix sum ``c``.

    Indices past the count ``c[-1]`` are 0: ``jnp.nonzero(mask, size=k,
    fill_value=0)`` without its scatter. The m-th True entry is where the running
    count first reaches m, a binary search of the ``k`` counts in the prefix sum
    (XLA's CPU backend runs a scatter as a loop over its rows).
    """
    idx = jnp.searchsorted(c, jnp.arange(1, k + 1, dtype=c.dtype))
    return jnp.where(idx < c.shape[0], idx, 0)


def _broad_phase(contact: Contact, g, entry):
    """``(table, c)``: one :func:`_pair_list` entry's segment pairs and broad phase.

    ``table``: the rows ``(ia, ib, a0, a1, b0, b1)`` of every segment pair, its
    segments on A and B and their ends' samples (static). ``c``: the prefix sum of
    the pairs whose bounding spheres overlap (each segment's: centre at its
    midpoint, radius half its length plus its larger end radius, grown by the law's
    reach, ``smoothing`` or a barrier's gap); None where the capacity holds every
    pair (no broad phase). A pair left out has spheres apart, so its segments are
    further apart than their radii and the reach: no force.
    """
    sa, ga, sb, gb, ia, ib = entry
    table = np.stack([ia, ib, ga.start[ia], ga.end[ia], gb.start[ib], gb.end[ib]])
    if _capacity(contact, entry) >= len(ia):
        return table, None
    gs = jax.lax.stop_gradient(g)

    def spheres(smp, seg):
        x = gs[smp.point, :3, 3]  # rod samples lie on the centre line
        r = jax.lax.stop_gradient(smp.radius)
        x0, x1 = x[seg.start], x[seg.end]
        half = 0.5 * _safe_norm(x1 - x0)
        return 0.5 * (x0 + x1), half + jnp.maximum(r[seg.start], r[seg.end])

    cA, RA = spheres(sa, ga)
    cB, RB = (cA, RA) if sa is sb else spheres(sb, gb)
    reach = jnp.maximum(jax.lax.stop_gradient(contact.law.smoothing), 0.0)
    # squared distances, one coordinate row at a time: elementwise over the pairs
    # (XLA's CPU backend forms a norm over the short last axis of the (pairs, 3)
    # differences in a kernel many times slower)
    # (the spheres stored first: read by every pair, their norms would be computed
    # again for each)
    A = _stored(jnp.concatenate([cA.T, RA[None]]), cA)
    B = A if sa is sb else _stored(jnp.concatenate([cB.T, RB[None]]), cB)
    d2 = sum((A[i][ia] - B[i][ib]) ** 2 for i in range(3))
    near = ~(d2 >= (A[3][ia] + B[3][ib] + reach) ** 2)  # NaN: cannot be ruled out
    return table, jnp.cumsum(near.astype(int))


def _pick(table, c, k: int):
    """``(pairs, valid)``: the first ``k`` candidates of :func:`_broad_phase`.

    Gathered in their order into ``k`` rows (:func:`_first_true`: a binary search
    of the prefix sum, no sort); ``valid`` marks the rows that hold one (the others
    repeat pair 0 and carry no force). All pairs (static, ``valid`` None) where
    there is no broad phase (``c`` None).
    """
    if c is None:
        return tuple(table), None
    idx = _first_true(c, k)
    return tuple(jnp.asarray(table)[:, idx]), jnp.arange(k) < c[-1]


def _candidates(contact: Contact, g, entry):
    """``(pairs, valid, overflow)``: the segment pairs the narrow phase examines.

    The broad phase's (:func:`_broad_phase`) first candidates in the capacity's
    rows (:func:`_pick`); more candidates than rows is an ``overflow``.
    """
    table, c = _broad_phase(contact, g, entry)
    k = _capacity(contact, entry)
    pairs, valid = _pick(table, c, k)
    return pairs, valid, _overflow(c, k)


def _overflow(c, k: int):
    """Whether the broad phase's prefix sum ``c`` holds more candidates than ``k``.

    False without a broad phase (``c`` None: every pair examined).
    """
    return jnp.zeros((), bool) if c is None else c[-1] > k


def _small_capacity(contact: Contact, entry) -> int | None:
    """Rows of the narrow phase's smaller pass (static; None: one pass).

    :func:`_pair_terms` examines the candidates in a quarter of the capacity's
    rows when they fit there (a heap at rest uses a fraction of the capacity, which
    is sized for denser contact), and in all of them otherwise.
    """
    ia = entry[4]
    k = _capacity(contact, entry)
    small = k // SMALL_PASS_FRACTION
    return small if k < len(ia) and small >= SMALL_PASS_MIN else None


SMALL_PASS_FRACTION = 4  # the smaller pass: this fraction of the capacity's rows
SMALL_PASS_MIN = 32  # ... where it holds at least this many


def _segment_velocity(x, w, v, i0, i1, c, lam):
    """Velocity of points ``c`` carried by segments ``i0 -> i1``.

    Weighted ``1 - lam`` and ``lam`` (as their forces are split), from the samples'
    positions ``x``, spins ``w`` and velocities ``v``.
    """
    v0 = v[i0] + jnp.cross(w[i0], c - x[i0])
    v1 = v[i1] + jnp.cross(w[i1], c - x[i1])
    return (1 - lam)[:, None] * v0 + lam[:, None] * v1


class _PairGeometry(NamedTuple):
    """One rod pair's segment pairs: closest points, normals, gaps, velocities.

    Vectors are rows ``(3, k)`` over the segment pairs (:func:`_pair_rows`) or
    stacks ``(k, 3)`` (:func:`_pair_geometry`).
    """

    a0: np.ndarray  # sample indices of the segments' ends on rod A
    a1: np.ndarray
    b0: np.ndarray  # ... and on rod B
    b1: np.ndarray
    s: Array  # closest points' parameters along A's and B's segments
    u: Array
    share: Array  # the vertex shares' weight of each segment pair
    n: Array  # unit normal, from B to A
    d: Array  # penetration (positive in contact)
    cA: Array  # contact points on A's and B's surfaces
    cB: Array
    v_rel: Array  # A's surface velocity relative to B's at the contact
    ends: tuple  # rows: the four ends' sample centres (A's two, then B's)


def _sample_rows(g, eta, smp: Samples):
    """A rod's sample centres, spins, velocities (world), radii: rows ``(10, n)``.

    Stored (:func:`_stored`): every segment pair reads them.
    """
    _, _, x, w, v = _world_points(g, eta, smp)
    rows = jnp.concatenate([x.T, w.T, v.T, smp.radius[None].astype(x.dtype)])
    return _stored(rows, rows)


def _pair_rows(g, eta, sa, ga, sb, gb, pairs, valid=None) -> _PairGeometry:
    """Segment pairs of two rods (or one, for self-contact), as rows.

    ``pairs``: :func:`_candidates`' rows.

    Every quantity is a row over the segment pairs (structure of arrays: each kernel
    a loop along them, not over ``(k, 3)`` stacks whose minor axis is three long).
    ``valid``: False at the broad phase's empty rows (no share, a gap of twice the
    radii: no force). Rod samples lie on the centre line (no offset).
    """
    A = _sample_rows(g, eta, sa)
    B = A if sa is sb else _sample_rows(g, eta, sb)
    ia, ib, a0, a1, b0, b1 = pairs
    XA0, XA1, XB0, XB1 = A[:, a0], A[:, a1], B[:, b0], B[:, b1]
    pa0, pa1, pb0, pb1 = (list(X[:3]) for X in (XA0, XA1, XB0, XB1))
    s, u, s_line, u_line, parallel = _segment_closest(pa0, pa1, pb0, pb1)
    share_b = _vertex_share(u_line, ib == 0, ib == len(gb.start) - 1)
    share = _vertex_share(s_line, ia == 0, ia == len(ga.start) - 1) * share_b
    # parallel segments take their start vertex: every vertex once
    share = jnp.where(parallel, share_b, share)
    PA = [x0 + s * (x1 - x0) for x0, x1 in zip(pa0, pa1, strict=True)]
    PB = [x0 + u * (x1 - x0) for x0, x1 in zip(pb0, pb1, strict=True)]
    rA = (1 - s) * XA0[9] + s * XA1[9]
    rB = (1 - u) * XB0[9] + u * XB1[9]
    dvec = jnp.stack([x - y for x, y in zip(PA, PB, strict=True)])
    dist = _safe_norm(dvec, axis=0)
    n = dvec / jnp.maximum(dist, 1e-12)[None]
    d = rA + rB - dist
    if valid is not None:
        share = jnp.where(valid, share, 0.0)
        d = jnp.where(valid, d, -(rA + rB))
    cA = jnp.stack(PA) - rA[None] * n
    cB = jnp.stack(PB) + rB[None] * n

    def velocity(X0, X1, c, lam):  # of points c carried by segments (as split)
        v0 = _add(list(X0[6:9]), _cross(list(X0[3:6]), list(c - X0[:3])))
        v1 = _add(list(X1[6:9]), _cross(list(X1[3:6]), list(c - X1[:3])))
        return jnp.stack([(1 - lam) * x + lam * y for x, y in zip(v0, v1, strict=True)])

    v_rel = velocity(XA0, XA1, cA, s) - velocity(XB0, XB1, cB, u)
    ends = (XA0[:3], XA1[:3], XB0[:3], XB1[:3])
    return _PairGeometry(a0, a1, b0, b1, s, u, share, n, d, cA, cB, v_rel, ends)


def _pair_geometry(g, eta, sa, ga, sb, gb, pairs, valid=None) -> _PairGeometry:
    """:func:`_pair_rows` with its vectors as ``(k, 3)`` stacks."""
    k = _pair_rows(g, eta, sa, ga, sb, gb, pairs, valid)
    return k._replace(n=k.n.T, cA=k.cA.T, cB=k.cB.T, v_rel=k.v_rel.T, ends=())


def _stored(x, key):
    """``x``, computed once and stored (a conditional whose branches both return it).

    XLA's CPU fusion copies elementwise producers into every kernel that reads
    them: the segments' bounding spheres were computed again for each of seven
    thousand pairs, the rod pairs' law for each component of their force (the
    pile's evaluation on one thread 400 us with both stored, ~420 us with the
    law's terms computed in each reader). A conditional's operands are stored; its
    predicate (whether ``key``, a value known at run time only, is NaN; a constant
    one would be folded away) picks between ``x`` and ``x + 0``, equal values.
    ``key``: an array, its first entry read (0 where it is empty).
    """
    first = jnp.sum(jnp.ravel(key)[:1])
    return jax.lax.cond(jnp.isnan(first), lambda y: y, lambda y: y + 0.0, x)


def _pair_terms(contact: Contact, pairs, g, eta, friction: bool):
    """Rod-rod contacts: (wrenches, report rows, overflow).

    ``wrenches``: ``(points, W)``, body wrenches ``W`` at the rods' samples'
    points (static, distinct within each entry). Each rod pair's narrow phase
    works on its broad phase's candidates (:func:`_broad_phase`), on rows
    (:func:`_pair_narrow`). Where the candidates fit in a quarter of the capacity
    (:func:`_small_capacity`), a conditional takes a narrow phase on that many
    rows; its report rows are padded to the capacity's with copies of an empty row
    (the rows the full pass leaves empty), so both give the same forces and report.
    """
    wrenches, rows = [], []
    overflow = jnp.zeros((), bool)
    for entry in pairs:
        sa, ga, sb, gb, _, _ = entry
        table, c = _broad_phase(contact, g, entry)
        K = _capacity(contact, entry)
        small = _small_capacity(contact, entry)
        args = (contact, entry, table, c, g, eta, friction, K)
        if small is None:
            sums, row = _pair_pass(*args, K)
        else:
            sums, row = jax.lax.cond(
                c[-1] < small,
                functools.partial(_pair_pass, *args, small),
                functools.partial(_pair_pass, *args, K),
            )
        overflow = overflow | _overflow(c, K)
        for smp, S in zip((sa,) if sa is sb else (sa, sb), sums, strict=True):
            R = g[smp.point, :3, :3]
            wrenches.append(
                (smp.point, jnp.concatenate(
                    [_rotate_back(R, S[:, :3]), _rotate_back(R, S[:, 3:])], axis=-1
                ))
            )  # fmt: skip
        rows.append((*row, np.full(K, sa.link[0])))
    return wrenches, rows, overflow


def _pair_pass(contact, entry, table, c, g, eta, friction, K: int, k: int):
    """:func:`_pair_narrow` on the first ``k`` candidates, its rows padded to ``K``.

    The padding repeats row ``k - 1``, empty where ``k < K`` is taken (fewer than
    ``k`` candidates): the rows the full pass leaves empty.
    """
    pick = _pick(table, c, k)
    sums, row = _pair_narrow(contact, entry, pick, g, eta, friction)
    if k < K:
        row = tuple(
            jnp.concatenate([r, jnp.broadcast_to(r[-1:], (K - k, *r.shape[1:]))])
            if r.ndim
            else r
            for r in row
        )
    return sums, row


def _pair_narrow(contact: Contact, entry, pick, g, eta, friction: bool):
    """One rod pair's narrow phase on the rows ``pick = (pairs, valid)``.

    Returns ``(sums, row)``: ``sums``, world wrenches (moment, force) summed at each
    rod's samples (one ``(n, 6)`` array per rod: one for self-contact), and the
    report's row ``(cA, n, d, fn, f, vt, energy)``. Each pair's force is split to
    its segments' four ends (weighted by the closest points' parameters) as a
    force and its moment about the end's sample.
    """
    law = contact.law
    sa, ga, sb, gb, _, _ = entry
    k = _pair_rows(g, eta, sa, ga, sb, gb, *pick)
    f, fn, vt = _law_forces(
        law,
        k.d,
        k.n,
        k.v_rel,
        k.share,
        friction and contact.friction_in_rod_pairs,
        comp=0,
        keep=True,
    )
    ends = []  # (sample, world moment about it and force): (k, 6)
    for idx, c_, lam, x in zip(
        (k.a0, k.a1, k.b0, k.b1),
        (k.cA, k.cA, k.cB, k.cB),
        (1 - k.s, k.s, -(1 - k.u), -k.u),
        k.ends,
        strict=True,
    ):
        F = lam[None] * f
        mf = _cross(list(c_ - x), list(F)) + list(F)
        ends.append((idx, jnp.stack(mf, axis=1)))  # not a transpose of rows
    parts = [(sa, ends)] if sa is sb else [(sa, ends[:2]), (sb, ends[2:])]
    sums = []
    for smp, e in parts:
        idx = _join_indices([i for i, _ in e])
        val = jnp.concatenate([v for _, v in e])
        sums.append(jnp.zeros((len(smp.point), 6), val.dtype).at[idx].add(val))
    energy = jnp.sum(k.share * law.potential(k.d))
    return tuple(sums), (k.cA.T, k.n.T, k.d, fn, f.T, vt.T, energy)


def _bore_radii(linkage: Linkage, tube: int) -> Array:
    """Inner radius at each of a tube's samples (its divisions' annular sections)."""
    contact = linkage.contact
    link = linkage.links[tube - 1]
    cells = dict(contact.cells)[tube]
    out = []
    for div, n in zip(link.divisions, cells, strict=True):
        X1 = np.arange(n + 1) / n
        out.append(jnp.stack([div.section.inner_radius(float(x)) for x in X1]))
    return jnp.concatenate(out)


def sphere_rod_pairs(linkage: Linkage) -> tuple[tuple[int, int, bool], ...]:
    """``(rod, body, inside)``: bodies in soft tubes, then rigid shapes against rods."""
    contact = linkage.contact
    out = [(tube, body, True) for tube, body in contact.inside]
    for a, b in contact.rod_pairs:
        if not linkage.layout.links[a - 1].soft:
            out.append((b, a, False))
        elif not linkage.layout.links[b - 1].soft:
            out.append((a, b, False))
    return tuple(out)


class _SphereRod(NamedTuple):
    """Geometry of a body's spheres against a rod's segments (one row a pair)."""

    st: Samples  # the rod's samples
    sb: Samples  # the body's
    ib: np.ndarray  # body sample of each row
    a0: np.ndarray  # segment start (rod sample) of each row
    a1: np.ndarray  # segment end
    s: Array  # closest point's parameter on the segment
    share: Array  # the segment's share of the contact
    d: Array  # penetration
    n_body: Array  # unit normal into the body
    c_body: Array  # the body's point against the wall
    c_wall: Array  # the wall's point
    r_w: Array  # the wall's radius there
    v_rel: Array  # body's minus wall's velocity at the contact


def _sphere_rod(linkage: Linkage, g, eta, rod: int, body: int, inside: bool):
    """:class:`_SphereRod` of ``body`` against ``rod`` (inside it: a tube)."""
    st, gt = rod_samples(linkage, rod)
    sb = link_samples(linkage, body)
    wall = (_bore_radii(linkage, rod) if inside else st.radius).astype(g.dtype)
    _, _, xt, wt, vt_ = _world_points(g, eta, st)
    _, _, xb, wb, vb = _world_points(g, eta, sb)
    m = len(gt.start)
    ib, it = np.meshgrid(np.arange(len(sb.point)), np.arange(m), indexing="ij")
    ib, it = ib.ravel(), it.ravel()
    a0, a1 = gt.start[it], gt.end[it]
    A, B, X = xt[a0], xt[a1], xb[ib]
    AB = B - A
    den = jnp.sum(AB * AB, axis=-1)
    s_line = jnp.sum((X - A) * AB, axis=-1) / jnp.where(den > 0, den, 1.0)
    s = jnp.clip(s_line, 0.0, 1.0)
    P = A + s[:, None] * AB
    rvec = X - P
    dist = _safe_norm(rvec)
    n_out = rvec / jnp.maximum(dist, 1e-12)[:, None]  # from the axis outwards
    r_w = (1 - s) * wall[a0] + s * wall[a1]
    rho = sb.radius[ib]
    if inside:
        d = dist + rho - r_w
        n_body = -n_out  # the bore pushes the body towards the axis
        ends = np.zeros(len(it), bool)  # the wall ends at the openings
        share = _vertex_share(s_line, ends, ends)
    else:
        d = rho + r_w - dist
        n_body = n_out
        share = _vertex_share(s_line, it == 0, it == m - 1)
    c_body = X - rho[:, None] * n_body
    c_wall = P + r_w[:, None] * n_out
    v_body = vb[ib] + jnp.cross(wb[ib], c_body - X)
    v_wall = _segment_velocity(xt, wt, vt_, a0, a1, c_wall, s)
    return _SphereRod(
        st, sb, ib, a0, a1, s, share, d, n_body, c_body, c_wall, r_w, v_body - v_wall
    )


def _sphere_rod_terms(linkage: Linkage, g, eta, friction: bool):
    """A body's spheres against a soft rod's segments: (wrench rows, report rows).

    Inside a tube the spheres touch the bore (``d = dist + rho - r_in``, pushed
    towards the axis); outside, the rod's surface (``d = rho + r - dist``, pushed
    away). Each sphere-segment pair has the segment's smooth share of the contact
    (:func:`_vertex_share`); a tube's openings end its wall, a rod's ends are
    rounded.
    """
    law = linkage.contact.law
    loads, rows = [], []
    for rod, body, inside in sphere_rod_pairs(linkage):
        k = _sphere_rod(linkage, g, eta, rod, body, inside)
        f, fn, slip = _law_forces(law, k.d, k.n_body, k.v_rel, k.share, friction)
        loads.append((k.sb.point[k.ib], k.c_body, f))
        for idx, lam in ((k.a0, 1 - k.s), (k.a1, k.s)):
            loads.append((k.st.point[idx], k.c_wall, -lam[:, None] * f))
        energy = jnp.sum(k.share * law.potential(k.d))
        # past a segment's span (share 0) the row reports the wall's radius as a gap
        gap = jnp.where(k.share > 0, k.d, -k.r_w)
        rows.append((k.c_body, k.n_body, gap, fn, f, slip, energy, k.sb.link[k.ib]))
    return loads, rows


def contact_wrenches(linkage: Linkage, t, g, eta=None) -> Array:
    """Body wrenches ``(n_points, 6)`` of every contact; friction only with ``eta``."""
    return _contact(linkage, t, g, eta)[0]


def contact_loads(linkage: Linkage, t, rates, lay):
    """``(W, leaf_rows)``: the body wrenches of every contact, with friction.

    ``rates``: the dynamics' :class:`~sorojax.kinematics._recursion.PointRates`,
    ``lay`` the chain layout. Where the rates hold the leaves' frames component by
    component (:class:`~sorojax.kinematics._leaves.LeafFrames`), the obstacles'
    contact of the samples on leaves is formed on such rows
    (:func:`_obstacle_rows`) and returned as ``leaf_rows`` ``(6, n_leaves)``, each
    leaf's wrench at its chain point (for :func:`~sorojax.dynamics.
    _wrench_recursion.leaf_wrenches`); ``W`` ``(n_points, 6)`` holds every other
    contact. Otherwise this is :func:`contact_wrenches` and ``leaf_rows`` is None.
    """
    contact = linkage.contact
    assert contact is not None
    g, eta, frames = rates.g, rates.eta, rates.leaf_frames
    if frames is None or not contact.obstacles:
        return contact_wrenches(linkage, t, g, eta), None
    samples = obstacle_samples(linkage)
    leaf = lay.order[samples.point] - len(lay.core)  # leaf index (< 0: a chain point)
    on_leaf = np.flatnonzero(leaf >= 0)
    if not len(on_leaf):  # the leaves are other contacts' samples
        return contact_wrenches(linkage, t, g, eta), None
    li = leaf[on_leaf]
    n_leaves = frames.x.shape[1]
    whole = np.array_equal(li, np.arange(n_leaves))
    if not whole:
        frames = jax.tree.map(lambda a: a[..., li], frames)
    chain = (rates.core[0], lay.leaf_row[li])
    rows = _obstacle_rows(contact, _subset(samples, on_leaf), frames, t, chain)
    if not whole:
        rows = jnp.zeros((6, n_leaves), rows.dtype).at[:, li].add(rows)
    if contact_pairs(linkage):
        W = _contact(linkage, t, g, eta, _subset(samples, np.zeros(0, int)))[0]
    else:
        W = jnp.zeros((g.shape[0], 6), g.dtype)
    at_core = np.flatnonzero(leaf < 0)
    if len(at_core):  # the samples on chain points, from the chain's own rows
        gc, ec = rates.core
        pts = samples.point[at_core]
        sub = _subset(samples, at_core)._replace(point=lay.row[pts])
        loads, _ = _obstacle_terms(contact, sub, gc, ec, t, True)
        R, p = gc[sub.point, :3, :3], gc[sub.point, :3, 3]
        Wk = sum(_point_wrenches(R, p, x, f) for _, x, f in loads)
        W = _add_rows(W, pts, Wk)
    return W, rows


def contact_pairs(linkage: Linkage) -> bool:
    """Whether the scene has contacts between links (static).

    Rod pairs, self-contact, bodies against rods or in tubes: the contacts whose
    wrenches :func:`contact_loads` puts in ``W`` at any point, leaves included.
    """
    return bool(_pair_list(linkage) or sphere_rod_pairs(linkage))


def _subset(samples: Samples, idx: np.ndarray) -> Samples:
    """The samples ``idx`` (static indices), in that order."""
    return Samples(
        samples.point[idx],
        samples.link[idx],
        samples.weight[idx],
        samples.radius[idx],
        samples.offset[idx],
    )


def contact_wrenches_and_penetrations(linkage: Linkage, t, g) -> tuple[Array, Array]:
    """Frictionless contact wrenches and every contact's penetration (statics)."""
    W, rows, _, _ = _contact(linkage, t, g, None)
    pen = [r[2] for r in rows]
    return W, (jnp.concatenate(pen) if pen else jnp.zeros((0,), g.dtype))


def smallest_radius(linkage: Linkage) -> Array:
    """The smallest positive contact radius of the scene's samples [m] (inf if none).

    Point samples (a box's corners, radius 0) are left out: how deep they may go
    is not a radius.
    """
    contact = linkage.contact
    assert contact is not None
    radii = [obstacle_samples(linkage).radius] if contact.obstacles else []
    others = {i for p in contact.rod_pairs for i in p} | set(contact.self_contact)
    others |= {body for _, body in contact.inside}
    for link in sorted(others):
        radii.append(link_samples(linkage, link).radius)
    radii = [r for r in radii if r.shape[0]]
    if not radii:
        return jnp.asarray(jnp.inf)
    r = jnp.concatenate(radii)
    return jnp.min(jnp.where(r > 0, r, jnp.inf))


def _contact(linkage: Linkage, t, g, eta, samples: Samples | None = None):
    """``(W, rows, labels, overflow)``: wrenches, report rows and their labels.

    ``samples``: the obstacles' samples (None: :func:`obstacle_samples`).

    Each kind of contact gives its loads, ``(points, x, f)``: forces ``f`` (world)
    at world points ``x`` carried by significant points ``points``; they become
    body wrenches at those points in one batch. Rod pairs and self-contact give
    body wrenches at their samples' points (:func:`_pair_terms`). Where the broad
    phase overflowed
    the wrenches are NaN: a solver stops there (the report says why) rather than
    going on without some contacts.
    """
    contact = linkage.contact
    assert contact is not None
    friction = eta is not None
    loads, rows, labels = [], [], []
    overflow = jnp.zeros((), bool)
    if samples is None and contact.obstacles:
        samples = obstacle_samples(linkage)
    if contact.obstacles and len(samples.point):
        lo, ro = _obstacle_terms(contact, samples, g, eta, t, friction)
        loads += lo
        for k, r in enumerate(ro):
            rows.append(r)
            labels.append((samples.link, np.full(len(samples.link), k)))
    pairs = _pair_list(linkage)
    pair_wrenches = []
    if pairs:
        pair_wrenches, rp, overflow = _pair_terms(contact, pairs, g, eta, friction)
        for r in rp:
            rows.append(r[:7])
            labels.append((np.asarray(r[7]), np.full(len(r[7]), -1)))
    if sphere_rod_pairs(linkage):
        li, ri = _sphere_rod_terms(linkage, g, eta, friction)
        loads += li
        for r in ri:
            rows.append(r[:7])
            labels.append((np.asarray(r[7]), np.full(len(r[7]), -1)))
    W = jnp.zeros((g.shape[0], 6), g.dtype)
    if loads:  # every contact's forces as wrenches at their points: one scatter
        points = _join_indices([pt for pt, _, _ in loads])
        x = jnp.concatenate([x for _, x, _ in loads])
        f = jnp.concatenate([f for _, _, f in loads])
        R, p = g[points, :3, :3], g[points, :3, 3]
        W = _add_rows(W, points, _point_wrenches(R, p, x, f))
    for points, Wp in pair_wrenches:
        W = _add_rows(W, points, Wp)
    if pairs:
        W = jnp.where(overflow, jnp.nan, W)
    return W, rows, labels, overflow


def contact_energy_from_poses(linkage: Linkage, g) -> Array:
    """Elastic contact energy [J] at poses ``g``."""
    _, rows, _, _ = _contact(linkage, 0.0, g, None)
    return sum((r[6] for r in rows), jnp.zeros((), g.dtype))


# --------------------------------------------------------------------- public API
@jit
def contact_state(
    linkage: Linkage,
    q: ArrayLike,
    qd: ArrayLike | None = None,
    t: ArrayLike = 0.0,
) -> ContactState:
    """Contact points, normals, penetrations, forces and slip at ``(q, qd, t)``.

    Args:
        linkage: a model with ``contact``.
        q: coordinates ``(n_dof,)``.
        qd: velocities ``(n_dof,)``; default zeros (no damping, no friction: the
            statics' frictionless contact).
        t: time [s] (moving obstacles).

    Returns:
        A :class:`ContactState` (vmap it over a trajectory's ``q``, ``qd``, ``t``).

    Raises:
        ValueError: the linkage has no contact.
    """
    if linkage.contact is None:
        raise ValueError(
            "contact_state: this linkage has no contact; give Linkage(contact="
            "sorojax.Contact(...))."
        )
    q = _as_q(linkage, q)
    qd = None if qd is None else _as_q(linkage, qd, "qd")
    return state_from_data(linkage, precompute(linkage), q, qd, jnp.asarray(t, q.dtype))


def state_from_data(linkage: Linkage, data, q, qd, t) -> ContactState:
    """:func:`contact_state` from precomputed data (inside other programs).

    The points' twists are ``J qd`` formed as one column
    (:func:`~sorojax.kinematics._recursion.poses_and_jacobians` with ``V = qd``):
    neither the Jacobians nor the twists' rates that the dynamics need are formed
    (the grasp's contact report at its 61 save points compiles ~0.4 s faster
    than through the dynamics' kinematics, which form both).
    """
    from ..kinematics._recursion import poses, poses_and_jacobians

    if qd is None:
        g, eta = poses(data, q), None
    else:
        g, Jv = poses_and_jacobians(data, q, qd[:, None])
        eta = Jv[..., 0]
    _, rows, labels, overflow = _contact(linkage, t, g, eta)
    if not rows:
        z = jnp.zeros((0,), q.dtype)
        z3 = jnp.zeros((0, 3), q.dtype)
        zero = jnp.zeros((), q.dtype)
        return ContactState(z3, z3, z, z, z3, z3, (), (), zero, overflow)
    cat = [jnp.concatenate([r[k] for r in rows]) for k in range(6)]
    return ContactState(
        *cat,
        link_number=tuple(int(i) for lab in labels for i in lab[0]),
        obstacle_index=tuple(int(i) for lab in labels for i in lab[1]),
        energy=sum(r[6] for r in rows),
        overflow=overflow,
    )


def contact_report(linkage: Linkage, data, t, q, qd, result):
    """Contact states at a trajectory's save times (leading axis: time).

    Also ``result``, turned into ``RESULTS.contact_too_deep`` where a successful
    run went deeper than the smallest contact radius, and into
    ``RESULTS.contact_overflow`` where the broad phase overflowed. ``data``: the
    linkage's precomputed arrays. One save point at a time (a ``lax.map``): traced
    faster than a batch of them (a ``vmap``: the grasp's report in 0.3 s less) and
    compiled as fast.
    """
    states = jax.lax.map(
        lambda tqv: state_from_data(linkage, data, tqv[1], tqv[2], tqv[0]), (t, q, qd)
    )
    pen = jnp.where(jnp.isfinite(states.penetration), states.penetration, -jnp.inf)
    deep = jnp.max(pen, initial=-jnp.inf) > smallest_radius(linkage)
    ok = result == RESULTS.successful
    result = RESULTS.where(deep & ok, RESULTS.contact_too_deep, result)
    return states, RESULTS.where(
        jnp.any(states.overflow), RESULTS.contact_overflow, result
    )


@jit
def contact_energy(linkage: Linkage, q: ArrayLike) -> Float[Array, ""]:
    """Elastic contact energy [J] at ``q`` (add it to :func:`total_energy`)."""
    from ..kinematics._recursion import poses

    q = _as_q(linkage, q)
    if linkage.contact is None:
        return jnp.zeros((), q.dtype)
    return contact_energy_from_poses(linkage, poses(precompute(linkage), q))


def _point_jacobian(g, J, point, x_c):
    """World linear-velocity Jacobians ``(n, 3, n_dof)`` of points ``x_c``.

    The points move with significant points ``point``: ``R (J_v - [a_b]x J_w)``.
    """
    R, p = g[point, :3, :3], g[point, :3, 3]
    Jp = J[point]
    a_b = _rotate_back(R, x_c - p)
    Jv = Jp[:, 3:] - jnp.cross(a_b[:, :, None], Jp[:, :3], axis=1)
    return _rotate(R[:, None], jnp.moveaxis(Jv, 1, 2)).swapaxes(1, 2)


def _tangent_slopes(law, weight, d, n, v_rel, friction: bool = True):
    """Per contact: normal stiffness ``k_n``, normal and tangential damping slopes.

    ``(k_n, c_n - c_t, c_t)``: the contact's stiffness and damping are
    ``k_n n n^T`` and ``(c_n - c_t) n n^T + c_t I`` (world), with ``c_t = mu f_n /
    sqrt(|v_t|^2 + v_s^2)`` the friction's viscous slope (v_s grown by the law's
    ``stick_load``, :meth:`~sorojax.ContactLaw.stick_speed_squared`).
    """
    kn = weight * jax.vmap(jax.grad(law.normal_force))(d)
    cn = weight * law.damping * law.ramp(d)
    vn = jnp.sum(v_rel * n, axis=-1)
    vt = v_rel - vn[:, None] * n
    f_el = law.normal_force(d)
    ct = (
        weight
        * law.friction_coefficient(_safe_norm(vt))
        * f_el
        / jnp.sqrt(jnp.sum(vt * vt, axis=-1) + law.stick_speed_squared(f_el))
    )
    if not friction:
        ct = jnp.zeros_like(ct)
    return kn, cn - ct, ct


def contact_tangent(linkage: Linkage, t, g, J, eta) -> tuple[Array, Array]:
    """``(K_c, D_c)``: the contacts' stiffness and damping in coordinates.

    Gauss-Newton forms (symmetric positive semi-definite, so that ROS34PW2's
    ``M + c D + c^2 K`` stays positive definite): ``K_c = sum J_c^T (w f_n'(d)
    n n^T) J_c`` and ``D_c = sum J_c^T (w c s(d) n n^T + w c_t (I - n n^T)) J_c``
    with ``J_c`` the Jacobian of each contact's relative velocity (world) and
    ``c_t = mu f_n / sqrt(|v_t|^2 + v_s^2)`` the friction's viscous slope: obstacle
    contacts, rod pairs and self-contact (each segment pair's contact point moves
    with its segment's two samples, weighted as its force is split), and bodies
    against rods (tubes, a rigid shape in ``rod_pairs``). The geometric
    (curvature) terms are left out: W only needs the contacts' fast scales, its
    order conditions hold for any W.

    Every contact of every kind is one row of one batch: the points that carry
    the contacts (one per obstacle contact, three per body against a rod, four
    per rod pair), their velocity Jacobians in one gather and product, and the
    sums over the rows as three matrix products.
    """
    contact = linkage.contact
    assert contact is not None
    law = contact.law
    # per kind: (the rows' slopes, their carrying points (point index, weight, x))
    slopes, carriers = [], []
    if contact.obstacles:
        samples = obstacle_samples(linkage)
        _, _, x, w, v = _world_points(g, eta, samples)
        for k, ob in enumerate(contact.obstacles):
            n, d, x_c, v_rel = _against_obstacle(ob, t, x, w, v, samples.radius)
            slopes.append(
                (
                    n,
                    *_tangent_slopes(
                        contact.obstacle_law(k), samples.weight, d, n, v_rel
                    ),
                )
            )
            carriers.append([(samples.point, None, x_c)])
    for entry in _pair_list(linkage):
        sa, ga, sb, gb, _, _ = entry
        pick, valid, _ = _candidates(contact, g, entry)
        k = _pair_geometry(g, eta, sa, ga, sb, gb, pick, valid)
        friction = contact.friction_in_rod_pairs
        slopes.append(
            (k.n, *_tangent_slopes(law, k.share, k.d, k.n, k.v_rel, friction))
        )
        carriers.append([
            (_take(sa.point, k.a0), 1 - k.s, k.cA),
            (_take(sa.point, k.a1), k.s, k.cA),
            (_take(sb.point, k.b0), -(1 - k.u), k.cB),
            (_take(sb.point, k.b1), -k.u, k.cB),
        ])  # fmt: skip
    for rod, body, inside in sphere_rod_pairs(linkage):
        k = _sphere_rod(linkage, g, eta, rod, body, inside)
        slopes.append(
            (k.n_body, *_tangent_slopes(law, k.share, k.d, k.n_body, k.v_rel))
        )
        carriers.append([
            (k.sb.point[k.ib], None, k.c_body),
            (k.st.point[k.a0], -(1 - k.s), k.c_wall),
            (k.st.point[k.a1], -k.s, k.c_wall),
        ])  # fmt: skip
    n_dof = J.shape[-1]
    if not slopes:
        z = jnp.zeros((n_dof, n_dof), J.dtype)
        return z, z
    flat = [c for kind in carriers for c in kind]
    points = _join_indices([c[0] for c in flat])
    Jp = _point_jacobian(g, J, points, jnp.concatenate([c[2] for c in flat]))
    lam = jnp.concatenate([
        jnp.ones(c[2].shape[0], J.dtype) if c[1] is None else c[1] for c in flat
    ])  # fmt: skip
    Jp = lam[:, None, None] * Jp
    rows, at = [], 0  # each contact's Jacobian: the sum of its carriers'
    for kind in carriers:
        m = kind[0][2].shape[0]
        rows.append(sum(Jp[at + i * m : at + (i + 1) * m] for i in range(len(kind))))
        at += m * len(kind)
    Jc = jnp.concatenate(rows)
    n, kn, cnt, ct = (jnp.concatenate(x) for x in zip(*slopes, strict=True))
    Jn = n[:, 0, None] * Jc[:, 0] + n[:, 1, None] * Jc[:, 1] + n[:, 2, None] * Jc[:, 2]
    K = (kn[:, None] * Jn).T @ Jn
    D = (cnt[:, None] * Jn).T @ Jn + jnp.einsum("n,nik,nil->kl", ct, Jc, Jc)
    return K, D
