"""Equilibrium paths by pseudo-arclength continuation: stability, folds, bifurcations.

A *family* of linkages ``p -> linkage(p)`` (a load, an input, any physical parameter:
whatever the function builds from ``p``) has equilibria ``f(x, p) = 0`` with
``x = (q_free, mu)`` the statics solver's unknowns and ``f`` its Jacobi-scaled rows
(:func:`~sorojax.statics._solve.scaled_equilibrium`). The path through them is
followed in the arclength ``s`` of ``z = (x, p)`` (Keller 1977; e.g. Allgower &
Georg 2003, ch. 2; Seydel 2010, ch. 4):

- *predictor* ``z + ds t``, with ``t`` the unit tangent (``[f_x f_p] t = 0``,
  oriented like the previous one);
- *corrector*: Newton's method on ``f(z) = 0`` and ``t . W (z - z_pred) = 0``
  (bordered system; ``W`` weighs the coordinates by 1, the multipliers by 0 and the
  parameter by ``1 / |p1 - p0|^2``), which passes limit points (folds) where the
  load cannot be increased;
- *step control*: ``ds`` grows after fast corrections, halves after slow or failed
  ones or a tangent turning by more than ~25 degrees;
- *stability* of every point: the spectrum of the tangent stiffness on the
  constraint manifold (:mod:`~sorojax.statics._stability`); a change of the number of
  negative eigenvalues between two points is a critical point, located by the
  secant (Illinois) method on the eigenvalue that crosses zero, and classified as a
  *limit point* when the parameter turns back there, a *bifurcation* otherwise;
- *branch switching* at a bifurcation: the predictor follows the critical
  eigenvector (made orthogonal to the path's tangent) onto the crossing branch.

Each corrector (and its spectrum and next tangent) is one compiled program per
family and linkage structure; the loop over points runs in Python.
"""

import concurrent.futures
import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike

from .._jit import _bound_arguments, jit
from ..dynamics._eom import as_inputs
from ..model._linkage import Linkage
from ..model._precompute import precompute
from ._solve import _row_scale, free_coordinates, scaled_equilibrium, solve_statics
from ._stability import reduced_tangent_spectrum, stability_summary


@dataclasses.dataclass(frozen=True)
class CriticalPoint:
    """A limit point or bifurcation found on an equilibrium path.

    Attributes:
        kind: ``"limit"`` (fold: the parameter turns back) or ``"bifurcation"``.
        p: parameter value.
        q: coordinates ``(n_dof,)``.
        lam: closed-loop multipliers ``(n_constraints,)``.
        mode: critical direction in q, ``(n_dof,)``, max-norm 1 (the eigenvector of
            the eigenvalue crossing zero; buckling mode at a bifurcation).
        index: index of this point in the path's arrays.
        multiplicity: number of eigenvalues crossing zero together (2 for the
            double buckling eigenvalue of a rod of circular section bending in
            both planes).
        n_negative: negative eigenvalues just before and after, along the path.
    """

    kind: str
    p: float
    q: np.ndarray
    lam: np.ndarray
    mode: np.ndarray
    index: int
    multiplicity: int
    n_negative: tuple[int, int]


@dataclasses.dataclass(frozen=True)
class EquilibriumPath:
    """Equilibria along a path, in order of arclength.

    Attributes:
        p: parameter values ``(n_points,)``.
        q: coordinates ``(n_points, n_dof)``.
        lam: closed-loop multipliers ``(n_points, n_constraints)``.
        stable: ``(n_points,)``, no negative eigenvalue of the reduced tangent
            stiffness (:class:`~sorojax.StaticsSolution` ``stable``).
        n_negative: ``(n_points,)`` number of negative eigenvalues.
        min_eigenvalue: ``(n_points,)`` smallest eigenvalue (dimensionless).
        branch: ``(n_points,)`` 0 on the path from the start, 1 after a switch at
            a bifurcation.
        critical: the limit points and bifurcations found, in order (each also a
            point of the arrays, at its ``index``).
        status: ``"reached p1"``, ``"max_points"``, ``"left the range"`` (the path
            came back past ``p0 - (p1 - p0)``) or ``"step too small: ..."`` (the
            corrector failed at ``ds_min``).
        num_corrections: corrector runs (each a few Newton iterations), including
            rejected steps and the location of critical points.
    """

    p: np.ndarray
    q: np.ndarray
    lam: np.ndarray
    stable: np.ndarray
    n_negative: np.ndarray
    min_eigenvalue: np.ndarray
    branch: np.ndarray
    critical: tuple[CriticalPoint, ...]
    status: str
    num_corrections: int

    @property
    def limit_points(self) -> tuple[CriticalPoint, ...]:
        """The critical points of kind ``"limit"``."""
        return tuple(c for c in self.critical if c.kind == "limit")

    @property
    def bifurcations(self) -> tuple[CriticalPoint, ...]:
        """The critical points of kind ``"bifurcation"``."""
        return tuple(c for c in self.critical if c.kind == "bifurcation")


def _member(family, p, u):
    """``(linkage, u)`` of the family at ``p`` (``u`` given, or from the family).

    A bare Linkage is its own family: ``p`` is then the load factor (below).
    """
    if isinstance(family, Linkage):
        return family, u
    out = family(p)
    if isinstance(out, Linkage):
        return out, u
    linkage, u_p = out
    return linkage, u_p


def _rows(family, u, q_p0, t, z):
    """Scaled equilibrium rows at ``z = (x, p)`` and the row scale of ``r_free``.

    For a Linkage ``family``, ``p`` is the statics' load factor: external loads and
    actuation are scaled by ``p``, prescribed coordinates go from ``q_p0`` (p = 0)
    to their inputs (p = 1).
    """
    x, p = z[:-1], z[-1]
    linkage, u_p = _member(family, p, u)
    data = precompute(linkage)
    u_p = as_inputs(linkage, u_p, z.dtype)
    qi, ui = linkage.prescribed
    if isinstance(family, Linkage):
        lam = p
        q_p = q_p0 + p * (u_p[ui] - q_p0) if len(qi) else None
    else:
        lam = 1.0
        q_p = u_p[ui] if len(qi) else None
    f, _ = scaled_equilibrium(linkage, data, x, t, lam, u_p, q_p)
    return f, _row_scale(data.K)[free_coordinates(linkage)]


@jit
def _correct(family, u, q_p0, t, z_pred, t_w, *, max_iter: int, tol: float):
    """Newton on ``f(z) = 0``, ``t_w . (z - z_pred) = 0`` from ``z_pred``.

    Returns ``(z, converged, iterations, eigenvalues, vectors, (stable,
    n_negative, min_eigenvalue), tangent, J)``: the spectrum of the reduced tangent
    stiffness and its summary, the tangent
    (``tangent . t_w = 1``) and the Jacobian ``df/dz``, all from the last
    evaluation.
    """

    def rows_and_aux(z_):
        f, scale = _rows(family, u, q_p0, t, z_)
        return f, (f, scale)

    # Jitted: the shape probe below and the loop body share one trace.
    @jax.jit
    def evaluate(z):
        J, (f, scale) = jax.jacfwd(rows_and_aux, has_aux=True)(z)
        return f, scale, J

    def bordered(f, J, z):
        G = jnp.concatenate([f, (t_w @ (z - z_pred))[None]])
        JG = jnp.concatenate([J, t_w[None, :]], axis=0)
        return G, JG

    # One evaluation (rows and Jacobian) per pass, at the top of the loop body: the
    # program holds one copy of it (an evaluation before the loop and one in its
    # body compiled it twice). A pass evaluates at z and, while Newton goes on
    # (not converged, under max_iter, finite), takes the step from z; the pass
    # after a converged step only evaluates there (the step is still taken), so
    # f, scale and J are those at the returned z.
    def body(c):
        z, it, conv, ok_prev, *_ = c
        f, scale, J = evaluate(z)
        finite = jnp.all(jnp.isfinite(f)) & jnp.all(jnp.isfinite(J)) & ok_prev
        go = ~conv & (it < max_iter) & finite
        G, JG = bordered(f, J, z)
        dz = jnp.linalg.lstsq(JG, G)[0]
        ok = jnp.all(jnp.isfinite(dz))
        # converged at z when the rows and the step from z are small
        conv_z = (jnp.max(jnp.abs(G)) <= tol) & (
            jnp.max(jnp.abs(dz) / (1.0 + jnp.abs(z))) <= tol
        )
        return (
            jnp.where(go & ok, z - dz, z),
            jnp.where(go, it + 1, it),
            jnp.where(go, conv_z, conv),
            jnp.where(go, ok, ok_prev),
            f,
            scale,
            J,
            finite,
            go,
        )

    f0, scale0, J0 = (
        jnp.zeros(a.shape, a.dtype) for a in jax.eval_shape(evaluate, z_pred)
    )
    true = jnp.asarray(True)
    z, it, conv, _, f, scale, J, finite, _ = jax.lax.while_loop(
        lambda c: c[-1],
        body,
        (z_pred, jnp.asarray(0), jnp.asarray(False), true, f0, scale0, J0, true, true),
    )
    G, JG = bordered(f, J, z)
    conv = conv & finite
    nf = scale.shape[0]
    lam, vecs, n_man = reduced_tangent_spectrum(J[:, :-1], nf, scale)
    rhs = jnp.zeros(JG.shape[0], z.dtype).at[-1].set(1.0)
    tangent = jnp.linalg.lstsq(JG, rhs)[0]
    summary = stability_summary(lam, n_man)
    return z, conv, it, lam, vecs, summary, tangent, J


def _start(family, p0, p1, q0, u):
    """``(linkage at p0, its inputs, q0, prescribed q0)`` after the checks."""
    if p0 == p1:
        raise ValueError(f"p0 = p1 = {p0!r}: give two different parameter values.")
    lk0, u0 = _member(family, jnp.asarray(p0, dtype=float), u)
    n = lk0.n_dof
    q0 = jnp.zeros(n) if q0 is None else jnp.asarray(q0, dtype=float)
    if q0.shape != (n,):
        raise ValueError(f"q0 has shape {q0.shape}; this linkage needs ({n},).")
    return lk0, u0, q0, q0[lk0.prescribed[0]]


def continuation(
    family: Linkage | Callable[[ArrayLike], Linkage | tuple[Linkage, ArrayLike]],
    p0: float,
    p1: float,
    q0: ArrayLike | None = None,
    u: ArrayLike | None = None,
    *,
    t: float = 0.0,
    ds: float = 0.05,
    ds_min: float = 1e-6,
    ds_max: float = 0.25,
    max_points: int = 300,
    switch_branch: bool = False,
    branch_direction: int = 1,
    tol: float = 1e-10,
    max_iter: int = 12,
) -> EquilibriumPath:
    """Trace the equilibria of ``family(p)`` from ``p0`` towards ``p1``.

    Pseudo-arclength continuation (module docstring): follows the path through limit
    points, reports the stability of every point, finds limit points and
    bifurcations (a change in the number of negative eigenvalues of the reduced
    tangent stiffness) and locates them precisely, and with ``switch_branch``
    leaves the path at its first bifurcation onto the crossing branch (e.g. from
    the straight column onto the buckled one).

    Example::

        def column(P):  # a compressive dead load P at the tip
            return sj.Linkage(rod, point_wrenches=[
                sj.PointWrench(1, jnp.stack([0.0, 0, 0, -P, 0, 0]))])

        path = sj.continuation(column, 0.0, 2.0 * P_euler, switch_branch=True)
        path.bifurcations[0].p  # the buckling load
        sorojax.viz.plot_equilibrium_path(path, lambda q: ...)

    Args:
        family: a :class:`~sorojax.Linkage`, whose *load factor* is then ``p``
            (gravity, point and custom wrenches and actuation inputs times ``p``,
            prescribed coordinates moved from their ``q0`` values at ``p = 0`` to
            their inputs at ``p = 1``, as in :func:`~sorojax.solve_statics`'s load
            stepping); or ``p -> Linkage`` or ``p -> (Linkage, u)``, a pure JAX
            function of the scalar ``p`` (with ``jnp`` where ``p`` enters, so that
            ``df/dp`` comes by autodiff) for any parameter, every member sharing
            one structure. The compiled corrector is reused for linkages of the
            same structure, and for the same function object (a new lambda per
            call compiles again).
        p0: start value. For a Linkage the first point is Newton's method at load
            factor ``p0`` from ``q0`` (give a nearby ``q0`` if ``p0 != 0``); for a
            function, ``solve_statics(family(p0), q0, u)`` (load stepping).
        p1: end value (the path stops when it passes ``p1``, with a last point at
            exactly ``p1``). Past a limit point the parameter runs back; the path
            may go beyond ``p0`` (a snap-through passes through negative loads)
            down to ``p0 - (p1 - p0)``, where it stops.
        q0: initial guess at ``p0`` ``(n_dof,)`` (default zeros).
        u: actuation inputs (used when ``family`` returns a bare Linkage).
        t: time at which time-dependent loads are evaluated [s].
        ds: first arclength step, in the norm of the free coordinates (~rad) and of
            ``(p - p0) / |p1 - p0|``.
        ds_min: smallest step before giving up.
        ds_max: largest step.
        max_points: most points on the path.
        switch_branch: at the first bifurcation, continue on the crossing branch
            (the critical eigenvector's direction) instead of the current one.
        branch_direction: ``+1`` or ``-1``: which side of the crossing branch (the
            mode is normalised with its largest component positive).
        tol: corrector tolerance (scaled rows and relative step).
        max_iter: corrector iterations before a step is rejected.

    Returns:
        An :class:`EquilibriumPath`. Its points are not differentiable (the path is
        computed on the host); differentiate a point by calling
        :func:`~sorojax.solve_statics` at its ``p`` with ``q0`` its ``q``
        (implicit-function gradients where the point is not critical).

    Raises:
        ValueError: ``p0 == p1``, ``branch_direction`` not +-1, a bad ``q0``.
        RuntimeError: the start point does not converge.
    """
    if branch_direction not in (1, -1):
        raise ValueError(f"branch_direction = {branch_direction!r}: give +1 or -1.")
    lk0, u0, q0, q_p0 = _start(family, p0, p1, q0, u)
    load_factor = isinstance(family, Linkage)
    n = lk0.n_dof
    qi, ui = lk0.prescribed
    u_full = np.asarray(as_inputs(lk0, u0, q0.dtype))
    free = free_coordinates(lk0)
    nf, n_c = len(free), lk0.n_constraints
    if load_factor:  # the start: Newton at the load factor p0 from q0
        q_fixed = np.asarray(q0)
        x0 = np.concatenate([q_fixed[free], np.zeros(n_c)])
    else:  # the start: solve_statics (load stepping) at p0
        sol = solve_statics(lk0, q0, u0, t=t, warn_unstable=False)
        q_fixed = np.asarray(sol.q)  # prescribed coordinates stay these
        x0 = np.concatenate([q_fixed[free], np.asarray(sol.lam)])
    span = float(p1) - float(p0)
    direction = 1.0 if span > 0 else -1.0
    w = np.concatenate([np.ones(nf), np.zeros(n_c), [1.0 / span**2]])
    u_arr = None if u is None else jnp.asarray(u, dtype=float)
    tt = jnp.asarray(t, dtype=float)
    counter = [0]

    def correct(z_pred, t_w):
        counter[0] += 1
        out = _correct(
            family,
            u_arr,
            q_p0,
            tt,
            jnp.asarray(z_pred),
            jnp.asarray(t_w),
            max_iter=max_iter,
            tol=tol,
        )
        z, conv, it, lam, vecs, summary, tan, J = jax.device_get(out)
        stable, n_neg, lam_min = summary
        tan = tan / np.sqrt(tan @ (w * tan))
        return dict(
            z=z,
            ok=bool(conv),
            it=int(it),
            lam=lam,
            vecs=vecs,
            tan=tan,
            stable=bool(stable),
            n_neg=int(n_neg),
            lam_min=float(lam_min),
            J=J,
        )

    def q_of(z):
        q = q_fixed.copy()
        q[free] = z[:nf]
        if load_factor and len(qi):
            q[qi] = np.asarray(q_p0) + z[-1] * (u_full[ui] - np.asarray(q_p0))
        return q

    # the start point and its tangent towards p1
    z0 = np.concatenate([x0, [p0]])
    e_p = np.zeros(nf + n_c + 1)
    e_p[-1] = direction / abs(span)
    cur = correct(z0, e_p)
    if not cur["ok"]:
        raise RuntimeError(
            f"continuation: Newton's method did not converge at the start p0 = {p0} "
            "from q0: give a q0 closer to that equilibrium (e.g. from solve_statics)."
        )
    points = [(cur, 0)]
    critical: list[CriticalPoint] = []
    branch = 0
    switched = False
    status = "max_points"
    step = float(ds)

    def add_critical(kind, pt, n_before, n_after, mode):
        z = pt["z"]
        m = np.zeros(n)
        m[free] = mode
        m = m / np.max(np.abs(m))
        critical.append(
            CriticalPoint(
                kind=kind,
                p=float(z[-1]),
                q=q_of(z),
                lam=z[nf : nf + n_c].copy(),
                mode=m,
                index=len(points) - 1,
                multiplicity=abs(n_after - n_before),
                n_negative=(n_before, n_after),
            )
        )

    def locate(a, b, h):
        """Critical point between ``a`` and ``b`` (arclength h from a)."""
        na, nb = a["n_neg"], b["n_neg"]
        k = min(na, nb)  # index of the eigenvalue that crosses zero
        t_w = w * a["tan"]

        def g(pt):
            return float(pt["lam"][k])

        lo, hi, g_lo, g_hi = 0.0, h, g(a), g(b)
        best = b
        side = 0
        for _ in range(60):
            s = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
            if not lo < s < hi:
                s = 0.5 * (lo + hi)
            pt = correct(a["z"] + s * a["tan"], t_w)
            if not pt["ok"]:
                s = 0.5 * (lo + hi)
                pt = correct(a["z"] + s * a["tan"], t_w)
            gs = g(pt)
            best = pt
            if abs(gs) <= 1e-13 or hi - lo <= 1e-12 * max(h, 1.0):
                break
            if (gs > 0) == (g_lo > 0):
                lo, g_lo = s, gs
                if side == -1:
                    g_hi *= 0.5  # Illinois
                side = -1
            else:
                hi, g_hi = s, gs
                if side == 1:
                    g_lo *= 0.5
                side = 1
        return best, k

    while len(points) < max_points:
        pt_prev = points[-1][0]
        z_pred = pt_prev["z"] + step * pt_prev["tan"]
        new = correct(z_pred, w * pt_prev["tan"])
        turn = float(new["tan"] @ (w * pt_prev["tan"])) if new["ok"] else -1.0
        if not new["ok"] or new["it"] > 6 or turn < 0.9:
            if step <= ds_min:
                p_at = float(pt_prev["z"][-1])
                status = f"step too small: the corrector failed at p = {p_at:.6g}"
                break
            step = max(step / 2, ds_min)
            continue
        if new["n_neg"] != pt_prev["n_neg"]:
            found, k = locate(pt_prev, new, step)
            fold = np.sign(pt_prev["tan"][-1]) != np.sign(new["tan"][-1])
            kind = "limit" if fold else "bifurcation"
            points.append((found, branch))
            add_critical(
                kind,
                found,
                pt_prev["n_neg"],
                new["n_neg"],
                found["vecs"][:, k],
            )
            if kind == "bifurcation" and switch_branch and not switched:
                switched = True
                branch += 1
                phi = np.zeros(nf + n_c + 1)
                vec = found["vecs"][:, k]
                vec = vec / vec[np.argmax(np.abs(vec))] * branch_direction
                phi[:nf] = vec
                # multipliers along the mode: keep the equilibrium rows linear-zero
                if n_c:
                    J = found["J"]
                    phi[nf : nf + n_c] = np.linalg.lstsq(
                        J[:nf, nf : nf + n_c], -J[:nf, :nf] @ vec, rcond=None
                    )[0]
                tan = phi - (phi @ (w * found["tan"])) * found["tan"]
                tan = tan / np.sqrt(tan @ (w * tan))
                points[-1] = (dict(found, tan=tan), branch)
                continue
        points.append((new, branch))
        p_new = float(new["z"][-1])
        if (p_new - float(p1)) * direction >= 0:
            # last point exactly at p1
            a = pt_prev["z"]
            frac = (float(p1) - a[-1]) / (p_new - a[-1])
            z_end = a + frac * (new["z"] - a)
            end = correct(z_end, e_p)
            if end["ok"]:
                points[-1] = (end, branch)
            status = "reached p1"
            break
        if (p_new - float(p0)) * direction < -abs(span):
            status = "left the range"
            break
        if new["it"] <= 3:
            step = min(step * 1.5, ds_max)

    def stack(key, fn=lambda x: x):
        return np.asarray([fn(pt[key]) for pt, _ in points])

    return EquilibriumPath(
        p=stack("z", lambda z: float(z[-1])),
        q=stack("z", q_of),
        lam=stack("z", lambda z: z[nf : nf + n_c]).reshape(len(points), n_c),
        stable=stack("stable"),
        n_negative=stack("n_neg"),
        min_eigenvalue=stack("lam_min"),
        branch=np.asarray([b for _, b in points]),
        critical=tuple(critical),
        status=status,
        num_corrections=counter[0],
    )


def prepare_continuation(*args, **kwargs) -> concurrent.futures.Future | None:
    """Compile the corrector of ``continuation(...)`` (same arguments) in a thread.

    :func:`sorojax.prepare` with :func:`continuation`: the corrector's program (one
    per structure and family function) is traced and lowered here and compiled in a
    worker thread, and for a family function the start's ``solve_statics`` too;
    the later call waits for them instead of compiling. No point of the path is
    computed. Returns the corrector compile's future (None inside a trace, or when
    it is compiled or prepared already).
    """
    a = _bound_arguments(continuation, args, kwargs)
    family, u, t = a["family"], a["u"], jnp.asarray(a["t"], dtype=float)
    lk0, u0, q0, q_p0 = _start(family, a["p0"], a["p1"], a["q0"], u)
    if not isinstance(family, Linkage):  # its start solves the statics at p0
        solve_statics.prepare(lk0, q0, u0, t=a["t"], warn_unstable=False)
    nz = len(free_coordinates(lk0)) + lk0.n_constraints + 1
    z = np.zeros(nz)
    return _correct.prepare(
        family,
        None if u is None else jnp.asarray(u, dtype=float),
        q_p0,
        t,
        jnp.asarray(z),
        jnp.asarray(z),
        max_iter=a["max_iter"],
        tol=a["tol"],
    )


continuation.prepare = prepare_continuation
