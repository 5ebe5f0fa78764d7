"""Result codes and solution containers returned by the solvers.

Solvers never return silent NaNs: each solution carries a ``RESULTS`` code, and entry
points take ``throw`` (raise on failure) as optimistix and diffrax do.
"""

import equinox as eqx
from jaxtyping import Array, Float, Int


class RESULTS(eqx.Enumeration):
    """Outcome of a sorojax solve."""

    successful = ""
    max_steps_reached = "The solver reached its maximum number of steps."
    nonlinear_divergence = (
        "The nonlinear solver diverged or produced non-finite values."
    )
    singular = "A linear solve met a singular matrix."
    failed = "The solver failed (see the underlying optimistix/diffrax result)."


class StaticsSolution(eqx.Module):
    """Equilibrium found by :func:`sorojax.statics.solve_statics`.

    Attributes:
        q: generalised coordinates at equilibrium, shape ``(n_dof,)``.
        residual_norm: max-norm of the equilibrium residual ``K q - F(q) - B u`` at
            ``q`` (units of the generalised forces: N m for angular coordinates, N
            for linear joint coordinates).
        num_steps: Newton (or trust-region) iterations used, summed over load steps.
        result: a :class:`RESULTS` code; ``RESULTS.successful`` when converged.
        efforts: generalised efforts of the prescribed joint coordinates (in the
            order of ``Linkage.prescribed``) that hold them [N m or N].
        lam: closed-loop multipliers (constraint wrench components, one per row;
            the minimum-norm choice where rows are redundant).
        constraint_error: max-norm of the closed-loop errors e(q).
        constraint_rank: numerical rank of the constraint Jacobian with respect to
            the free (not prescribed) coordinates (less than
            ``Linkage.n_constraints`` when rows are redundant, e.g. a planar loop).
    """

    q: Float[Array, " n_dof"]
    residual_norm: Float[Array, ""]
    num_steps: Int[Array, ""]
    result: RESULTS
    efforts: Float[Array, " n_prescribed"]
    lam: Float[Array, " n_constraints"]
    constraint_error: Float[Array, ""]
    constraint_rank: Int[Array, ""]
