"""Derivatives of contact statics by the implicit function theorem, exact.

A soft cantilever (1 m, r 1 cm, E 1 MPa, rho 1000, bending only, 4 divisions of order
2) clamped level 0.15 m above a frictionless floor (penalty k 1e5 N/m^2, smoothing
1e-6 m): most of it lies on the floor, which carries its 2.2 N weight less what the
clamp holds. The reverse-mode Jacobian of the equilibrium coordinates and the floor's
total force with respect to E, density, the law's stiffness and the floor's height
equals converged central differences to 1e-6 relative (fourth order: Richardson's
combination of the steps h and 2h; h 1e-4 of E and rho, 1e-4 m, and 1e-2 of k: the
solution moves with k only as the penetration f / k does, and at 1e-4 of k the
differences of q's round-off leave 1.3e-6), and forward mode equals reverse mode to
round-off.

The same on three scenes of tests/stiff_contact_scenes.py at k 1e6 (N/m^2 on the
sphere, N/m between the rods and in the tube; smoothing 1e-8 m), with respect to E,
density and the obstacle's position (the sphere's height, the lower rod's drop, the
ball's joint), and on the sphere also k (step 1e-3 of it). Between the rods and in
the tube at 1e6 k moves the solution by k |dq/dk| = 4e-5 m and 7e-8 m: q's round-off
(about 1e-12) over any step that keeps the differences' truncation below 1e-6 leaves
more than 1e-6 of that column; their k columns are checked at softer laws instead
(1e4 N/m between the rods, 1e3 N/m in the tube: 3.8e-3 m and 6.6e-5 m). Forward against
reverse mode agree to 1e-8 of each column (measured up to 1.2e-9, in the tube: the
linear solve's round-off with a stiff contact). At k 1e8 the E, density and position
columns of the sphere and the rods agree to 2e-8 .. 1e-7; the floor of
``cantilever_on_floor`` (smoothing 1e-8 m) does not: two of its samples then lie
within the law's 1e-8 m ramp, where the exact derivative follows q's round-off
(a change of E by 1e-15 changes its height column by 1.3 %).
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from stiff_contact_scenes import SCENES

import sorojax as sj

P0 = np.array([1e6, 1000.0, 1e5, 0.0])  # E [Pa], rho [kg/m^3], k [N/m^2], floor z [m]
STEPS = np.array([1e2, 0.1, 1e3, 1e-4])  # central differences' steps h (module doc)


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
        central = []
        for step in (STEPS[i], 2 * STEPS[i]):
            e = jnp.zeros(4).at[i].set(step)
            central.append((out(p0 + e) - out(p0 - e)) / (2 * step))
        fd = (4 * central[0] - central[1]) / 3  # Richardson: fourth order
        scale = float(jnp.max(jnp.abs(fd)))
        assert scale > 0, f"the solution does not depend on {name}"
        err = float(jnp.max(jnp.abs(jac[:, i] - fd))) / scale
        assert err < 1e-6, f"d/d{name}: reverse mode vs central differences {err:.1e}"
        np.testing.assert_allclose(jac_fwd[:, i], jac[:, i], rtol=0,
                                   atol=1e-10 * scale)  # fmt: skip


K_TESTED = 1e6
# name -> (E [Pa], rho [kg/m^3], k [N/m^2 on the sphere, N/m between the rods and in
# the tube], the obstacle's position [m]), and the central differences' steps
# (relative to the parameter; the position's in metres; None: not checked), chosen
# by measurement (module docstring).
STIFF = {
    "rod_over_sphere": ((1e7, 1000.0, K_TESTED, -0.01), (1e-2, 1e-2, 1e-3, 1e-3)),
    "crossing_rods": ((1e8, 1000.0, K_TESTED, 0.0), (1e-2, 1e-2, None, 1e-3)),
    "ball_in_tube": ((1e6, 1000.0, K_TESTED, 0.0), (1e-2, 1e-2, None, 1e-3)),
}


def _stiff_outputs(name, p):
    E, rho, k, position = p
    sol = sj.solve_statics(SCENES[name](k, E, rho, position), throw=False)
    if name in ("crossing_rods", "ball_in_tube"):  # on the upper rod, the ball
        force = jnp.sum(sol.contact.force[:, 2])
    else:
        force = sol.contact.total_force()[2]
    return jnp.concatenate([sol.q, force[None]]), sol.result


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(STIFF))
def test_stiff_contact_statics_jacobian_equals_central_differences(name):
    values, steps = STIFF[name]
    p0 = jnp.asarray(values)
    out = jax.jit(functools.partial(_stiff_outputs, name))
    _, result = out(p0)
    assert result == sj.RESULTS.successful
    jac = jax.jit(jax.jacrev(lambda p: _stiff_outputs(name, p)[0]))(p0)
    jac_fwd = jax.jit(jax.jacfwd(lambda p: _stiff_outputs(name, p)[0]))(p0)
    failures = []
    for i, param in enumerate(("E", "rho", "stiffness", "position")):
        if steps[i] is None:  # out of the differences' reach (module docstring)
            continue
        h = steps[i] * (abs(values[i]) if i < 3 else 1.0)
        central = []
        for step in (h, 2 * h):
            e = jnp.zeros(4).at[i].set(step)
            (plus, ok_plus), (minus, ok_minus) = out(p0 + e), out(p0 - e)
            assert ok_plus == sj.RESULTS.successful, (name, param, step)
            assert ok_minus == sj.RESULTS.successful, (name, param, -step)
            central.append((plus - minus) / (2 * step))
        fd = (4 * central[0] - central[1]) / 3  # Richardson: fourth order in h
        scale = float(jnp.max(jnp.abs(fd)))
        assert scale > 0, f"{name}: the solution does not depend on {param}"
        err = float(jnp.max(jnp.abs(jac[:, i] - fd))) / scale
        fwd = float(jnp.max(jnp.abs(jac_fwd[:, i] - jac[:, i]))) / scale
        if not (err < 1e-6 and fwd < 1e-8):
            failures.append(
                f"d/d{param}: reverse mode vs central differences {err:.1e}, "
                f"forward vs reverse {fwd:.1e} (of the column's scale {scale:.3e})"
            )
    assert not failures, f"{name}: " + "; ".join(failures)


# The stiffness column between the rods and in the tube, at a softer law where the
# solution moves with k by more than q's round-off (k |dq/dk| 3.8e-3 m between the
# rods at 1e4 N/m, 6.6e-5 m in the tube at 1e3 N/m; measured: 2.4e-8 .. 4.5e-8 and
# 4e-8 .. 3.2e-7 for relative steps 1e-3 .. 1e-2, the differences' plateau).
SOFT_K = {"crossing_rods": 1e4, "ball_in_tube": 1e3}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SOFT_K))
def test_stiffness_column_between_bodies_equals_central_differences(name):
    values = list(STIFF[name][0])
    values[2] = SOFT_K[name]
    p0 = jnp.asarray(values)
    out = jax.jit(functools.partial(_stiff_outputs, name))
    assert out(p0)[1] == sj.RESULTS.successful
    jac = jax.jit(jax.jacrev(lambda p: _stiff_outputs(name, p)[0]))(p0)[:, 2]
    jac_fwd = jax.jit(jax.jacfwd(lambda p: _stiff_outputs(name, p)[0]))(p0)[:, 2]
    h = 1e-2 * values[2]
    central = []
    for step in (h, 2 * h):
        e = jnp.zeros(4).at[2].set(step)
        (plus, ok_plus), (minus, ok_minus) = out(p0 + e), out(p0 - e)
        assert ok_plus == sj.RESULTS.successful and ok_minus == sj.RESULTS.successful
        central.append((plus - minus) / (2 * step))
    fd = (4 * central[0] - central[1]) / 3  # Richardson: fourth order in h
    scale = float(jnp.max(jnp.abs(fd)))
    assert scale * values[2] > 1e-5, "the solution should move with k"
    err = float(jnp.max(jnp.abs(jac - fd))) / scale
    assert err < 1e-6, f"{name}: d/dk reverse mode vs central differences {err:.1e}"
    fwd = float(jnp.max(jnp.abs(jac_fwd - jac))) / scale
    assert fwd < 1e-8, f"{name}: d/dk forward vs reverse {fwd:.1e}"
