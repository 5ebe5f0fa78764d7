"""The cosseratbench adapter (sorojax/contrib/cosseratbench.py) on short cases.

Skipped without cosseratbench (``pip install -e ".[test]"`` installs it). One static
scene through the adapter's ``run`` at a low resolution (one compile, ~5 s) and the
contact scenes' modelling choices (no solve); the dynamic path (frame chunks,
pre-stretched initial fit) is marked ``slow`` (its compiles take ~10 s and more):
``pytest tests/test_cosseratbench.py -m slow``.
"""

import os

import numpy as np
import pytest

cb = pytest.importorskip(
    "cosseratbench", reason="cosseratbench (the rod benchmark) is not installed"
)

from cosseratbench.experiments.cantilever import cantilever  # noqa: E402
from cosseratbench.experiments.capstan import capstan  # noqa: E402
from cosseratbench.experiments.crossing import crossing  # noqa: E402
from cosseratbench.experiments.pendulum import pendulum  # noqa: E402
from cosseratbench.experiments.pile import pile  # noqa: E402

import sorojax.contrib.cosseratbench as adapter  # noqa: E402
from sorojax.contrib.cosseratbench import SorojaxSolver  # noqa: E402


def test_solver_contract():
    """The adapter satisfies the benchmark's Solver protocol and its registry."""
    from cosseratbench import registry

    solver = SorojaxSolver()
    assert isinstance(solver, cb.Solver)
    assert solver.name == "sorojax"
    # every capability by default; contact=False declares none of contact's
    assert solver.capabilities == frozenset(cb.Capability)
    assert SorojaxSolver(contact=False).capabilities == {
        cb.Capability.STRETCH,
        cb.Capability.SHEAR,
    }
    assert "sorojax" in registry.names(registry.SOLVERS), "entry point not installed"
    assert SorojaxSolver(time_step_scale=2.0).time_step_scale == 2.0


def test_solver_sets_one_runtime_thread_before_jax_starts():
    """A solver made before JAX's backend starts sets NPROC = XLA_THREADS (1).

    In a fresh interpreter (this process's backend has started): set when unset;
    not once the backend runs (XLA has read it); a user's NPROC kept.
    """
    import subprocess
    import sys

    code = (
        "import os\n"
        "os.environ.pop('NPROC', None)\n"
        "from sorojax.contrib.cosseratbench import SorojaxSolver, _runtime_threads\n"
        "SorojaxSolver()\n"
        "print(os.environ.get('NPROC'))\n"
        "import jax.numpy as jnp\n"
        "jnp.zeros(1).block_until_ready()\n"
        "del os.environ['NPROC']\n"
        "print(_runtime_threads(1), os.environ.get('NPROC'))\n"
        "os.environ['NPROC'] = '4'\n"
        "print(_runtime_threads(1), os.environ.get('NPROC'))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "NPROC"}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[:3] == ["1", "False None", "False 4"], out.stdout


def test_cantilever_tip_deflection():
    """Clamped rod, 7.5 mN dead tip load: Timoshenko's tip deflection.

    Reference: P L^3 / (3 E I) + P L / (k G A) (Euler-Bernoulli plus shear; the
    adapter models shear here, 3 E I / (k G A L^2) = 1.0e-3). Tolerance 1e-3: the
    large-deflection shortening (tip at 2% of L) lowers the tip by ~4e-4 of it,
    which the linear formula leaves out. Frame 0 is the straight rod exactly.
    """
    scenario = cantilever.scenario
    rod = scenario.rods[0]
    n, frames = 10, 3
    solver = SorojaxSolver()
    settings = solver.settings(scenario, n_elements=n, n_frames=frames)["model"]
    assert settings["orders"] == {"bend_z": 2, "shear_y": 2}, settings
    assert settings["method"] == "statics"
    tr = solver.run(scenario, n_elements=n, n_frames=frames)

    assert tr.times.shape == (frames,)
    assert tr.positions[0].shape == (frames, n + 1, 3)
    assert tr.directors[0].shape == (frames, n, 3)
    np.testing.assert_allclose(tr.times, np.linspace(0, scenario.duration, frames))
    # t = 0: the straight rod and the benchmark's material frame, to rounding.
    np.testing.assert_allclose(tr.positions[0][0], rod.nodes(n), rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.directors[0][0], rod.directors(n), rtol=0, atol=1e-12)

    P = -cantilever.scenario.rods[0].loads[0].force[2]
    E, G = rod.material.youngs_modulus, rod.material.shear_modulus
    nu = E / (2 * G) - 1
    k = 6 * (1 + nu) / (7 + 6 * nu)  # Cowper, solid circle
    L, I, A = rod.length, rod.second_moment_of_area, rod.area
    reference = P * L**3 / (3 * E * I) + P * L / (k * G * A)
    tip = -tr.positions[0][-1, -1, 2]
    assert abs(tip - reference) < 1e-3 * reference, (
        f"tip deflection {tip:.6e} m vs Timoshenko {reference:.6e} m"
    )
    # The directors stay unit and perpendicular to their elements (to rounding).
    d = tr.directors[0][-1]
    e = np.diff(tr.positions[0][-1], axis=0)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    assert np.abs(np.sum(d * e, axis=1) / np.linalg.norm(e, axis=1)).max() < 1e-3


@pytest.mark.slow
def test_pendulum_short_swing():
    """The pinned, pre-stretched cable released in its first mode, 0.3 s.

    Frames come in chunks of 32 (40 frames: a full and a padded chunk). Checks: the
    initial shape is the scenario's (the stretch and curvature fit, 1e-5 m), the pin
    stays put (1e-9 m), the free end moves back toward the vertical (it starts at
    its largest swing: x decreases), and no element stretches by more than the
    static strain rho g L / E = 1e-3 plus 20%.
    """
    scenario = pendulum.scenario
    scenario = type(scenario)(**{**scenario.__dict__, "duration": 0.3})
    rod = scenario.rods[0]
    n, frames = 12, 40
    tr = SorojaxSolver().run(scenario, n_elements=n, n_frames=frames)
    x = tr.positions[0]
    assert x.shape == (frames, n + 1, 3)
    assert np.all(np.isfinite(x))
    np.testing.assert_allclose(x[0], rod.nodes(n), rtol=0, atol=1e-5)
    np.testing.assert_allclose(tr.directors[0][0], rod.directors(n), atol=1e-12)
    assert np.abs(x[:, 0]).max() < 1e-9, "the pin moved"
    tip_x = x[:, -1, 0]
    assert tip_x[-1] < tip_x[0] and np.all(np.diff(tip_x) < 1e-6), tip_x
    strain = np.linalg.norm(np.diff(x, axis=1), axis=2) / (rod.length / n) - 1
    bound = 1.2 * rod.material.density * 9.81 * rod.length / rod.material.youngs_modulus
    assert np.abs(strain).max() < bound, f"max element strain {np.abs(strain).max()}"


def test_contact_scenes_model_choices():
    """The contact scenes' models, from their settings (nothing is solved).

    Crossing: both ropes in one linkage, planar (two ropes crossing at a right
    angle press along gravity), divided where they cross (the shear force jumps
    there), solved by the contact statics from the initial shapes (should its
    equilibrium be unstable: settled by the damped dynamics, constant linearly
    implicit Euler steps, for half the duration and solved by Newton's method from
    there), a rod-pair stiffness that sinks the ropes' weight by 2e-3 of the
    radius. Capstan: the free rope on a planar free joint, damped
    dynamics with friction against the cylinder (a capsule) on several divisions.
    Pile: a 3D rope on a prismatic (lowered) start, Bogacki-Shampine's explicit
    3(2) pair (a W of every segment pair would cost more than the explicit steps it
    saves) with the heap's softer
    laws: self-contact sinks the rope's weight by 5e-2 of the radius, the floor four
    layers of it by 5e-3 (stiffer as the square of a feed faster than 0.4 m/s),
    friction regularised at 1e-2 m/s.
    """
    solver = SorojaxSolver()
    s = solver.settings(crossing.scenario, n_elements=51, n_frames=3)
    m = s["model"]
    assert m["rods"] == [0, 1] and m["divisions"] == 2, m
    assert m["method"] == "statics" and m["start_joint"] == "R", m
    assert m["orders"]["bend_y"] == 10 and m["solver"].startswith("solve_statics"), m
    # frictionless and quasi-static: were the equilibrium unstable, settled by
    # constant linearly implicit Euler steps, then Newton's equilibrium from there
    assert m["settle"].startswith("rosenbrock_euler, constant steps"), m
    assert m["then"].startswith("solve_statics from the state at 0.5"), m
    m31 = solver.settings(crossing.scenario, n_elements=31, n_frames=3)["model"]
    assert m31["orders"]["bend_y"] == 6 and m31["method"] == "statics", m31
    rod = crossing.scenario.rods[0]
    weight = rod.material.density * rod.area * rod.length * 9.81
    k = s["contact"]["rod_rod_stiffness_N_per_m"]
    np.testing.assert_allclose(weight / k, 2e-3 * rod.radius, rtol=1e-9)

    s = solver.settings(capstan.scenario, n_elements=100, n_frames=3)
    m = s["model"]
    assert m["method"] == "damped" and m["start_joint"] == "A", m
    assert m["divisions"] == 10 and m["end_closure"] is None, m
    assert s["contact"]["cylinder_friction"] == 0.3, s["contact"]
    # divisions end where the draped rope's curvature jumps: at the wrap's ends,
    # 0.15 m of rest length from the light end and a half-turn of the wrap radius
    # further (its tension stretches it by under 1e-3), to within a point spacing
    rod = capstan.scenario.rods[0]
    L = rod.length
    wrap = np.pi * (0.05 + rod.radius)
    np.testing.assert_allclose(
        np.asarray(adapter._kinks(rod)) * L, [0.15, 0.15 + wrap], atol=3e-3
    )
    cuts = adapter._divided(10, adapter._kinks(rod))
    assert len(cuts) == 9 and all(k in cuts for k in adapter._kinks(rod)), cuts
    # a straight rod has none
    assert adapter._kinks(crossing.scenario.rods[0]) == ()

    s = solver.settings(pile.scenario, n_elements=100, n_frames=3)
    m = s["model"]
    assert m["method"] == "damped" and m["start_joint"] == "P", m
    assert m["solver"] == "bosh3" and m["rtol"] == adapter.CONTACT_RTOL, m
    assert {"bend_y", "bend_z", "torsion"} <= set(m["orders"]), m  # 3D
    rod = pile.scenario.rods[0]
    w_len = rod.material.density * rod.area * 9.81
    c = s["contact"]
    np.testing.assert_allclose(
        w_len * rod.length / c["rod_rod_stiffness_N_per_m"],
        adapter.HEAP_PENETRATION * rod.radius,
        rtol=1e-9,
    )
    np.testing.assert_allclose(
        adapter.PILE_LAYERS * w_len / c["plane_stiffness_N_per_m2"],
        adapter.HEAP_FLOOR_PENETRATION * rod.radius,
        rtol=1e-9,
    )
    assert c["stick_velocity_m_per_s"] == adapter.HEAP_STICK_VELOCITY
    np.testing.assert_allclose(
        c["plane_stick_load_N_per_m"],
        adapter.HEAP_STICK_LOAD * adapter.PILE_LAYERS * w_len,
        rtol=1e-9,
    )
    assert m["controller_gains"] == list(adapter.HEAP_CONTROLLER_GAINS), m
    # a feed twice as fast lands the rope's end twice as fast: an impact goes
    # v sqrt(m / k) deep, so the floor is four times as stiff (the same depth);
    # the default feed (0.4 m/s) and slower ones keep the floor above
    for speed, scale in ((0.8, 4.0), (0.2, 1.0)):
        scene = pile.build(speed=speed, friction=0.3, youngs_modulus=1e6)
        assert adapter._feed_speed(scene) == pytest.approx(speed, rel=1e-12)
        ck = solver.settings(scene, n_elements=100, n_frames=3)["contact"]
        np.testing.assert_allclose(
            ck["plane_stiffness_N_per_m2"] / c["plane_stiffness_N_per_m2"],
            scale,
            rtol=1e-9,
        )
