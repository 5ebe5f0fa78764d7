"""Derivatives of contact statics by the implicit function theorem, exact.

A soft cantilever (1 m, r 1 cm, E 1 MPa, rho 1000, bending only, 4 divisions of order
2) clamped level 0.15 m above a frictionless floor (penalty k 1e5 N/m^2, smoothing
1e-6 m): most of it lies on the floor, which carries its 2.2 N weight less what the
clamp holds. The reverse-mode Jacobian of the equilibrium coordinates and the floor's
total force with respect to E, density, the law's stiffness and the floor's height
equals converged central differences (relative steps 1e-4: measured agreement
1e-8 to 7e-8; their truncation error at 1e-3 is 1e-6 to 4e-6) to 1e-6 relative, and
forward mode equals reverse mode to round-off.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj

P0 = np.array([1e6, 1000.0, 1e5, 0.0])  # E [Pa], rho [kg/m^3], k [N/m^2], floor z [m]
STEPS = np.array([1e2, 0.1, 10.0, 1e-4])  # central differences' steps (1e-4 relative)


def _cantilever(p):
    E, rho, k, z = p
    div = sj.Division(
        0.25, sj.CircularSection(0.01), sj.LegendreBasis((0, 1, 0, 0, 0, 0), 2)
    )
    rod = sj.SoftLink([div] * 4, sj.Material(E=E, poisson=0.5, rho=rho))
    place = np.eye(4)
    place[2, 3] = 0.15
    floor = sj.Plane(point=jnp.stack([0.0, 0.0, z]))
    law = sj.ContactLaw(stiffness=k, smoothing=1e-6)
    return sj.Linkage(
        [rod], placements=place[None], gravity=(0, 0, -9.81),
        contact=sj.Contact(floor, law),
    )  # fmt: skip


def _outputs(p):
    sol = sj.solve_statics(_cantilever(p), throw=False)
    return jnp.concatenate([sol.q, sol.contact.total_force()[2:]]), sol.result


@pytest.mark.slow
def test_contact_statics_jacobian_equals_central_differences():
    p0 = jnp.asarray(P0)
    out = jax.jit(lambda p: _outputs(p)[0])
    value, result = _outputs(p0)
    assert result == sj.RESULTS.successful
    # the floor carries most of the weight (2.22 N in all)
    assert 1.5 < float(value[-1]) < 2.3
    jac = jax.jit(jax.jacrev(lambda p: _outputs(p)[0]))(p0)
    jac_fwd = jax.jit(jax.jacfwd(lambda p: _outputs(p)[0]))(p0)
    for i, name in enumerate(("E", "rho", "stiffness", "floor height")):
        e = jnp.zeros(4).at[i].set(STEPS[i])
        fd = (out(p0 + e) - out(p0 - e)) / (2 * STEPS[i])
        scale = float(jnp.max(jnp.abs(fd)))
        assert scale > 0, f"the solution does not depend on {name}"
        err = float(jnp.max(jnp.abs(jac[:, i] - fd))) / scale
        assert err < 1e-6, f"d/d{name}: reverse mode vs central differences {err:.1e}"
        np.testing.assert_allclose(jac_fwd[:, i], jac[:, i], rtol=0,
                                   atol=1e-10 * scale)  # fmt: skip
