"""Model adequacy for statics: error estimates and the strain orders a scene needs.

A soft division's strain is a Legendre series per mode (torsion, two bendings,
elongation, two shears). Legendre polynomials are orthogonal on the division and,
for a uniform section, orthogonal in the stiffness too, so dropping a mode's
highest coefficients from a solution is the stiffness-weighted projection onto the
smaller model: for a linear problem it is exactly that model's solution (Galerkin),
for a nonlinear one close to it. This makes truncations of one well-resolved
solution a cheap proxy for the solutions of every smaller model, evaluated by
forward kinematics alone (one vmapped call over all candidates):

- :func:`discretization_error` estimates a solution's discretisation error as the
  change of the quantity of interest (QoI; by default the whole configuration:
  poses at probe points of every soft division and at every link's tip, positions
  and rotations times the reference length, and the reactions of closed loops and
  prescribed joints as lengths, all relative to the reference length) when each
  mode's highest coefficient is dropped: the error of the next smaller model, an
  upper estimate of this one's under spectral decay.
- :func:`choose_model` solves a *reference* model (every mode at a high order,
  many points), picks per division and per mode the smallest orders (modes off
  where they are not needed) whose Galerkin solution of the equilibrium
  linearised at the reference keeps the QoI within a fraction of the tolerance
  (greedy, best error reduction per coordinate), then *verifies* the choice with
  one solve of the chosen model against the reference, tightening and repeating
  if needed. Its error estimate is that verified difference.
  :func:`solve_statics_adequate` is its one-liner for a tolerance alone.

Only soft divisions with a :class:`~sorojax.LegendreBasis` are supported (the
monomial and custom bases are not nested orthogonal families).
"""

import dataclasses
import time
import warnings
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from .._jit import jit
from ..dynamics._eom import as_inputs
from ..kinematics._api import forward_kinematics
from ..model._actuation import JointActuator
from ..model._basis import MODE_NAMES, LegendreBasis
from ..model._link import Division, SoftLink
from ..model._linkage import Linkage
from ..model._loads import PointWrench
from ..model._precompute import precompute
from ..model._size_class import replace_divisions
from ._solve import _row_scale, free_coordinates, scaled_equilibrium, solve_statics

# An order of -1 switches a mode off.
OFF = -1
# Relative cut-off of the Galerkin least squares (columns normalised): a buckled
# clamped-clamped rod's neutral turn about its end-to-end line made an order-8
# estimate 1.6e-6 against a true 1e-9 without it.
RCOND = 1e-10
# The final trim's target as a fraction of the tolerance.
TRIM = 0.95
# choose_model's reference: order 12, raised by 4 up to 24 while its own estimated
# error exceeds this share of the tolerance (a clamped-clamped rod buckled to 0.8 L
# is off by 2.5e-6 L at order 12, 1.4e-7 L at 16).
REFERENCE_ORDER, MAX_REFERENCE_ORDER, REFERENCE_SHARE = 12, 24, 0.2


class InsensitiveQuantityWarning(UserWarning):
    """A quantity of interest that cannot tell the candidate models apart."""


# ------------------------------------------------------------------ model surgery
def _soft_divisions(linkage: Linkage):
    """``[(link, division, Division)]`` of every soft division (1-based link)."""
    out = []
    for i, link in enumerate(linkage.links, start=1):
        if isinstance(link, SoftLink):
            for k, div in enumerate(link.divisions):
                out.append((i, k, div))
    return out


def division_orders(linkage: Linkage) -> dict[tuple[int, int], tuple[int, ...]]:
    """Orders per mode of every soft division, ``-1`` where a mode is off.

    Returns:
        ``{(link, division): (o_torsion, o_bend_y, o_bend_z, o_elong, o_shear_y,
        o_shear_z)}`` with 1-based links and 0-based divisions.

    Raises:
        ValueError: a division whose basis is not a LegendreBasis.
    """
    out = {}
    for i, k, div in _soft_divisions(linkage):
        b = div.basis
        if not isinstance(b, LegendreBasis):
            raise ValueError(
                f"link {i} division {k} has a {type(b).__name__}: model adequacy "
                "works on LegendreBasis divisions only (give the division a "
                "LegendreBasis of the same modes)."
            )
        out[(i, k)] = tuple(
            o if m else OFF for m, o in zip(b.modes, b.orders, strict=True)
        )
    return out


def with_orders(
    linkage: Linkage,
    orders: dict[tuple[int, int], tuple[int, ...]],
    n_gauss: dict[tuple[int, int], int] | int | None = None,
) -> Linkage:
    """The same linkage with other Legendre orders (and points) in soft divisions.

    Args:
        linkage: the model.
        orders: ``{(link, division): six orders}`` (1-based link, 0-based division;
            ``-1`` switches a mode off); divisions not named keep their basis.
        n_gauss: interior points per division (a dict like ``orders``, one int for
            all changed divisions, or None for the default rule of
            :class:`~sorojax.Division`).

    Returns:
        A new :class:`~sorojax.Linkage` (loads, actuators and loops unchanged).

    Raises:
        ValueError: a bad key or order, or a linkage with ``added_mass`` whose
            points change (its per-point shape depends on them).
    """
    known = {(i, k) for i, k, _ in _soft_divisions(linkage)}
    for key, o in orders.items():
        if key not in known:
            raise ValueError(
                f"orders key {key!r} is not a soft division (link, division): "
                f"the soft divisions are {sorted(known)}."
            )
        if len(o) != 6 or any(int(x) < OFF for x in o):
            raise ValueError(
                f"orders[{key!r}] = {o!r}: give six orders >= 0, or -1 for a mode "
                f"off, in the order {MODE_NAMES}."
            )

    def change(i: int, k: int, div: Division) -> Division:
        if (i, k) not in orders:
            return div
        o = tuple(int(x) for x in orders[(i, k)])
        basis = LegendreBasis(tuple(x >= 0 for x in o), tuple(max(x, 0) for x in o))
        ng = n_gauss.get((i, k)) if isinstance(n_gauss, dict) else n_gauss
        return Division(div.length, div.section, basis, ng, div.xi_ref)

    return replace_divisions(linkage, change, "with_orders")


def _coefficient_index(linkage: Linkage) -> dict:
    """``{(link, division, mode, k): index in q}`` of every Legendre coefficient."""
    orders = division_orders(linkage)
    lay = linkage.layout
    out = {}
    for (i, k), o in orders.items():
        j = lay.links[i - 1].divisions[k].offset
        for m in range(6):
            for c in range(o[m] + 1):
                out[(i, k, m, c)] = j
                j += 1
    return out


def transfer_coordinates(source: Linkage, q: ArrayLike, target: Linkage) -> np.ndarray:
    """Coordinates of ``source`` expressed in ``target`` (same links, other orders).

    Joint coordinates are copied; each Legendre coefficient present in both is
    copied, those only in ``target`` are 0, those only in ``source`` are dropped
    (a truncation: the L2-orthogonal projection of the strain per division).
    """
    q = np.asarray(q, dtype=float)
    out = np.zeros(target.n_dof)
    for ls, lt in zip(source.layout.links, target.layout.links, strict=True):
        out[lt.joint_offset : lt.joint_offset + lt.joint_n_dof] = q[
            ls.joint_offset : ls.joint_offset + ls.joint_n_dof
        ]
    src, dst = _coefficient_index(source), _coefficient_index(target)
    for key, j in dst.items():
        if key in src:
            out[j] = q[src[key]]
    return out


# ---------------------------------------------------------- quantity of interest
# Probe intervals per soft division of the default QoI: 17 evenly spaced points
# (ends included). Errors between probes are not seen; orders above 16 (up to 20 on
# the clamped rods of tests/test_adequacy.py) then rely on the error's smoothness.
PROBES = 16
# Built-in quantities: the whole configuration, or every link's tip pose alone.
QUANTITIES = ("configuration", "tips")
# A quantity that changes less than this fraction of the configuration's change
# between the reference and smaller models cannot tell them apart.
INSENSITIVE = 1e-3


def reference_length(linkage: Linkage) -> float:
    """The QoI's length scale: the longest soft link (or rigid link) [m]."""
    lengths = [float(lk.length) for lk in linkage.links]
    return max(lengths)


def bending_stiffness(linkage: Linkage) -> float | None:
    """Length-weighted mean bending stiffness ``E (Iy + Iz) / 2`` [N m^2].

    Evaluated at every soft division's middle; None without soft divisions.
    """
    num = den = 0.0
    for i, _, div in _soft_divisions(linkage):
        _, Iy, Iz, _ = div.section.properties(0.5)
        E = float(linkage.links[i - 1].material.E)
        num += float(div.length) * E * (float(Iy) + float(Iz)) / 2.0
        den += float(div.length)
    return num / den if den > 0 else None


def reaction_scales(linkage: Linkage, length: float) -> tuple[np.ndarray, np.ndarray]:
    """Lengths per unit closed-loop multiplier and per unit prescribed effort.

    Units m / (N m) or m / N by the row's direction.
    A reaction error is expressed as the deflection it would give a cantilever of
    the reference length ``l`` and the scene's :func:`bending_stiffness` ``EI``:
    ``l^2 / EI`` per N m of moment and ``l^3 / EI`` per N of force (an angle
    ``M l / EI`` times ``l``; a deflection ``F l^3 / EI``). A row whose direction
    mixes both (a helical joint's) adds them by its angular and linear norms.

    Returns:
        ``(per multiplier row (n_constraints,), per prescribed coordinate (n,))``;
        zeros without soft divisions.
    """
    EI = bending_stiffness(linkage)
    n_p = len(linkage.prescribed[0])
    if EI is None:
        return np.zeros(linkage.n_constraints), np.zeros(n_p)

    def scale(columns):
        columns = np.asarray(columns, dtype=float).reshape(6, -1)
        ang = np.linalg.norm(columns[:3], axis=0)
        lin = np.linalg.norm(columns[3:], axis=0)
        return ang * length**2 / EI + lin * length**3 / EI

    loops = [scale(c.constrained_basis()) for c in linkage.closed_loops]
    s_lam = np.concatenate(loops) if loops else np.zeros(0)
    efforts = []
    for a in linkage.actuators:
        if isinstance(a, JointActuator) and a.prescribed:
            efforts.append(scale(linkage.links[a.link - 1].joint.basis()))
    s_eff = np.concatenate(efforts) if efforts else np.zeros(0)
    return s_lam, s_eff


def _sampler(linkage: Linkage) -> tuple[Linkage, np.ndarray]:
    """``linkage`` with probe points and the indices of probes and tips.

    The probes are zero point wrenches at ``X1 = j / PROBES`` of every soft division
    (exact significant points of the kinematics; no coordinates, no load).
    """
    probes = [
        PointWrench(i, jnp.zeros(6), division=k + 1, X1=j / PROBES)
        for i, k, _ in _soft_divisions(linkage)
        for j in range(PROBES + 1)
    ]
    sampler = Linkage(
        list(linkage.links),
        parents=linkage.parents,
        placements=linkage.placements,
        gravity=linkage.gravity,
        point_wrenches=tuple(linkage.point_wrenches) + tuple(probes),
        custom_wrench=linkage.custom_wrench,
        actuators=linkage.actuators,
        closed_loops=linkage.closed_loops,
        custom_actuation=linkage.custom_actuation,
        actuator_strength=linkage.actuator_strength,
        baumgarte_time=linkage.baumgarte_time,
        contact=linkage.contact,
    )
    idx = [sampler.point_index(p) for p in probes]
    idx += [sampler.tip_point(i + 1) for i in range(linkage.n_links)]
    return sampler, np.asarray(idx)


@jit
def _tip_poses(linkage: Linkage, qs):
    """World poses of every link's tip, for a batch of q: ``(batch, n_links, 4, 4)``."""
    tips = np.asarray([linkage.tip_point(i + 1) for i in range(linkage.n_links)])
    return jax.vmap(lambda q: forward_kinematics(linkage, q)[tips])(qs)


@jit
def _poses_at(linkage: Linkage, qs, idx):
    """World poses at points ``idx`` for a batch of q: ``(batch, len(idx), 4, 4)``."""
    return jax.vmap(lambda q: forward_kinematics(linkage, q)[idx])(qs)


def pose_distance(g_a, g_b, length: float) -> np.ndarray:
    """``max(|p_a - p_b|, length * angle(R_a^T R_b)) / length`` over the last axes."""
    g_a, g_b = np.asarray(g_a), np.asarray(g_b)
    dp = np.linalg.norm(g_a[..., :3, 3] - g_b[..., :3, 3], axis=-1)
    R = np.einsum("...ji,...jk->...ik", g_a[..., :3, :3], g_b[..., :3, :3])
    c = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    # arccos loses accuracy near 0: the skew part's norm is sin(angle)
    s = 0.5 * np.linalg.norm(
        np.stack(
            [
                R[..., 2, 1] - R[..., 1, 2],
                R[..., 0, 2] - R[..., 2, 0],
                R[..., 1, 0] - R[..., 0, 1],
            ],
            axis=-1,
        ),
        axis=-1,
    )
    angle = np.arctan2(s, c)
    return np.maximum(dp, length * angle) / length


def _quantity_name(quantity) -> str:
    if quantity is None:
        return "configuration"
    if isinstance(quantity, str):
        return quantity
    return getattr(quantity, "__name__", repr(quantity))


class _Qoi:
    """The quantity of interest of one model, evaluated on batches of states.

    A state is ``(q, lam, eff)``: coordinates, closed-loop multipliers and efforts
    of prescribed coordinates (None: no reactions, e.g. a trajectory's states).

    - ``"configuration"`` (default): world poses at :data:`PROBES` + 1 points of
      every soft division and at every link's tip, and the reactions times
      :func:`reaction_scales`;
    - ``"tips"``: every link's tip pose;
    - a callable ``(linkage, q) -> array`` [m].
    """

    def __init__(self, linkage: Linkage, quantity, length: float):
        self.linkage, self.length, self.quantity = linkage, float(length), quantity
        self.name = _quantity_name(quantity)
        if callable(quantity):
            return
        if self.name not in QUANTITIES:
            raise ValueError(
                f"quantity = {quantity!r}: give one of {QUANTITIES}, None (the "
                "configuration) or a function (linkage, q) -> array [m]."
            )
        if self.name == "configuration":
            self.sampler, self.idx = _sampler(linkage)
            self.s_lam, self.s_eff = reaction_scales(linkage, length)
        else:
            self.sampler = linkage
            self.idx = np.asarray(
                [linkage.tip_point(i + 1) for i in range(linkage.n_links)]
            )
            self.s_lam = np.zeros(0)
            self.s_eff = np.zeros(0)

    def poses(self, qs) -> np.ndarray:
        """``(batch, n_points, 4, 4)`` poses of a batch ``qs``."""
        qs = jnp.atleast_2d(jnp.asarray(qs))
        return np.asarray(_poses_at(self.sampler, qs, jnp.asarray(self.idx)))

    def reactions(self, lam, eff, batch: int) -> np.ndarray:
        """``(batch, n)`` scaled reactions [m] (``n = 0`` when not part of it)."""
        parts = []
        if len(self.s_lam) and lam is not None:
            parts.append(np.atleast_2d(np.asarray(lam)) * self.s_lam)
        if len(self.s_eff) and eff is not None:
            parts.append(np.atleast_2d(np.asarray(eff)) * self.s_eff)
        if not parts:
            return np.zeros((batch, 0))
        return np.concatenate(parts, axis=1)

    def user(self, qs) -> np.ndarray:
        """The user's quantity of each of a batch ``qs``, flattened."""
        qs = np.atleast_2d(np.asarray(qs))
        return np.asarray(
            [np.ravel(self.quantity(self.linkage, jnp.asarray(q))) for q in qs]
        )

    def errors(self, qs, lams, effs, q0, lam0, eff0) -> np.ndarray:
        """Distances (relative to the length) of a batch of states from one state."""
        return self.against(self, qs, lams, effs, q0, lam0, eff0)

    def against(self, other, qs, lams, effs, q0, lam0, eff0) -> np.ndarray:
        """Distances of a batch of states of this model from one state of ``other``.

        Both models have the same links and divisions (other orders or points):
        their probes lie at the same arc lengths.
        """
        qs = np.atleast_2d(np.asarray(qs))
        if callable(self.quantity):
            a, b = self.user(qs), other.user(q0)
            return np.max(np.abs(a - b), axis=1) / self.length
        d = pose_distance(self.poses(qs), other.poses(q0), self.length).max(axis=-1)
        r_a = self.reactions(lams, effs, len(qs))
        r_b = other.reactions(lam0, eff0, 1)
        if r_a.shape[1] and r_a.shape[1] == r_b.shape[1]:
            d = np.maximum(d, np.abs(r_a - r_b).max(axis=1) / self.length)
        return d

    def kinematics(self, other, qs, q0s) -> float:
        """Largest pose distance between equally long batches of this and ``other``."""
        g_a = self.poses(qs)
        g_b = other.poses(q0s)
        return float(pose_distance(g_a, g_b, self.length).max())


@jit
def _tangent(linkage: Linkage, x, u, q_p, t):
    """Statics Jacobian (scaled rows) at ``x``, row scale, efforts and their Jacobian.

    The efforts are the unscaled rows of the prescribed coordinates.
    """
    data = precompute(linkage)
    free = free_coordinates(linkage)
    qi = linkage.prescribed[0]

    def rows(x_):
        f, r = scaled_equilibrium(linkage, data, x_, t, 1.0, u, q_p)
        return f, r[qi]

    J, Jp = jax.jacfwd(rows)(x)
    return J, _row_scale(data.K)[free], Jp, rows(x)[1]


def _reference_tangent(linkage, q, lam, u, t):
    """``(J_u, free, (J_p, e_p))``: the unscaled statics Jacobian at ``(q, lam)``.

    ``e_p`` are the prescribed coordinates' efforts there, ``J_p`` their Jacobian.
    """
    free = free_coordinates(linkage)
    qi, ui = linkage.prescribed
    q = jnp.asarray(q)
    u_arr = as_inputs(linkage, None if u is None else jnp.asarray(u, float), q.dtype)
    x = jnp.concatenate([q[free], jnp.asarray(lam)])
    J, scale, Jp, ep = _tangent(
        linkage, x, u_arr, q[qi] if len(qi) else None, jnp.asarray(t, q.dtype)
    )
    J = np.asarray(J).copy()
    J[: len(free)] /= np.asarray(scale)[:, None]
    return J, free, (np.asarray(Jp), np.asarray(ep))


def _with_enough_points(linkage, orders, ref_qoi, q_t, target, cap):
    """``linkage`` at ``orders``, points doubled until its kinematics of ``q_t``.

    (reference coordinates, one or a batch) agree with the reference's (on
    ``ref_qoi``'s points: a user quantity's on the configuration's) within
    ``target``, or the points reach ``cap``.
    """
    reference, length = ref_qoi.linkage, ref_qoi.length
    kind = "tips" if ref_qoi.name == "tips" else "configuration"
    if kind != ref_qoi.name:
        ref_qoi = _Qoi(reference, kind, length)
    ng = None
    while True:
        chosen = with_orders(linkage, orders, ng)
        q_tc = np.asarray(
            [transfer_coordinates(reference, q, chosen) for q in np.atleast_2d(q_t)]
        )
        e_pts = _Qoi(chosen, kind, length).kinematics(ref_qoi, q_tc, q_t)
        if e_pts <= target or ng is not None and max(ng.values()) >= cap:
            return chosen
        ng = {(i, k): 2 * chosen.links[i - 1].divisions[k].n_gauss for i, k in orders}


# ------------------------------------------------------------------ estimates
@dataclasses.dataclass(frozen=True)
class DiscretizationEstimate:
    """Discretisation error indicators of one solution.

    Attributes:
        error: the estimate, ``max(coefficients, points)``.
        coefficients: ``e1 * min(1, e1 / e2)``, with ``e1`` (``e2``) the QoI
            change (relative to the reference length) when the highest (two
            highest) coefficients of every active mode are dropped: the
            geometric-decay extrapolation one order up.
        points: QoI change when the same q is integrated with twice the points
            (the kinematics' integration error, which coefficients cannot see).
        per_mode: ``{(link, division, mode name): QoI change}`` when only that
            mode's highest coefficient is dropped.
    """

    error: float
    coefficients: float
    points: float
    per_mode: dict


@jit
def _rows_without_multipliers(linkage: Linkage, q_free, u, q_p, t):
    """The statics rows at ``(q, lam = 0)`` and their row scale."""
    data = precompute(linkage)
    free = free_coordinates(linkage)
    x = jnp.concatenate([q_free, jnp.zeros(linkage.n_constraints, q_free.dtype)])
    r = scaled_equilibrium(linkage, data, x, t, 1.0, u, q_p)[0]
    return r, _row_scale(data.K)[free]


def _multipliers(linkage, q, u, t, J_u, free):
    """Least-squares closed-loop multipliers of ``q`` (the rows are affine in them)."""
    qi, _ = linkage.prescribed
    q = jnp.asarray(q)
    u_arr = as_inputs(linkage, None if u is None else jnp.asarray(u, float), q.dtype)
    r, scale = _rows_without_multipliers(
        linkage, q[free], u_arr, q[qi] if len(qi) else None, jnp.asarray(t, q.dtype)
    )
    r = np.asarray(r).copy()
    r[: len(free)] /= np.asarray(scale)
    n = len(free)
    return np.linalg.lstsq(J_u[:n, n:], -r[:n], rcond=None)[0]


def _galerkin(tangent, q_ref, dropped):
    """The state of the smaller model that drops coordinates ``dropped`` (q indices).

    Its Galerkin solution of the equilibrium linearised at ``x_ref = (q_free,
    lam)``: ``E^T J (E x_K - x_ref) = 0`` on the kept unknowns (exact up to second
    order in the error; plain truncation misses the coupling of modes: a hanging
    rod's truncation error was 80x below its model's error). ``tangent = (J_u,
    free, x_ref, (J_p, e_p))`` (:func:`_equilibrium_tangent`).

    Returns:
        ``(q, lam, eff)``: coordinates, multipliers and the prescribed
        coordinates' efforts (linearised too).
    """
    J_u, free, x_ref, (J_p, e_p) = tangent
    pos_in_x = {int(j): a for a, j in enumerate(free)}
    q = np.array(q_ref, dtype=float)
    keep = np.ones(len(x_ref), bool)
    for j in dropped:
        q[j] = 0.0
        if j in pos_in_x:
            keep[pos_in_x[j]] = False
    A = J_u[np.ix_(keep, keep)]
    x = np.where(keep, x_ref, 0.0)  # the truncation, corrected (minimum norm:
    c = np.linalg.norm(A, axis=0)  # a near-neutral direction stays the reference's)
    c[c == 0] = 1.0
    r = J_u[keep] @ (x - x_ref)
    x[keep] -= np.linalg.lstsq(A / c, r, rcond=RCOND)[0] / c
    q[free] = x[: len(free)]
    eff = e_p + J_p @ (x - x_ref) if len(e_p) else e_p
    return q, x[len(free) :], eff


def _equilibrium_tangent(linkage, q, u, lam, t):
    """The unscaled statics tangent at the equilibrium ``q``.

    Returns ``(J_u, free, x, (J_p, e_p))``: ``x = (q_free, lam)``, with
    least-squares multipliers when ``lam`` is None; ``e_p`` the prescribed
    coordinates' efforts and ``J_p`` their Jacobian in ``x``.
    """
    n_c = linkage.n_constraints
    q = np.asarray(q, dtype=float)
    if n_c and lam is None:
        # the multiplier columns do not depend on lam (the q block does: the
        # constraint curvature), so a tangent at lam = 0 gives the least squares
        J_0, free, _ = _reference_tangent(linkage, q, np.zeros(n_c), u, t)
        lam = _multipliers(linkage, q, u, t, J_0, free)
    lam = np.zeros(0) if not n_c else np.asarray(lam, dtype=float)
    J_u, free, P = _reference_tangent(linkage, q, lam, u, t)
    return J_u, free, np.concatenate([q[free], lam]), P


def discretization_error(
    linkage: Linkage,
    q: ArrayLike,
    u: ArrayLike | None = None,
    *,
    lam: ArrayLike | None = None,
    t: float = 0.0,
    quantity: str | Callable | None = None,
    length: float | None = None,
    equilibrium: bool = True,
) -> DiscretizationEstimate:
    """Estimate the discretisation error of an equilibrium ``q`` from its coefficients.

    The QoI errors of the models one and two orders down in every active mode,
    ``e1`` and ``e2``, are measured on their Galerkin solutions of the equilibrium
    linearised at ``q`` (one tangent stiffness; see :func:`choose_model`); under
    spectral (geometric) decay this model's error is about ``e1 * e1 / e2``. The
    points' integration error is estimated apart, by integrating the same q with
    twice the points (one more compile of the kinematics). An indicator, not a
    bound: on a planar cantilever with a tip force (orders 1-6 against an
    order-14 reference, tip poses) it was 0.25-5.8x the true error; on a soft rod
    hanging under its own weight at orders 10-14 (all six modes) 0.5-1.5x.

    Args:
        linkage: the model (soft divisions with LegendreBasis).
        q: an equilibrium ``(n_dof,)`` of ``linkage`` under ``u``.
        u: its actuation inputs (for the tangent stiffness).
        lam: its closed-loop multipliers (a :class:`StaticsSolution`'s ``lam``);
            default their least-squares values at ``q``.
        t: time for time-dependent loads [s].
        quantity: the QoI. None or ``"configuration"`` (default): world poses at
            ``PROBES + 1`` evenly spaced points of every soft division and at every
            link's tip (positions, and rotation angles times ``length``), and the
            closed-loop multipliers and prescribed coordinates' efforts as lengths
            (:func:`reaction_scales`); ``"tips"``: every link's tip pose; or a
            function ``(linkage, q) -> array`` [m].
        length: reference length [m]; default :func:`reference_length`.
        equilibrium: False when ``q`` is not an equilibrium (a state of a
            trajectory): the smaller models are then plain truncations of ``q``
            (no tangent, no reactions; an underestimate where modes couple).

    Returns:
        A :class:`DiscretizationEstimate`.
    """
    length = reference_length(linkage) if length is None else float(length)
    q = np.asarray(q, dtype=float)
    tangent = _equilibrium_tangent(linkage, q, u, lam, t) if equilibrium else None
    return _estimate(linkage, q, tangent, _Qoi(linkage, quantity, length))


def _estimate(linkage, q, tangent, qoi) -> DiscretizationEstimate:
    """The estimate of :func:`discretization_error` on the quantity ``qoi``.

    ``tangent`` as :func:`_equilibrium_tangent` returns it at ``q``, or None for
    plain truncations (then no reactions).
    """
    orders = division_orders(linkage)
    index = _coefficient_index(linkage)

    def smaller(down):  # state of the model with orders lowered by {(i, k, m): steps}
        lowered = {
            (i, k): tuple(o[m] - down.get((i, k, m), 0) for m in range(6))
            for (i, k), o in orders.items()
        }
        dropped = _dropped(index, lowered)
        if tangent is not None:
            return _galerkin(tangent, q, dropped)
        out = q.copy()
        out[dropped] = 0.0
        return out, None, None

    if tangent is None:
        state = (q, None, None)
    else:
        state = (q, tangent[2][len(tangent[1]) :], tangent[3][1])
    active = [(i, k, m) for (i, k), o in orders.items() for m in range(6) if o[m] >= 0]
    keys = [(i, k, MODE_NAMES[m]) for i, k, m in active]
    states = [smaller({key: 1}) for key in active]
    states.append(smaller(dict.fromkeys(active, 1)))  # top coefficient dropped
    states.append(smaller(dict.fromkeys(active, 2)))  # top two dropped
    errs = qoi.errors(*_stack(states), *state)
    # the model one order down is off by e1, two down by e2: under geometric decay
    # this one is off by about e1 * (e1 / e2)
    e1, e2 = float(errs[-2]), float(errs[-1])
    coefficients = e1 * min(1.0, e1 / e2) if e2 > 0 else e1
    finer = with_orders(
        linkage,
        orders,
        {(i, k): 2 * linkage.links[i - 1].divisions[k].n_gauss for i, k in orders},
    )
    fine = _Qoi(finer, qoi.quantity, qoi.length)
    if callable(qoi.quantity):
        points = float(qoi.against(fine, q, None, None, q, None, None)[0])
    else:
        points = qoi.kinematics(fine, q, q)
    return DiscretizationEstimate(
        error=max(coefficients, points),
        coefficients=coefficients,
        points=points,
        per_mode={key: float(e) for key, e in zip(keys, errs[:-2], strict=True)},
    )


def _stack(states):
    """``(qs, lams, effs)`` of a list of ``(q, lam, eff)`` (None stays None)."""
    qs = np.asarray([s[0] for s in states])
    lams = None if states[0][1] is None else np.asarray([s[1] for s in states])
    effs = None if states[0][2] is None else np.asarray([s[2] for s in states])
    return qs, lams, effs


# ------------------------------------------------------------------ choice
@dataclasses.dataclass(frozen=True)
class ModelChoice:
    """The model :func:`choose_model` picked, and how it was verified.

    Attributes:
        linkage: the chosen model.
        orders: ``{(link, division): six orders}``, ``-1`` for modes off.
        n_dof: its number of coordinates.
        q: its solution.
        error_estimate: QoI distance (relative) of its solution from the
            reference solution's.
        reference: the reference model.
        q_reference: the reference solution.
        reference_error: :func:`discretization_error` of the reference.
        num_solves: statics solves used (reference and verifications).
        seconds: wall time of the whole choice (compiles included).
        history: ``[(n_dof, truncation estimate, verified error)]`` per round.
        quantity: the name of the QoI the choice was made on.
        solution: the chosen model's :class:`~sorojax.StaticsSolution` (statics;
            None for a trajectory).
    """

    linkage: Linkage
    orders: dict
    n_dof: int
    q: np.ndarray
    error_estimate: float
    reference: Linkage
    q_reference: np.ndarray
    reference_error: float
    num_solves: int
    seconds: float
    history: tuple
    quantity: str = "configuration"
    solution: Any = None


def _dofs(orders) -> int:
    return sum(o + 1 for v in orders.values() for o in v if o >= 0)


def _greedy(cur, err, errors, modes, n_ref, target):
    """Raise orders until ``errors`` says the QoI error is below ``target``, then prune.

    Each round tries one and two more orders of every (division, mode) the
    choice may use, and the coupled moves one more order of every mode of a
    division and of a mode in every division; it keeps the candidate with the
    largest drop of log(error) per added coordinate; when none lowers it, every
    usable mode goes up by one. ``errors(list of orders dicts) -> array``
    evaluates all candidates at once.
    """
    keys = list(cur)

    def raised(moves):
        """``cur`` with ``{(key, mode): steps}`` applied, and the coordinates added."""
        cand, extra = dict(cur), 0
        for (key, m), step in moves.items():
            o = list(cand[key])
            new = min(o[m] + step, n_ref)
            extra += new - o[m]
            o[m] = new
            cand[key] = tuple(o)
        return cand, extra

    usable = [(key, m) for key in keys for m in range(6) if modes[m]]
    while err > target:
        open_ = [(key, m) for key, m in usable if cur[key][m] < n_ref]
        moves = [{km: step} for km in open_ for step in (1, 2)]
        moves += [{(key, m): 1 for k2, m in open_ if k2 == key} for key in keys]
        moves += [{(key, m): 1 for key, m2 in open_ if m2 == m} for m in range(6)]
        cands, added = [], []
        for mv in moves:
            cand, extra = raised(mv)
            if extra > 0 and cand not in cands:
                cands.append(cand)
                added.append(extra)
        if not cands:
            break
        errs = np.asarray(errors(cands))
        gains = (
            np.log(max(err, 1e-300)) - np.log(np.maximum(errs, 1e-300))
        ) / np.asarray(added)
        best = int(np.argmax(gains))
        if gains[best] <= 0:  # nothing helps by itself: raise everything
            cur = {
                key: tuple(
                    min(o + 1, n_ref) if modes[m] else o for m, o in enumerate(cur[key])
                )
                for key in keys
            }
            err = float(errors([cur])[0])
            continue
        cur, err = cands[best], float(errs[best])
    return _prune(cur, err, errors, target)


def _prune(cur, err, errors, target):
    """Lower orders one at a time while ``errors`` stays within ``target``.

    The forward greedy can overshoot (a coupled move, or an early order a later one
    makes redundant: the L-beam at 1e-3 L took 24 coordinates where 12 do); each
    pass tries every (division, mode) one order down (order 0 -> off) and keeps the
    lowest error among those within the target.
    """
    while True:
        cands = []
        for key, o in cur.items():
            for m in range(6):
                if o[m] >= 0:
                    low = list(o)
                    low[m] -= 1
                    cand = dict(cur)
                    cand[key] = tuple(low)
                    cands.append(cand)
        if not cands:
            return cur, err
        errs = np.asarray(errors(cands))
        best = int(np.argmin(errs))
        if errs[best] > target:
            return cur, err
        cur, err = cands[best], float(errs[best])


def _reference_model(linkage, tol, modes, length, reference_order, reference_points):
    """Checked arguments and the reference model of the model choice.

    Returns ``(modes, length, user orders, reference, points per division)``.
    """
    if not 0 < tol < 1:
        raise ValueError(f"tol = {tol!r}: give a relative tolerance in (0, 1).")
    modes = tuple(int(bool(m)) for m in modes)
    if len(modes) != 6 or not any(modes):
        raise ValueError(f"modes = {modes!r}: give six 0/1 flags, at least one 1.")
    length = reference_length(linkage) if length is None else float(length)
    user = division_orders(linkage)
    n_ref = int(reference_order)
    pts = 4 * n_ref + 8 if reference_points is None else int(reference_points)
    ref_orders = {key: tuple(n_ref if m else OFF for m in modes) for key in user}
    return modes, length, user, with_orders(linkage, ref_orders, pts), pts


def _dropped(index, orders) -> list[int]:
    """Indices in q of the coefficients above ``orders`` (``_coefficient_index``)."""
    return [j for (i, k, m, c), j in index.items() if c > orders[(i, k)][m]]


def _choose(
    linkage,
    user,
    ref_qoi,
    q_ref,
    truncated,
    errors,
    verify,
    ref_err,
    *,
    modes,
    tol,
    safety,
    max_rounds,
    cap,
    start,
) -> ModelChoice:
    """The rounds shared by :func:`choose_model` and its dynamics twin.

    Greedy orders against the proxy ``errors`` down to the target, points until the
    kinematics agree, then ``verify(chosen) -> (q, error, ok, solution)`` (one solve
    or simulation); above ``tol`` the target drops by the excess and a round
    follows.
    """
    reference = ref_qoi.linkage
    n_ref = max(o for v in division_orders(reference).values() for o in v)
    cur = {key: (OFF,) * 6 for key in user}
    err = float(errors([cur])[0])
    target = safety * tol
    history, chosen, q_c, verified, runs, sol = [], None, None, np.inf, 1, None
    for _ in range(max_rounds):
        cur, err = _greedy(cur, err, errors, modes, n_ref, target)
        chosen = _with_enough_points(linkage, cur, ref_qoi, truncated(cur), target, cap)
        runs += 1
        q_c, verified, ok, sol = verify(chosen)
        history.append((_dofs(cur), err, verified))
        if verified <= tol and ok:
            break
        target = target * min(0.5, tol / max(verified, 1e-300))
    # Trim: the safety margin can keep an order the tolerance does not need (a
    # follower-loaded rod's 3-coordinate model is off by 7.3e-4 L: within 1e-3 L
    # but not 0.7e-3 L); one more verification decides, with the reference's own
    # error counted twice (its estimate was 0.47x the truth on a hanging rod).
    trim = TRIM * tol - 2.0 * ref_err
    if verified <= tol and ok and trim > 0:
        cand, err_c = _prune(cur, np.inf, errors, trim)
        if _dofs(cand) < _dofs(cur):
            alt = _with_enough_points(
                linkage, cand, ref_qoi, truncated(cand), trim, cap
            )
            runs += 1
            q_a, verified_a, ok_a, sol_a = verify(alt)
            history.append((_dofs(cand), err_c, verified_a))
            if ok_a and verified_a <= trim:
                chosen, cur, q_c, verified, sol = alt, cand, q_a, verified_a, sol_a
    return ModelChoice(
        linkage=chosen,
        orders=dict(cur),
        n_dof=chosen.n_dof,
        q=q_c,
        error_estimate=verified,
        reference=reference,
        q_reference=q_ref,
        reference_error=ref_err,
        num_solves=runs,
        seconds=time.perf_counter() - start,
        history=tuple(history),
        quantity=ref_qoi.name,
        solution=sol,
    )


def _check_sensitive(ref_qoi, tangent, q_ref, index, orders_ref, state_ref, modes):
    """The QoI to choose with: ``ref_qoi``, or the configuration if it is blind.

    A quantity other than the default is compared with the configuration on
    Galerkin candidates of the reference: uniform orders 0-3 of ``modes`` and the
    reference one to four orders down, those within 0.1 (relative) of the
    reference on the configuration. A candidate is blind to the quantity when
    it changes by at most ``INSENSITIVE`` times the configuration's change ``e``,
    or by at most ``e^2`` (the proxy's own second-order error: a tip held by a
    closed loop is exact in every solved model but moves by ``~e^2`` in the
    linearised one, where a free tip's superconvergent error is ``~100 e^2``). If
    every candidate is blind (a held tip, a statically determinate reaction), the
    smallest model would pass: a warning names the quantity and the choice is made
    on the configuration.
    """
    if ref_qoi.name == "configuration":
        return ref_qoi
    conf = _Qoi(ref_qoi.linkage, "configuration", ref_qoi.length)
    ladder = [
        {key: tuple(k if m else OFF for m in modes) for key in orders_ref}
        for k in range(4)
    ]
    ladder += [
        {
            key: tuple(o - down if o >= 0 else o for o in v)
            for key, v in orders_ref.items()
        }
        for down in (1, 2, 3, 4)
    ]
    states = [_galerkin(tangent, q_ref, _dropped(index, c)) for c in ladder]
    stacked = _stack(states)
    e_q = ref_qoi.errors(*stacked, *state_ref)
    e_c = conf.errors(*stacked, *state_ref)
    # candidates off by more than 10 % are outside the linearisation's reach
    near = e_c <= 0.1
    blind = e_q[near] <= np.maximum(INSENSITIVE * e_c[near], e_c[near] ** 2)
    if near.any() and e_c[near].max() > 0 and np.all(blind):
        warnings.warn(
            f"choose_model: the quantity of interest {ref_qoi.name!r} changes by at "
            f"most {e_q[near].max():.1e} (relative) between the reference and "
            f"smaller models, where the configuration changes by up to "
            f"{e_c[near].max():.1e}: "
            "it cannot tell the models apart (the smallest model would pass). The "
            "choice is made on the whole configuration (quantity='configuration') "
            "instead.",
            InsensitiveQuantityWarning,
            stacklevel=3,
        )
        return conf
    return ref_qoi


def choose_model(
    linkage: Linkage,
    q0: ArrayLike | None = None,
    u: ArrayLike | None = None,
    *,
    tol: float = 1e-5,
    quantity: str | Callable | None = None,
    length: float | None = None,
    reference_order: int | None = None,
    reference_points: int | None = None,
    modes: tuple[int, ...] = (1, 1, 1, 1, 1, 1),
    safety: float = 0.7,
    max_rounds: int = 4,
    t: float = 0.0,
) -> ModelChoice:
    """Choose per division and per mode the Legendre orders a statics scene needs.

    1. Solve a reference model: every division with the ``modes`` (default all
       six) at ``reference_order`` and ``reference_points`` (default
       ``4 reference_order + 8``) points. By default the order starts at 12 and
       rises by 4 (to at most ``MAX_REFERENCE_ORDER``), each time solved again
       from the last, while the reference's own :func:`discretization_error` is
       above ``REFERENCE_SHARE * tol``.
    2. Greedily raise orders (from every mode off), each time the
       (division, mode) whose next one or two orders cut the QoI error most per
       added coordinate, until that error is below ``safety * tol``. A
       candidate's error is that of its Galerkin solution of the equilibrium
       linearised at the reference solution (a small least-squares solve with the
       reference's tangent; exact up to second order in the error), its QoI from
       the reference's kinematics; all candidates of a round are one vmapped
       forward kinematics call: no nonlinear solve.
    3. Double the chosen model's points until its kinematics of that solution
       agree with the reference's within the target.
    4. Solve the chosen model (from the reference solution, truncated) and
       measure its QoI distance from the reference. Above ``tol``: lower the
       target by the excess and continue from step 2 (at most ``max_rounds``
       solves).

    The QoI (``quantity``) is by default the whole configuration: the world poses
    at ``PROBES + 1`` evenly spaced points of every soft division and at every
    link's tip (positions, and rotation angles times ``length``), and the
    reactions of closed loops and prescribed coordinates as lengths
    (:func:`reaction_scales`). A quantity of the user's that does not change
    between the reference and its truncations (a tip held by a closed loop) is
    reported by an :class:`InsensitiveQuantityWarning` and replaced by the
    configuration.

    The result's ``error_estimate`` is the verified distance from the reference,
    which is the true error up to the reference's own (``reference_error``,
    reported).

    Args:
        linkage: the scene (soft divisions with LegendreBasis; their current orders
            only supply ``q0``'s values).
        q0: initial guess for ``linkage`` (transferred to the reference model).
        u: actuation inputs.
        tol: tolerance on the QoI relative to ``length``.
        quantity: None or ``"configuration"`` (default), ``"tips"`` (every link's
            tip pose alone), or a function ``(linkage, q) -> array`` [m].
        length: reference length [m]; default the longest link.
        reference_order: order of the reference model's modes; None (default)
            for the rising order of step 1.
        reference_points: its interior points per division.
        modes: the modes the choice may use (six 0/1 flags; e.g. ``(0, 0, 1, 0, 0,
            0)`` for a planar, inextensible rod).
        safety: the proxy's target as a fraction of ``tol`` (0.7: the linearised
            Galerkin proxy was within a few % of the verified error on the
            benchmark's scenes; a miss costs one more verification solve).
        max_rounds: most verification solves (one more for the final trim).
        t: time for time-dependent loads [s].

    Returns:
        A :class:`ModelChoice` (its ``solution`` is the chosen model's
        :class:`~sorojax.StaticsSolution`).

    Raises:
        ValueError: a division without LegendreBasis, bad ``tol``, ``modes`` or
            ``quantity``.
        RuntimeError: the reference solve fails.
    """
    start = time.perf_counter()
    rising = reference_order is None
    n_ref = REFERENCE_ORDER if rising else int(reference_order)
    q_prev, prev = q0, linkage
    while True:
        modes, length, user, reference, pts = _reference_model(
            linkage, tol, modes, length, n_ref, reference_points
        )
        q0_ref = (
            None if q_prev is None else transfer_coordinates(prev, q_prev, reference)
        )
        sol_ref = solve_statics(reference, q0_ref, u, t=t, warn_unstable=False)
        q_ref = np.asarray(sol_ref.q)
        # The reference's tangent at its solution: candidates are judged by their
        # Galerkin solution of the equilibrium linearised there (exact up to second
        # order in their error), not by plain truncation, which misses the coupling
        # of modes (a hanging rod's truncation error was 80x below its model's).
        tangent = _equilibrium_tangent(reference, q_ref, u, sol_ref.lam, t)
        ref_qoi = _Qoi(reference, quantity, length)
        ref_err = _estimate(reference, q_ref, tangent, ref_qoi).error
        if (
            not rising
            or ref_err <= REFERENCE_SHARE * tol
            or n_ref >= MAX_REFERENCE_ORDER
        ):
            break
        q_prev, prev = q_ref, reference
        n_ref += 4
    index = _coefficient_index(reference)
    state_ref = (q_ref, tangent[2][len(tangent[1]) :], tangent[3][1])
    checked = _check_sensitive(
        ref_qoi, tangent, q_ref, index, division_orders(reference), state_ref, modes
    )
    if checked is not ref_qoi:
        ref_qoi = checked
        ref_err = _estimate(reference, q_ref, tangent, ref_qoi).error

    def truncated(orders):
        return _galerkin(tangent, q_ref, _dropped(index, orders))[0]

    def errors(candidates):
        states = [_galerkin(tangent, q_ref, _dropped(index, c)) for c in candidates]
        return ref_qoi.errors(*_stack(states), *state_ref)

    def verify(chosen):
        sol = solve_statics(
            chosen,
            transfer_coordinates(reference, q_ref, chosen),
            u,
            t=t,
            warn_unstable=False,
            throw=False,
        )
        q_c = np.asarray(sol.q)
        qoi = _Qoi(chosen, ref_qoi.quantity, length)  # its own kinematics (points)
        err = float(
            qoi.against(ref_qoi, q_c, sol.lam[None], sol.efforts[None], *state_ref)[0]
        )
        return q_c, err, int(sol.result._value) == 0, sol

    return _choose(
        linkage,
        user,
        ref_qoi,
        q_ref,
        truncated,
        errors,
        verify,
        ref_err,
        modes=modes,
        tol=tol,
        safety=safety,
        max_rounds=max_rounds,
        cap=4 * pts,
        start=start,
    )


def solve_statics_adequate(
    linkage: Linkage,
    q0: ArrayLike | None = None,
    u: ArrayLike | None = None,
    *,
    tol: float = 1e-6,
    **choose_kwargs,
) -> ModelChoice:
    """Solve the statics of ``linkage`` at the model its tolerance needs.

    ``choose_model(linkage, q0, u, tol=tol, **choose_kwargs)``: a user who does not
    know GVS orders gives the scene (any orders: they only carry ``q0``) and a
    tolerance on the whole configuration (relative to the longest link), and gets
    the chosen model's solution, verified against a reference model:
    ``.solution`` (a :class:`~sorojax.StaticsSolution` of ``.linkage``),
    ``.orders``, ``.n_dof`` and ``.error_estimate``.

    It is a function apart from :func:`~sorojax.solve_statics` because choosing
    changes the model (its coordinates' number): it runs on the host, solving and
    compiling several models, so it cannot run under ``jit``, ``vmap`` or
    ``grad``; differentiate ``solve_statics`` of the chosen ``.linkage``.

    Example:
        ``res = sj.solve_statics_adequate(lk, tol=1e-6); res.solution.q``

    Returns:
        A :class:`ModelChoice`.
    """
    return choose_model(linkage, q0, u, tol=tol, **choose_kwargs)


def choose_model_dynamics(
    linkage: Linkage,
    t1: float,
    q0: ArrayLike | None = None,
    qd0: ArrayLike | None = None,
    *,
    tol: float = 1e-3,
    n_save: int = 21,
    quantity: str = "configuration",
    length: float | None = None,
    reference_order: int = 6,
    reference_points: int | None = None,
    modes: tuple[int, ...] = (1, 1, 1, 1, 1, 1),
    safety: float = 0.5,
    max_rounds: int = 3,
    **simulate_kwargs,
) -> ModelChoice:
    """Choose the Legendre orders a trajectory window ``[0, t1]`` needs.

    As :func:`choose_model`, on the QoI at ``n_save`` evenly spaced times (by
    default the configuration: poses at the probes of every soft division and at
    every link's tip; no reactions; ``"tips"`` for the tip poses alone): a
    reference model (``modes`` at ``reference_order``, ``4 order + 8`` points) is
    simulated; candidates are judged by *truncating* the reference trajectory
    (no linearised Galerkin proxy here, so the verification simulation, which
    tightens and repeats when above ``tol``, matters more); the points are doubled
    until the chosen kinematics agree; each round simulates the chosen model once.
    The time integration error must be well below ``tol``: pass tight ``rtol`` /
    ``atol`` (defaults here 1e-6 / 1e-8) and a ``solver`` in ``simulate_kwargs``.

    Returns:
        A :class:`ModelChoice` whose ``q`` and ``q_reference`` are trajectories
        ``(n_save, n_dof)``, ``num_solves`` counts simulations and
        ``reference_error`` is the reference's estimate at ``t1``.
    """
    from ..integrate import simulate  # statics and integrate are peers: no cycle

    start = time.perf_counter()
    if callable(quantity) or quantity not in QUANTITIES:
        raise ValueError(f"quantity = {quantity!r}: give one of {QUANTITIES}.")
    modes, length, user, reference, pts = _reference_model(
        linkage, tol, modes, length, reference_order, reference_points
    )
    simulate_kwargs.setdefault("rtol", 1e-6)
    simulate_kwargs.setdefault("atol", 1e-8)

    def moved(q, target):
        return None if q is None else transfer_coordinates(linkage, q, target)

    traj = simulate(
        reference,
        t1,
        moved(q0, reference),
        moved(qd0, reference),
        n_save=n_save,
        **simulate_kwargs,
    )
    q_ref = np.asarray(traj.q)
    index = _coefficient_index(reference)
    ref_qoi = _Qoi(reference, quantity, length)
    g_ref = ref_qoi.poses(q_ref)

    def truncated(orders):
        q = q_ref.copy()
        q[:, _dropped(index, orders)] = 0.0
        return q

    def errors(candidates):
        qs = np.concatenate([truncated(c) for c in candidates])
        g = ref_qoi.poses(qs)
        g = g.reshape(len(candidates), len(q_ref), *g.shape[1:])
        return pose_distance(g, g_ref[None], length).max(axis=(1, 2))

    def verify(chosen):
        tr = simulate(
            chosen,
            t1,
            transfer_coordinates(reference, q_ref[0], chosen),
            transfer_coordinates(reference, np.asarray(traj.qd)[0], chosen),
            n_save=n_save,
            throw=False,
            **simulate_kwargs,
        )
        q_c = np.asarray(tr.q)
        err = _Qoi(chosen, quantity, length).kinematics(ref_qoi, q_c, q_ref)
        return q_c, err, int(tr.result._value) == 0, None

    ref_err = _estimate(reference, np.asarray(q_ref[-1]), None, ref_qoi).error
    return _choose(
        linkage,
        user,
        ref_qoi,
        q_ref,
        truncated,
        errors,
        verify,
        ref_err,
        modes=modes,
        tol=tol,
        safety=safety,
        max_rounds=max_rounds,
        cap=4 * pts,
        start=start,
    )
