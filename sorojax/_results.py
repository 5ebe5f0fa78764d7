"""Result codes and solution containers returned by the solvers.

Solvers never return silent NaNs: each solution carries a ``RESULTS`` code, and entry
points take ``throw`` (raise on failure) as optimistix and diffrax do.
"""

from collections.abc import Callable
from typing import Any, TypeVar

import equinox as eqx
import jax
from jaxtyping import Array, Bool, Float, Int


class RESULTS(eqx.Enumeration):
    """Outcome of a sorojax solve."""

    successful = ""
    max_steps_reached = "The solver reached its maximum number of steps."
    nonlinear_divergence = (
        "The nonlinear solver diverged or produced non-finite values."
    )
    singular = "A linear solve met a singular matrix."
    contact_too_deep = (
        "A contact's penetration exceeds the smallest contact radius: a body went "
        "into (or started inside) an obstacle or another body. Start it outside, "
        "raise ContactLaw.stiffness, or take smaller steps."
    )
    failed = "The solver failed (see the underlying optimistix/diffrax result)."
    contact_overflow = (
        "More segment pairs of a rod pair (or of a rod's self-contact) can touch "
        "than the broad phase's capacity: give Contact(pair_capacity=...) a larger "
        "number (the default is 4 per segment)."
    )
    unstable_step = (
        "The state went non-finite at a constant step: the step is too large for "
        "the scheme to stay stable. Give a smaller dt0 (or adaptive steps)."
    )


class StaticsSolution(eqx.Module):
    """Equilibrium found by :func:`sorojax.statics.solve_statics`.

    With sorojax's own Newton solver, ``residual_norm``, ``efforts`` and
    ``constraint_error`` are evaluated at the solver's last iterate; ``q`` is that
    iterate plus one more Newton step, already within the tolerances (so ``q`` is the
    more accurate, to about the square of that step), which saves a whole evaluation
    of the residual and its Jacobian per solve. Their values at ``q`` itself differ
    by about the tolerances times the stiffness (e.g. 2e-10 relative in the manual
    hybrid scene's revolute torque at the default 1e-10). Derivatives of ``q``,
    ``lam``, ``efforts`` and ``residual_norm`` (``jax.grad``, ``jax.jvp``, ...) come
    from the implicit function theorem with the same last iterate's Jacobian, so they
    are exact to about the tolerances as well (a user optimistix ``solver`` forms it
    at ``q``).

    Attributes:
        q: generalised coordinates at equilibrium, shape ``(n_dof,)``.
        residual_norm: max-norm of the equilibrium residual ``K q - F(q) - B u``
            (units of the generalised forces: N m for angular coordinates, N for
            linear joint coordinates).
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
        stable: whether the solve converged to a stable equilibrium (False when
            it failed): no eigenvalue of the tangent
            stiffness restricted to the constraint manifold (prescribed coordinates
            held, with the constraint-curvature term of the multipliers) is
            negative (:mod:`sorojax.statics._stability`; eigenvalues within 1e-9 of
            the largest are neutral: symmetries, unloaded mechanisms, critical
            points; ``min_eigenvalue`` shows them). Under follower or other
            non-conservative loads this is the symmetric part's test: no
            divergence, flutter is not seen (see the README).
        n_negative: number of negative eigenvalues of that reduced tangent
            stiffness (0 at a stable equilibrium; its Morse index otherwise).
        min_eigenvalue: its smallest eigenvalue, dimensionless (in coordinates
            scaled by each one's own stiffness, diag(K)^(1/2) q: near 1 for an
            unloaded elastic rod, 0 at a buckling load); ``+inf`` when no free
            direction is left. All three are taken at the last iterate's Jacobian
            (no extra evaluation) and carry no gradient.
        contact: a :class:`~sorojax.ContactState` at ``q`` (frictionless: points,
            normals, penetrations and forces of every candidate contact) for a
            linkage with contact, else None.
    """

    q: Float[Array, " n_dof"]
    residual_norm: Float[Array, ""]
    num_steps: Int[Array, ""]
    result: RESULTS
    efforts: Float[Array, " n_prescribed"]
    lam: Float[Array, " n_constraints"]
    constraint_error: Float[Array, ""]
    constraint_rank: Int[Array, ""]
    stable: Bool[Array, ""]
    n_negative: Int[Array, ""]
    min_eigenvalue: Float[Array, ""]
    contact: Any = None


def failed(result: RESULTS) -> bool | Array:
    """Whether ``result`` is not ``RESULTS.successful``.

    A Python bool for a concrete code, compared on the host (``!=`` on the arrays
    would compile and run a program of its own); a traced boolean under a trace.
    """
    code = result._value
    if isinstance(code, jax.core.Tracer):
        return result != RESULTS.successful
    return int(code) != int(RESULTS.successful._value)


def message(code: int) -> str:
    """The message of the result with integer code ``code`` (``result._value``)."""
    return RESULTS._index_to_message[int(code)]


_Solution = TypeVar("_Solution")


def throw_on_failure(solution: _Solution, describe: Callable[[str], str]) -> _Solution:
    """``solution`` (with ``result`` and ``q``), or its failure raised.

    Concrete: a failed solve raises ``RuntimeError(describe(message))`` with the
    result's message. Traced (inside an outer jit, vmap or grad): ``q`` carries an
    equinox runtime error that fires when the code is not successful.
    """
    bad = failed(solution.result)
    if isinstance(bad, jax.core.Tracer):
        q = solution.result.error_if(solution.q, bad)
        return eqx.tree_at(lambda s: s.q, solution, q)
    if bad:
        raise RuntimeError(describe(message(int(solution.result._value))))
    return solution
