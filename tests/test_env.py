"""The control/learning environment: step == simulate, vmap == loop, exact gradients.

One small model serves the file: the four-cable tapered arm at constant strain per
division (4 DoF: two bendings x two divisions), damped, under gravity.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
from sorojax._mechanisms import cable_manipulator

PERIOD = 0.02
ETA = 3e3  # Pa s: damped, as the arm of examples/cable_manipulator.py


@pytest.fixture(scope="module")
def arm():
    return cable_manipulator(order=0, eta=ETA)


@pytest.fixture(scope="module")
def env(arm):
    return sj.Environment(arm, period=PERIOD, noise=0.05)


@pytest.fixture(scope="module")
def step(env):
    return jax.jit(env.step)


@pytest.mark.parametrize("dt", [None, PERIOD / 2])
def test_step_equals_simulate_over_the_period(env, step, arm, dt):
    """Two periods from a perturbed rest state: each step is simulate from the
    state's time over one period with the clipped tensions held (same solver and
    tolerances, one save time; adaptive, or two constant steps, which the
    environment takes outside diffrax's loop): equal to rounding (1e-10; measured
    ~1e-14)."""
    if dt is not None:
        env = sj.Environment(arm, period=PERIOD, dt=dt, noise=0.05)
        step = jax.jit(env.step)
    s0 = env.reset(jax.random.key(1))
    a = jnp.array([1.5, -2.0, 0.5, 0.0])
    np.testing.assert_array_equal(np.asarray(env.inputs(a)), [1.5, 0.0, 0.5, 0.0])
    s1 = step(s0, a)
    s2 = step(s1, 2 * a)
    assert int(s1.result) == 0 and int(s2.result) == 0
    for s_a, s_b, u in ((s0, s1, env.inputs(a)), (s1, s2, env.inputs(2 * a))):
        t0 = float(s_a.t)
        tr = sj.simulate(
            arm,
            t0 + PERIOD,
            s_a.q,
            s_a.qd,
            t0=t0,
            ts=[t0 + PERIOD],
            solver="ros34pw2",
            u=u,
            dt0=dt,
            adaptive=dt is None,
        )
        assert abs(float(s_b.t) - (t0 + PERIOD)) < 1e-15
        scale = 1.0 + float(jnp.abs(tr.qd[-1]).max())
        np.testing.assert_allclose(s_b.q, tr.q[-1], rtol=0, atol=1e-10)
        np.testing.assert_allclose(s_b.qd, tr.qd[-1], rtol=0, atol=1e-10 * scale)
    assert float(jnp.abs(s2.q - s0.q).max()) > 1e-3  # the step moved the arm


def test_vmap_of_step_equals_the_loop(env, step):
    """16 random states and actions: the batched step equals 16 single steps (the
    batched adaptive loop runs each member's own steps; 1e-10, rounding)."""
    keys = jax.random.split(jax.random.key(2), 16)
    states = jax.vmap(env.reset)(keys)
    actions = 3.0 * jax.random.uniform(jax.random.key(3), (16, env.action_size))
    batched = jax.jit(jax.vmap(env.step))(states, actions)
    assert np.all(np.asarray(batched.result) == 0)
    for i in range(16):
        s_i = jax.tree.map(lambda x, i=i: x[i], states)
        one = step(s_i, actions[i])
        np.testing.assert_allclose(batched.q[i], one.q, rtol=0, atol=1e-10)
        np.testing.assert_allclose(batched.qd[i], one.qd, rtol=0, atol=1e-9)
        assert int(batched.steps[i]) == int(one.steps)


def test_gradient_of_a_100_step_rollout_matches_central_differences():
    """d(loss)/d(actions) through 100 periods of a soft rod on a torque-driven
    revolute joint (3 DoF, damped; constant steps: the rollout is a smooth function
    of the actions) against a central difference along a random direction: step
    1e-4 of the actions' scale, so truncation ~1e-8 and rounding ~1e-12 relative;
    tolerance 1e-5 relative."""
    rod = sj.SoftLink(
        [
            sj.Division(
                0.3, sj.CircularSection(0.01), sj.LegendreBasis((0, 0, 1, 0, 0, 0), 1)
            )
        ],
        sj.Material(E=1e6, poisson=0.5, rho=1000.0, eta=3e3),
        joint=sj.Joint("R", axis=(0.0, 0.0, 1.0), damping=1e-3),
    )
    lk = sj.Linkage([rod], gravity=(0.0, -9.81, 0.0), actuators=[sj.JointActuator(1)])
    env = sj.Environment(lk, period=0.01, dt=0.005)
    s0 = env.reset(jax.random.key(0))
    target = jnp.array([0.2, -0.2, 0.0])

    def loss(actions):
        final, states = sj.rollout(env, s0, actions)
        tips = jax.vmap(env.tip_position)(states)
        return jnp.mean(jnp.sum((tips - target[None]) ** 2, axis=-1)) + 1e-2 * jnp.sum(
            final.qd**2
        )

    actions = 0.05 * jax.random.normal(jax.random.key(4), (100, env.action_size))
    d = jax.random.normal(jax.random.key(5), actions.shape)
    # One compiled program: the gradient and, at shifted actions, the differences.
    f = jax.jit(jax.value_and_grad(loss))
    value, g = f(actions)
    assert np.isfinite(float(value)) and bool(jnp.all(jnp.isfinite(g)))
    eps = 1e-4 * 0.05
    fd = (f(actions + eps * d)[0] - f(actions - eps * d)[0]) / (2 * eps)
    exact = float(jnp.vdot(g, d))
    assert abs(exact - float(fd)) < 1e-5 * abs(float(fd)), (exact, float(fd))
    assert float(jnp.abs(g).max()) > 0  # the actions matter


def test_a_failed_step_reports_and_keeps_the_state(arm):
    """max_steps = 1 cannot cover a period: result max_steps_reached, the state
    (q, qd, t) unchanged and finite, no exception under jit."""
    env = sj.Environment(arm, period=PERIOD, max_steps=1)
    s0 = env.reset(jax.random.key(0))
    s1 = jax.jit(env.step)(s0, jnp.array([5.0, 0.0, 0.0, 0.0]))
    assert int(s1.result) == int(sj.RESULTS.max_steps_reached._value)
    np.testing.assert_array_equal(s1.q, s0.q)
    np.testing.assert_array_equal(s1.qd, s0.qd)
    assert float(s1.t) == 0.0


def test_prescribed_joint_ramps_to_the_action():
    """A bar on a prescribed revolute: over each period the angle ramps linearly
    from the previous action to the new one (first-order hold), so at the period's
    end q equals the action (exact for a linear function: 1e-12) and qd the ramp's
    slope (integrated from u'' = 0 through the Rosenbrock stages' linear solves:
    measured 1.5e-10 relative; 1e-9)."""
    bar = sj.RigidLink(
        sj.Joint("R", axis=(0, 0, 1.0)),
        length=0.3,
        mass=0.5,
        inertia=np.diag([1e-4, 3e-3, 4e-3]),
    )
    lk = sj.Linkage(
        [bar], gravity=(0, -9.81, 0), actuators=[sj.JointActuator(1, prescribed=True)]
    )
    env = sj.Environment(lk, period=0.1, u0=jnp.array([0.2]))
    s = env.reset(jax.random.key(0))
    assert abs(float(s.q[0]) - 0.2) < 1e-15
    step = jax.jit(env.step)
    for target in (0.5, -0.1):
        prev = float(s.u[0])
        s = step(s, jnp.array([target]))
        assert int(s.result) == 0
        assert abs(float(s.q[0]) - target) < 1e-12
        assert abs(float(s.qd[0]) - (target - prev) / 0.1) < 1e-9 * 3


def test_bad_settings_name_the_field(arm):
    with pytest.raises(ValueError, match="period"):
        sj.Environment(arm, period=0.0)
    with pytest.raises(ValueError, match="dt"):
        sj.Environment(arm, period=0.02, dt=0.003)
    with pytest.raises(ValueError, match="auto"):
        sj.Environment(arm, period=0.02, solver="auto")
    with pytest.raises(ValueError, match="q0"):
        sj.Environment(arm, period=0.02, q0=jnp.zeros(3))


def test_environment_is_a_pytree_for_domain_randomisation(arm):
    """vmap over environments whose damping differs (stacked leaves): more damping,
    less velocity after one period from the same perturbed state."""
    env = sj.Environment(arm, period=PERIOD, noise=0.05)
    etas = jnp.array([1e3, 1e4])
    envs = jax.vmap(
        lambda e: eqx.tree_at(lambda x: x.linkage.links[0].material.eta, env, e)
    )(etas)
    s0 = env.reset(jax.random.key(7))
    out = eqx.filter_jit(
        eqx.filter_vmap(lambda e: e.step(s0, jnp.zeros(4)), in_axes=(eqx.if_array(0),))
    )(envs)
    speed = np.abs(np.asarray(out.qd)).max(axis=1)
    assert np.all(np.asarray(out.result) == 0)
    assert speed[1] < speed[0], speed


def test_observations_agree_with_the_kinematics(env, arm):
    """tip_velocity is the time derivative of tip_position along qd (a JVP of the
    forward kinematics: 1e-12 m/s); cable_lengths and strains have one entry per
    cable / per point; the flat observation stacks q, qd, tip position, velocity."""
    s = env.reset(jax.random.key(3))
    s = eqx.tree_at(lambda x: x.qd, s, jax.random.normal(jax.random.key(4), (4,)))
    _, v_jvp = jax.jvp(lambda q: sj.tip_pose(arm, q)[:3, 3], (s.q,), (s.qd,))
    np.testing.assert_allclose(env.tip_velocity(s), v_jvp, rtol=0, atol=1e-12)
    assert env.cable_lengths(s).shape == (4,)
    assert env.strains(s).shape[1] == 6
    obs = env.observation(s)
    np.testing.assert_array_equal(obs[:4], s.q)
    np.testing.assert_allclose(obs[-3:], v_jvp, rtol=0, atol=1e-12)
