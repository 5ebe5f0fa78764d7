"""Stability of a static equilibrium: the reduced tangent stiffness and its spectrum.

At an equilibrium of ``r(q, mu) = K q - F(q) - Q_act(q, u) - A(q)^T mu = 0``,
``e(q) = 0`` the second variation of the potential on the constraint manifold is
``Z^T H Z``, with ``H = dr/dq`` at fixed multipliers (so it holds the constraint-
curvature term ``-sum_i mu_i d^2 e_i / dq^2``), ``Z`` a basis of the null space of
``A = de/dq`` and prescribed coordinates held (their rows and columns left out). The
equilibrium is stable (a local minimum of the potential on the manifold) when no
eigenvalue of ``Z^T H Z`` is negative (zero ones are neutral directions: symmetries
or critical points), unstable when one is; the number of negative eigenvalues is its
Morse index (Koiter's energy criterion;
e.g. Thompson & Hunt 1973, ch. 2). This reduced Hessian depends only on the manifold,
not on how its constraint functions are written (the multipliers absorb that).

The spectrum is taken in the Jacobi-scaled coordinates of the statics solver
(``q = D y`` with ``D = diag(K_ff)^(-1/2)``): the eigenvalues are then dimensionless,
relative to each coordinate's own stiffness (a straight elastic rod without load has
eigenvalues near 1), and their signs (the inertia) are those of ``Z^T H Z`` by
Sylvester's law.

Non-conservative loads (follower wrenches, a dead moment in 3D, custom wrenches or
actuation that do not derive from a potential) make ``H`` non-symmetric. The count
is then taken on the real parts of ``H``'s own eigenvalues (on CPU; other backends
use the symmetric part, which can report instability where there is none): a real
eigenvalue through zero is divergence, but static tests can never see flutter
(complex eigenvalues of the linearised dynamics, e.g. Beck's column): for such
loads "stable" means "no divergence found", and dynamic stability needs the
eigenvalues of the linearised equations of motion.
"""

import jax
import jax.numpy as jnp
from jaxtyping import Array


class UnstableEquilibriumWarning(RuntimeWarning):
    """A static solve converged, but to an unstable equilibrium."""


# Eigenvalues within this fraction of the largest |eigenvalue| count as zero
# (neither negative nor a proof of stability): round-off of the scaled tangent.
ZERO_TOL = 1e-9


def reduced_tangent_spectrum(J, n_free: int, scale) -> tuple[Array, Array, Array]:
    """Spectrum of the tangent stiffness restricted to the constraint manifold.

    Args:
        J: Jacobian of the statics solver's scaled system, shape
            ``(n_free + n_c, n_free + n_c)``: rows ``(scale * r_free, e)``, columns
            ``(q_free, mu)`` (the top-left block is ``diag(scale) dr/dq``).
        n_free: number of free (not prescribed) coordinates.
        scale: the positive row scale of ``r_free``, shape ``(n_free,)``.

    Returns:
        ``(eigenvalues, vectors, n_manifold)``: eigenvalues ascending, shape
        ``(n_free,)``; the first ``n_manifold`` belong to the manifold (the rest are
        ``+inf`` placeholders for the constrained directions); ``vectors[:, i]`` the
        matching direction in free coordinates q (not normalised in q); ``n_manifold``
        the manifold's dimension (``n_free`` minus the constraint rank).
    """
    J = jax.lax.stop_gradient(J)
    if n_free == 0:
        empty = jnp.zeros((0,), J.dtype)
        return empty, jnp.zeros((0, 0), J.dtype), jnp.asarray(0)
    d = jnp.sqrt(scale)
    # diag(d) H diag(d) with H = diag(1/scale) J_qq: the scaled second variation
    Hs = J[:n_free, :n_free] * (d[None, :] / d[:, None])
    n_c = J.shape[0] - n_free
    if n_c == 0:
        lam, V = _eigen(Hs)
        return lam, d[:, None] * V, jnp.asarray(n_free)
    A = J[n_free:, :n_free] * d[None, :]  # constraint Jacobian in y = q / d
    _, s, vt = jnp.linalg.svd(A, full_matrices=True)
    s_full = jnp.zeros(n_free, J.dtype).at[: s.shape[0]].set(s[:n_free])
    in_range = s_full > 1e-9 * jnp.maximum(s_full[0], 1e-300)
    n_manifold = n_free - jnp.sum(in_range)
    # Rotate to (range of A^T, null space of A); the range block is replaced by a
    # shift above every eigenvalue of Hs, so the lowest eigenvalues are those of
    # Z^T Hs Z in ascending order.
    Hr = vt @ Hs @ vt.T
    shift = 1.0 + 2.0 * jnp.sqrt(jnp.sum(Hs * Hs))
    keep = ~in_range
    Hr = jnp.where(keep[:, None] & keep[None, :], Hr, 0.0) + jnp.diag(
        jnp.where(keep, 0.0, shift)
    )
    lam, W = _eigen(Hr)
    idx = jnp.arange(n_free)
    lam = jnp.where(idx < n_manifold, lam, jnp.inf)
    return lam, d[:, None] * (vt.T @ W), n_manifold


def _eigen(H) -> tuple[Array, Array]:
    """Ascending eigenvalues of ``H`` (real parts) and the symmetric part's vectors.

    Conservative loads make ``H`` symmetric (to round-off): ``eigh``. Otherwise
    (follower loads; a dead moment in 3D) the symmetric part's eigenvalues can be
    negative where no eigenvalue of ``H`` is (a rod rolled into a circle by a
    follower end moment: -0.33 against real parts >= 0.58), so the real parts of
    ``H``'s own eigenvalues are used: LAPACK's ``geev``, which JAX provides on CPU
    only; on other backends the symmetric part's (documented limitation).
    """
    sym = 0.5 * (H + H.T)
    lam_s, V = jnp.linalg.eigh(sym)
    if jax.default_backend() != "cpu":
        return lam_s, V
    size = jnp.max(jnp.abs(H), initial=0.0)
    asym = jnp.max(jnp.abs(H - H.T), initial=0.0) > 1e-8 * jnp.maximum(size, 1e-300)

    def general(H_):
        return jnp.sort(jnp.real(jnp.linalg.eig(H_)[0]))

    lam = jax.lax.cond(asym, general, lambda H_: lam_s, H)
    return lam, V


def stability_summary(eigenvalues, n_manifold) -> tuple[Array, Array, Array]:
    """``(stable, n_negative, min_eigenvalue)`` from :func:`reduced_tangent_spectrum`.

    ``n_negative`` counts eigenvalues below ``-ZERO_TOL`` times the largest finite
    |eigenvalue|; ``stable`` means none is (and all are finite). Eigenvalues within
    that tolerance of zero are neutral directions, not instabilities: a symmetry
    (a buckled rod of circular section clamped at both ends can be turned about the
    line through its ends at no cost), an unloaded mechanism, or a critical point;
    ``min_eigenvalue`` tells them apart from strict minima. With no free direction
    left (``n_manifold = 0``) the equilibrium is stable and ``min_eigenvalue`` is
    ``+inf``.
    """
    if eigenvalues.shape[0] == 0:
        return jnp.asarray(True), jnp.asarray(0), jnp.asarray(jnp.inf)
    finite = jnp.isfinite(eigenvalues)
    big = jnp.max(jnp.where(finite, jnp.abs(eigenvalues), 0.0), initial=0.0)
    tol = ZERO_TOL * jnp.maximum(big, 1e-300)
    n_negative = jnp.sum(finite & (eigenvalues < -tol))
    lam_min = jnp.where(n_manifold > 0, eigenvalues[0], jnp.inf)
    stable = (n_negative == 0) & ~jnp.any(jnp.isnan(eigenvalues))
    return stable, n_negative, lam_min
