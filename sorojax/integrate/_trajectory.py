"""The result of :func:`sorojax.simulate`: saved states, result code and statistics."""

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from .._jit import jit
from .._results import RESULTS


class Trajectory(eqx.Module):
    """States of a simulation at its save times.

    Attributes:
        t: (n_save,) save times [s].
        q: (n_save, n_dof) coordinates.
        qd: (n_save, n_dof) velocities.
        result: a :class:`sorojax.RESULTS` code; ``RESULTS.successful`` when the
            integration reached ``t1``. Entries after a failure are ``inf``.
        num_steps: steps attempted (accepted + rejected).
        num_accepted_steps: accepted steps.
        num_rejected_steps: rejected steps (adaptive step-size control).
        solver: name of the diffrax solver class that produced it ("" if loaded or
            built by hand).
        u: (n_save, n_inputs) actuation inputs (after the actuator-strength hook),
            or None for a linkage without actuators or closed loops.
        efforts: (n_save, n_prescribed) efforts of prescribed joint coordinates.
        lam: (n_save, n_constraints) closed-loop multipliers.
        contact: a :class:`~sorojax.ContactState` with a leading time axis
            (points, normals, penetrations, forces and slip of every candidate
            contact at each save time) for a linkage with contact, else None.
    """

    t: Float[Array, " n_save"]
    q: Float[Array, "n_save n_dof"]
    qd: Float[Array, "n_save n_dof"]
    result: RESULTS
    num_steps: Int[Array, ""]
    num_accepted_steps: Int[Array, ""]
    num_rejected_steps: Int[Array, ""]
    solver: str = eqx.field(static=True, default="")
    u: Float[Array, "n_save n_inputs"] | None = None
    efforts: Float[Array, "n_save n_prescribed"] | None = None
    lam: Float[Array, "n_save n_constraints"] | None = None
    contact: Any = None

    @property
    def qqd(self) -> Float[Array, "n_save two_n_dof"]:
        """States as SoRoSim's ``qqd``: ``[q, qd]`` side by side, one row per time."""
        return jnp.concatenate([self.q, self.qd], axis=-1)

    def poses(self, linkage) -> Float[Array, "n_save n_points 4 4"]:
        """World poses of every significant point at every save time."""
        return _poses(linkage, self.q)

    def tip_positions(self, linkage, link: int = -1) -> Array:
        """Tip position of ``link`` (1-based; -1 = the last link) at every save time."""
        return _tip_positions(linkage, self.q, link)

    def energies(self, linkage) -> Float[Array, "n_save 4"]:
        """Kinetic, gravitational, elastic and total energy [J] at every save time.

        Point wrenches and hooks are excluded, as in :func:`sorojax.total_energy`.
        """
        return _energies(linkage, self.q, self.qd)

    def closure_errors(self, linkage) -> Float[Array, "n_save n_constraints"]:
        """Closed-loop constraint errors e(q) [rad, m] at every save time (drift)."""
        return _closure_errors(linkage, self.q)


# One compiled program per linkage structure and number of save times, shared by the
# methods' callers (scripts, plots), compiled with sorojax's XLA options.
@jit
def _poses(linkage, q):
    from ..kinematics import forward_kinematics

    return jax.vmap(lambda qi: forward_kinematics(linkage, qi))(q)


@jit
def _tip_positions(linkage, q, link: int):
    from ..kinematics import tip_pose

    return jax.vmap(lambda qi: tip_pose(linkage, qi, link)[:3, 3])(q)


@jit
def _energies(linkage, q, qd):
    from ..dynamics import elastic_energy, gravitational_energy, kinetic_energy

    def one(qi, qdi):
        kin = kinetic_energy(linkage, qi, qdi)
        grav = gravitational_energy(linkage, qi)
        ela = elastic_energy(linkage, qi)
        return jnp.stack([kin, grav, ela, kin + grav + ela])

    return jax.vmap(one)(q, qd)


@jit
def _closure_errors(linkage, q):
    from ..dynamics import closure_errors

    return jax.vmap(lambda qi: closure_errors(linkage, qi))(q)
