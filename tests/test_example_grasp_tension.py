"""examples/grasp.py's slip is differentiable in the cable tension through contact.

The forward-mode derivative of the ball's slip with respect to the tension (through
``simulate``'s constant-step linearly implicit Euler rollout with friction, as
examples/grasp_tension.py descends on it) against central differences of the same
program.

Slow (three rollouts of the 12-DoF gripper with their tangents, 2,800 steps each, in
one ``vmap``; most of it the compile): run with ``-m slow``.
"""

import importlib.util
import pathlib

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"


@pytest.mark.slow
def test_slip_derivative_matches_central_differences(jit_optimised):
    spec = importlib.util.spec_from_file_location("grasp", EXAMPLES / "grasp.py")
    ex = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ex)
    lk = ex.gripper()
    T, h, t1 = 4.0, 0.02, 1.4  # holding: the ball creeps, it does not slide out

    def slip(tension):
        return ex.slip(lk, tension, t1, adjoint=diffrax.ForwardMode(), throw=False)

    @jit_optimised
    def slip_and_derivative(tensions):
        return jax.vmap(lambda x: jax.jvp(slip, (x,), (jnp.ones_like(x),)))(tensions)

    s, ds = (np.asarray(v) for v in slip_and_derivative(jnp.array([T - h, T, T + h])))
    fd = (s[2] - s[0]) / (2 * h)
    assert np.all(np.isfinite(ds)), f"d slip / dT not finite: {ds}"
    # more tension, less slip (measured -2.41 mm/N at 4 N)
    assert ds[1] < -1e-3, f"d slip / dT = {ds[1]} m/N"
    # the exact derivative of the computed rollout vs central differences of it:
    # constant steps, so only the O(h^2) truncation (examples/grasp_tension.py
    # measured 2.4e-5 at 3.82 N and 6 N)
    np.testing.assert_allclose(
        ds[1], fd, rtol=2e-4, err_msg="d slip / dT vs central differences"
    )
