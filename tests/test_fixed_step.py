"""The constant-step linearly implicit solvers (``RosenbrockEuler``).

References: a tight Dopri8 solution of a forced, damped linear oscillator (convergence
orders 1 and 2); the exact energy of an undamped linear oscillator (the linearised
trapezoidal rule is its Cayley transform: energy kept to round-off; implicit Euler's
amplification factor is below 1: energy falls every step); the Coulomb sliding
acceleration g (sin - mu cos) of a block on an incline; energy that a damped contact
can only remove; central differences for forward- and reverse-mode derivatives.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_contact import MU, _downhill, dropped_rod, incline

import sorojax as sj
from sorojax.integrate import MechanicalTerm, RosenbrockEuler

G = 9.81
# a 2-DoF linear oscillator M qdd = -K q - D qd + F(t): the fast mode (omega ~ 45)
# damped, the slow one (omega ~ 1) lightly, forced at 3 rad/s
M_ = np.array([[2.0, 0.3], [0.3, 1.0]])
K_ = np.array([[2000.0, -5.0], [-5.0, 1.0]])
D_ = np.array([[20.0, 0.0], [0.0, 0.02]])


def _force(t):
    return jnp.stack([jnp.sin(3.0 * t), 0.5 * jnp.cos(3.0 * t)])


def _linear_field(t, y, args):
    """``(ydot, (M, K, D))`` of the oscillator (a MechanicalTerm's field)."""
    M, K, D = (jnp.asarray(a) for a in (M_, K_, D_))
    q, v = y[:2], y[2:]
    a = jnp.linalg.solve(M, _force(t) - K @ q - D @ v)
    return jnp.concatenate([v, a]), (M, K, D)


def _solve(term, solver, h, t1=1.0, y0=None):
    y0 = jnp.array([0.01, 0.5, 0.0, 0.0]) if y0 is None else y0
    sol = diffrax.diffeqsolve(
        term, solver, 0.0, t1, h, y0, stepsize_controller=diffrax.ConstantStepSize(),
        max_steps=100_000,
    )  # fmt: skip
    return sol.ys[-1]


@pytest.fixture(scope="module")
def reference():
    term = diffrax.ODETerm(lambda t, y, a: _linear_field(t, y, a)[0])
    sol = diffrax.diffeqsolve(
        term, diffrax.Dopri8(), 0.0, 1.0, 1e-3, jnp.array([0.01, 0.5, 0.0, 0.0]),
        stepsize_controller=diffrax.PIDController(rtol=1e-13, atol=1e-13),
        max_steps=100_000,
    )  # fmt: skip
    return sol.ys[-1]


@pytest.mark.parametrize(("gamma", "order"), [(1.0, 1), (0.5, 2)])
def test_convergence_order_on_a_forced_linear_oscillator(reference, gamma, order):
    """W is the exact Jacobian of a linear system: Euler is order 1, the linearised
    trapezoidal rule (inputs at the step's middle) order 2, time-dependent force
    included."""
    term = MechanicalTerm(_linear_field)
    solver = RosenbrockEuler(gamma=gamma)
    hs = [1 / 800, 1 / 1600, 1 / 3200]
    err = [float(jnp.linalg.norm(_solve(term, solver, h) - reference)) for h in hs]
    observed = np.log2(np.array(err[:-1]) / np.array(err[1:]))
    # asymptotic ratios 2^order (Euler's error approaches its order slowly from
    # below here: measured 0.88, 0.93; the trapezoidal rule 2.005, 2.001)
    np.testing.assert_allclose(observed, order, atol=0.15)
    assert solver.order(term) == order


@pytest.mark.parametrize("gamma", [1.0, 0.5])
def test_mechanical_and_dense_paths_agree(gamma):
    """The Cholesky system of a MechanicalTerm and the autodiff Jacobian with LU of a
    plain ODE term are the same method on a linear system: equal to round-off."""
    solver = RosenbrockEuler(gamma=gamma)
    a = _solve(MechanicalTerm(_linear_field), solver, 1 / 100)
    b = _solve(diffrax.ODETerm(lambda t, y, x: _linear_field(t, y, x)[0]), solver,
               1 / 100)  # fmt: skip
    np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-14)


def test_energy_of_an_undamped_oscillator_at_steps_beyond_its_period():
    """Undamped, unforced, h omega = 20 (an explicit method would blow up): the
    trapezoidal rule keeps the energy to round-off; implicit Euler loses energy
    at every step (amplification |1 / (1 - i h omega)| < 1), never gains."""
    M, K = jnp.eye(1), jnp.full((1, 1), 400.0)  # omega = 20

    def field(t, y, args):
        return jnp.concatenate([y[1:], -K[0] * y[:1]]), (M, K, jnp.zeros((1, 1)))

    term, h = MechanicalTerm(field), 1.0
    y0 = jnp.array([1.0, 0.0])
    energy = {}
    for gamma in (1.0, 0.5):
        y, e = y0, []
        for k in range(8):
            y = RosenbrockEuler(gamma=gamma).step(term, k * h, (k + 1) * h, y, None,
                                                  None, False)[0]  # fmt: skip
            e.append(float(0.5 * y[1] ** 2 + 0.5 * K[0, 0] * y[0] ** 2))
        energy[gamma] = np.array(e)
    np.testing.assert_allclose(energy[0.5], 200.0, rtol=1e-13)
    assert np.all(np.diff(energy[1.0]) < 0) and energy[1.0][0] < 200.0


def test_bad_gamma_and_state_refused():
    with pytest.raises(ValueError, match="0 < gamma <= 1"):
        RosenbrockEuler(gamma=1.5)
    with pytest.raises(ValueError, match="one-dimensional array state"):
        RosenbrockEuler().init(None, 0.0, 1.0, (jnp.zeros(2),), None)


# --------------------------------------------------------------- through simulate
@pytest.mark.parametrize("alpha_deg", [15.0, 35.0])
def test_block_on_incline_sticks_or_slides_at_constant_steps(alpha_deg):
    """As tests/test_contact.py's adaptive run, at 1 ms linearly implicit Euler
    steps (the contact's stiffness 1e4 and the sticking friction's slope in W)."""
    alpha = np.radians(alpha_deg)
    lk = incline(alpha)
    tr = sj.simulate(lk, 1.0, solver="rosenbrock_euler", dt0=1e-3, n_save=41)
    s = _downhill(lk, tr, alpha)
    assert int(tr.num_steps) == 1000
    if np.tan(alpha) < MU:
        # friction angle 26.6 deg: held (the regularisation's creep 0.63 mm/s)
        assert abs(s[-1]) < 1e-3, f"drift {s[-1]:.2e} m in 1 s below the friction angle"
    else:
        t = np.asarray(tr.t)
        a = 2 * np.polyfit(t[20:], s[20:], 2)[0]
        np.testing.assert_allclose(a, G * (np.sin(alpha) - MU * np.cos(alpha)),
                                   rtol=0.02)  # fmt: skip


def test_dropped_rod_never_gains_energy_at_constant_steps():
    """A tilted rod falls on a damped floor: 2 ms steps (the contact's stiffness in
    W, 750 steps for 1.5 s); contact damping, material damping and the method's own
    dissipation only remove energy."""
    lk = dropped_rod()
    q0 = jnp.zeros(lk.n_dof).at[0].set(0.1)
    tr = sj.simulate(lk, 1.5, q0, solver="rosenbrock_euler", dt0=2e-3, n_save=151)
    E = np.asarray(jax.vmap(lambda q, qd: sj.total_energy(lk, q, qd))(tr.q, tr.qd))
    assert np.max(np.diff(E)) <= 1e-9 * abs(E[0]), (
        f"energy rose by {np.max(np.diff(E)):.2e} J"
    )
    assert E[-1] < 0.5 * E[0]


def test_constant_step_settings_refused_or_reported():
    lk = incline(np.radians(15.0))
    with pytest.raises(ValueError, match="takes constant steps"):
        sj.simulate(lk, 0.1, solver="rosenbrock_euler", dt0=1e-3, adaptive=True)
    with pytest.raises(ValueError, match="give dt0"):
        sj.simulate(lk, 0.1, solver="rosenbrock_euler")
    with pytest.raises(ValueError, match="takes constant steps: give dt"):
        sj.Environment(lk, period=0.01, solver="rosenbrock_euler")
    with pytest.raises(ValueError, match=r"takes 100 constant steps.*max_steps = 50"):
        sj.simulate(lk, 0.1, solver="rosenbrock_euler", dt0=1e-3, max_steps=50)
    # a step far beyond the explicit bound of the contact (omega ~ 316 rad/s): the
    # state blows up, reported as such, not returned as a success
    tr = sj.simulate(lk, 0.5, solver="tsit5", dt0=0.05, adaptive=False, throw=False)
    assert tr.result == sj.RESULTS.unstable_step
    with pytest.raises(RuntimeError, match="too large for the scheme"):
        sj.simulate(lk, 0.5, solver="tsit5", dt0=0.05, adaptive=False)


def test_derivatives_through_constant_steps_match_central_differences():
    """d(final height of the rod's tip)/d(the floor's stiffness) through 0.3 s of
    the dropped rod landing (40 ms of contact), forward mode and reverse mode, against
    central differences: constant steps make the result smooth in the parameter."""
    base = dropped_rod()
    q0 = jnp.zeros(base.n_dof).at[0].set(0.1)

    def height(k, adjoint):
        lk = eqx.tree_at(lambda m: m.contact.law.stiffness, base, k)
        tr = sj.simulate(lk, 0.3, q0, solver="rosenbrock_euler", dt0=2e-3, n_save=2,
                         adjoint=adjoint)  # fmt: skip
        return sj.forward_kinematics(lk, tr.q[-1])[-1, 2, 3]

    @jax.jit
    def forward(k):  # the height and its derivative: one program for every k
        return jax.jvp(lambda k: height(k, diffrax.ForwardMode()), (k,), (1.0,))

    k0 = jnp.asarray(1e4)
    _, fwd = forward(k0)
    rev = jax.jit(jax.grad(lambda k: height(k, None)))(k0)
    # the height is strongly curved in k here: central differences converge as
    # dk^2 (measured 4e-4 relative off at dk = 1, 4e-6 at 0.1, 4e-8 at 0.01)
    dk = 0.01
    fd = (forward(k0 + dk)[0] - forward(k0 - dk)[0]) / (2 * dk)
    np.testing.assert_allclose(float(fwd), float(rev), rtol=1e-10)
    np.testing.assert_allclose(float(rev), float(fd), rtol=1e-6)
    assert abs(float(fd)) > 1e-9  # the landing depends on the floor's stiffness
