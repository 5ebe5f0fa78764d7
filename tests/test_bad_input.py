"""Bad input across the public API: each case fails with a message that says what.

Every case calls one public entry point with one wrong value and asserts that the
error names the field and the value (the regexes below), so a user can find the
mistake without reading sorojax's source. The fix each message proposes is read by
eye: the regexes pin the field and the value, not the wording. Almost every case
fails while the model is built or before anything is traced (no compile), so the
file runs in a few seconds.
"""

import functools
import math
import re
import tempfile

import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj

NAN = math.nan


# ----------------------------------------------------------------- small models
def _division(length=0.2, radius=0.01, modes=(0, 1, 1, 0, 0, 0), order=0, **kw):
    return sj.Division(
        length, sj.CircularSection(radius), sj.LegendreBasis(modes, order), **kw
    )


def _material(**kw):
    return sj.Material(**{"E": 1e6, "poisson": 0.5, "rho": 1000.0, **kw})


def _soft(**kw):
    return sj.SoftLink([_division(**kw)], _material())


@functools.cache
def _rod() -> sj.Linkage:
    """A clamped rod, 2 DoF, no actuators, no loads."""
    return sj.Linkage([_soft()])


@functools.cache
def _cable_rod() -> sj.Linkage:
    """The rod with one cable at +y, 5 mm off the axis (half its radius)."""
    cable = sj.Cable([sj.CableSpan(1, sj.ConstantPath(0.005, 0.0))])
    return sj.Linkage([_soft()], actuators=[cable])


def _linkage(**kw):
    return sj.Linkage([_soft()], **kw)


def _cable(y=0.005, z=0.0, link=1):
    return sj.Linkage(
        [_soft()], actuators=[sj.Cable([sj.CableSpan(link, sj.ConstantPath(y, z))])]
    )


def _wrench(w, **kw):
    return sj.Linkage([_soft()], point_wrenches=[sj.PointWrench(1, w, **kw)])


def _statics(**kw):
    return sj.solve_statics(_rod(), **kw)


def _simulate(t1=0.1, **kw):
    return sj.simulate(_rod(), t1, **kw)


def _environment(**kw):
    return sj.Environment(_cable_rod(), **{"period": 0.05, **kw})


def _trajectory():
    n = _rod().n_dof
    zero = np.zeros((), int)
    return sj.Trajectory(
        t=np.linspace(0.0, 0.1, 3),
        q=np.zeros((3, n)),
        qd=np.zeros((3, n)),
        result=sj.RESULTS.successful,
        num_steps=zero,
        num_accepted_steps=zero,
        num_rejected_steps=zero,
    )


def _save(name, **kw):
    folder = tempfile.mkdtemp()
    return sj.save_trajectory(f"{folder}/{name}", _trajectory(), **kw)


def _save_twice():
    path = f"{tempfile.mkdtemp()}/run.npz"
    sj.save_trajectory(path, _trajectory())
    return sj.save_trajectory(path, _trajectory())


def _load_not_a_trajectory():
    path = f"{tempfile.mkdtemp()}/other.npz"
    np.savez(path, x=np.zeros(3))
    return sj.load_trajectory(path)


def _sweep(*args, **kw):
    return sj.sweep(lambda x: x, *args, **kw)


# --------------------------------------------------------------------- the cases
# (id, call, exception, regexes that must all appear in the message: field, value)
CASES = [
    # materials
    ("material-E-negative", lambda: _material(E=-1.0), ValueError, [r"E\b", r"-1"]),
    ("material-E-zero", lambda: _material(E=0.0), ValueError, [r"E\b", r"0"]),
    ("material-E-nan", lambda: _material(E=NAN), ValueError, [r"E\b", r"nan"]),
    ("material-E-inf", lambda: _material(E=math.inf), ValueError, [r"E\b", r"inf"]),
    (
        "material-poisson",
        lambda: _material(poisson=0.7),
        ValueError,
        [r"poisson", r"0\.7"],
    ),
    ("material-rho", lambda: _material(rho=-5.0), ValueError, [r"rho", r"-5"]),
    ("material-eta", lambda: _material(eta=-1.0), ValueError, [r"eta", r"-1"]),
    # sections
    (
        "circle-radius-negative",
        lambda: sj.CircularSection(-0.01),
        ValueError,
        [r"radius", r"-0\.01"],
    ),
    (
        "circle-radius-zero",
        lambda: sj.CircularSection(0.0),
        ValueError,
        [r"radius", r"0"],
    ),
    (
        "circle-taper-negative",
        lambda: sj.CircularSection((0.02, -0.01)),
        ValueError,
        [r"radius", r"-0\.01"],
    ),
    (
        "circle-torsion",
        lambda: sj.CircularSection(0.01, torsion="bogus"),
        ValueError,
        [r"torsion", r"bogus"],
    ),
    (
        "rectangle-width",
        lambda: sj.RectangularSection(0.01, 0.0),
        ValueError,
        [r"width", r"0"],
    ),
    (
        "ellipse-b",
        lambda: sj.EllipticalSection(0.01, -0.02),
        ValueError,
        [r"\bb\b", r"-0\.02"],
    ),
    (
        "annulus-inner",
        lambda: sj.AnnularSection(0.01, 0.02),
        ValueError,
        [r"inner", r"0\.02"],
    ),
    (
        "properties-area",
        lambda: sj.SectionProperties(-1.0, 1e-8, 1e-8, 2e-8),
        ValueError,
        [r"\bA\b", r"-1"],
    ),
    # strain bases and divisions
    (
        "basis-modes-length",
        lambda: sj.LegendreBasis((1, 1, 1, 0, 0)),
        ValueError,
        [r"modes", r"\(1, 1, 1, 0, 0\)"],
    ),
    (
        "basis-modes-flag",
        lambda: sj.LegendreBasis((0, 0, 0, 0, 0, 2)),
        ValueError,
        [r"modes", r"2"],
    ),
    (
        "basis-order",
        lambda: sj.LegendreBasis((0, 1, 0, 0, 0, 0), -1),
        ValueError,
        [r"order", r"-1"],
    ),
    (
        "division-length",
        lambda: _division(length=-0.1),
        ValueError,
        [r"length", r"-0\.1"],
    ),
    (
        "division-length-nan",
        lambda: _division(length=NAN),
        ValueError,
        [r"length", r"nan"],
    ),
    ("division-n_gauss", lambda: _division(n_gauss=0), ValueError, [r"n_gauss", r"0"]),
    (
        "division-xi_ref-shape",
        lambda: _division(xi_ref=(0, 0, 0, 1, 0)),
        ValueError,
        [r"xi_ref", r"\(5,\)"],
    ),
    (
        "division-xi_ref-collapsed",
        lambda: _division(xi_ref=(0, 0, 0, 0, 0, 0)),
        ValueError,
        [r"xi_ref", r"gx", r"0"],
    ),
    # links
    (
        "softlink-no-divisions",
        lambda: sj.SoftLink([], _material()),
        ValueError,
        [r"divisions", r"\(\)"],
    ),
    (
        "softlink-material",
        lambda: sj.SoftLink([_division()], "steel"),
        ValueError,
        [r"material", r"steel"],
    ),
    (
        "rigidlink-length",
        lambda: sj.RigidLink(length=-1.0),
        ValueError,
        [r"length", r"-1"],
    ),
    ("rigidlink-mass", lambda: sj.RigidLink(mass=-1.0), ValueError, [r"mass", r"-1"]),
    (
        "rigidlink-inertia",
        lambda: sj.RigidLink(mass=1.0, inertia=-np.eye(3)),
        ValueError,
        [r"inertia", r"-1"],
    ),
    (
        "rigidlink-g_i",
        lambda: sj.RigidLink(g_i=np.ones((4, 4))),
        ValueError,
        [r"g_i", r"SE\(3\)"],
    ),
    # joints
    ("joint-kind", lambda: sj.Joint("Q"), ValueError, [r"kind", r"Q"]),
    (
        "joint-axis-zero",
        lambda: sj.Joint("R", (0.0, 0.0, 0.0)),
        ValueError,
        [r"axis", r"0"],
    ),
    (
        "joint-stiffness",
        lambda: sj.Joint("R", stiffness=-1.0),
        ValueError,
        [r"stiffness", r"-1"],
    ),
    (
        "joint-damping",
        lambda: sj.Joint("R", damping=-2.0),
        ValueError,
        [r"damping", r"-2"],
    ),
    (
        "joint-pitch-nan",
        lambda: sj.Joint("H", pitch=NAN),
        ValueError,
        [r"pitch", r"nan"],
    ),
    # linkages
    ("linkage-no-links", lambda: sj.Linkage([]), ValueError, [r"links", r"empty"]),
    (
        "linkage-parent-self",
        lambda: sj.Linkage([_soft()], parents=(1,)),
        ValueError,
        [r"parent", r"1"],
    ),
    (
        "linkage-parents-length",
        lambda: sj.Linkage([_soft(), _soft()], parents=(0,)),
        ValueError,
        [r"parents", r"1 entries for 2 links"],
    ),
    (
        "linkage-placements-shape",
        lambda: _linkage(placements=np.eye(4)),
        ValueError,
        [r"placements", r"\(4, 4\)"],
    ),
    (
        "linkage-baumgarte",
        lambda: _linkage(baumgarte_time=0.0),
        ValueError,
        [r"baumgarte_time", r"0"],
    ),
    (
        "linkage-added-mass-shape",
        lambda: _linkage(added_mass=np.eye(3)),
        ValueError,
        [r"added_mass", r"\(3, 3\)"],
    ),
    (
        "closed-loop-link",
        lambda: _linkage(closed_loops=[sj.ClosedLoopJoint("R", 5)]),
        ValueError,
        [r"link_A", r"5"],
    ),
    # loads
    (
        "gravity-shape",
        lambda: _linkage(gravity=(0.0, -9.81)),
        ValueError,
        [r"gravity", r"\(2,\)"],
    ),
    (
        "gravity-nan",
        lambda: _linkage(gravity=(0.0, 0.0, NAN)),
        ValueError,
        [r"gravity", r"nan"],
    ),
    (
        "gravity-inf",
        lambda: _linkage(gravity=(math.inf, 0.0, 0.0)),
        ValueError,
        [r"gravity", r"inf"],
    ),
    (
        "wrench-nan",
        lambda: _wrench((0, 0, 0, NAN, 0, 0)),
        ValueError,
        [r"wrench", r"nan"],
    ),
    (
        "wrench-shape",
        lambda: _wrench((1.0, 2.0, 3.0)),
        ValueError,
        [r"wrench", r"\(3,\)"],
    ),
    ("wrench-X1", lambda: _wrench(np.zeros(6), X1=1.5), ValueError, [r"X1", r"1\.5"]),
    (
        "wrench-division",
        lambda: _wrench(np.zeros(6), division=3),
        ValueError,
        [r"division", r"3"],
    ),
    (
        "wrench-link",
        lambda: sj.Linkage([_soft()], point_wrenches=[sj.PointWrench(4, np.zeros(6))]),
        ValueError,
        [r"link", r"4"],
    ),
    # actuators and cables
    (
        "cable-offset-outside",
        lambda: _cable(y=0.5),
        ValueError,
        [r"offset", r"0\.5", r"radius"],
    ),
    ("cable-offset-nan", lambda: _cable(z=NAN), ValueError, [r"offset|path", r"nan"]),
    ("cable-link-range", lambda: _cable(link=5), ValueError, [r"link", r"5"]),
    ("cable-empty-route", lambda: sj.Cable([]), ValueError, [r"route", r"\(\)"]),
    (
        "cable-on-rigid-link",
        lambda: sj.Linkage(
            [sj.RigidLink(sj.Joint("R"))],
            actuators=[sj.Cable([sj.CableSpan(1, sj.ConstantPath(0.0, 0.0))])],
        ),
        ValueError,
        [r"link", r"1", r"rigid|soft"],
    ),
    (
        "helix-radius",
        lambda: sj.HelicalPath(-0.01, 2.0),
        ValueError,
        [r"radius", r"-0\.01"],
    ),
    (
        "oblique-shape",
        lambda: sj.ObliquePath((0.0, 0.0), (0.0,)),
        ValueError,
        [r"end", r"\(1,\)"],
    ),
    (
        "joint-actuator-fixed",
        lambda: _linkage(actuators=[sj.JointActuator(1)]),
        ValueError,
        [r"actuators\[0\]", r"link 1", r"'N'"],
    ),
    (
        "joint-actuator-range",
        lambda: sj.Linkage(
            [sj.RigidLink(sj.Joint("R"))], actuators=[sj.JointActuator(3)]
        ),
        ValueError,
        [r"link", r"3"],
    ),
    # statics settings
    (
        "statics-u-without-actuators",
        lambda: _statics(u=[1.0]),
        ValueError,
        [r"\bu = \[1\.0\]", r"n_inputs = 0"],
    ),
    (
        "statics-u-length",
        lambda: sj.solve_statics(_cable_rod(), u=[1.0, 2.0]),
        ValueError,
        [r"\bu\b", r"\(2,\)", r"n_inputs = 1"],
    ),
    (
        "statics-u-nan",
        lambda: sj.solve_statics(_cable_rod(), u=[NAN]),
        ValueError,
        [r"\bu\b", r"nan"],
    ),
    (
        "statics-q0-shape",
        lambda: _statics(q0=np.zeros(5)),
        ValueError,
        [r"q0", r"\(5,\)"],
    ),
    ("statics-q0-nan", lambda: _statics(q0=[NAN, 0.0]), ValueError, [r"q0", r"nan"]),
    (
        "statics-max_steps",
        lambda: _statics(max_steps=0),
        ValueError,
        [r"max_steps", r"0"],
    ),
    ("statics-rtol", lambda: _statics(rtol=-1e-8), ValueError, [r"rtol", r"-1e-08"]),
    (
        "statics-load_steps",
        lambda: _statics(load_steps=0),
        ValueError,
        [r"load_steps", r"0"],
    ),
    (
        "statics-max_load_steps",
        lambda: _statics(max_load_steps=0),
        ValueError,
        [r"max_load_steps", r"0"],
    ),
    (
        "statics-load_increment",
        lambda: _statics(load_increment=0.0),
        ValueError,
        [r"load_increment", r"0"],
    ),
    # simulate settings
    (
        "simulate-t1-before-t0",
        lambda: _simulate(t1=0.1, t0=0.5),
        ValueError,
        [r"t1", r"0\.1", r"t0", r"0\.5"],
    ),
    ("simulate-t1-nan", lambda: _simulate(t1=NAN), ValueError, [r"t1", r"nan"]),
    ("simulate-n_save", lambda: _simulate(n_save=0), ValueError, [r"n_save", r"0"]),
    (
        "simulate-solver-name",
        lambda: _simulate(solver="euler-ish"),
        ValueError,
        [r"solver", r"euler-ish"],
    ),
    ("simulate-rtol", lambda: _simulate(rtol=-1e-3), ValueError, [r"rtol", r"-0\.001"]),
    ("simulate-dt0", lambda: _simulate(dt0=-0.01), ValueError, [r"dt0", r"-0\.01"]),
    (
        "simulate-fixed-step-without-dt0",
        lambda: _simulate(adaptive=False),
        ValueError,
        [r"adaptive=False", r"dt0 = None"],
    ),
    (
        "simulate-q0-shape",
        lambda: _simulate(q0=np.zeros(3)),
        ValueError,
        [r"q0", r"\(3,\)"],
    ),
    (
        "simulate-qd0-nan",
        lambda: _simulate(qd0=[0.0, NAN]),
        ValueError,
        [r"qd0", r"nan"],
    ),
    (
        "simulate-ts-decreasing",
        lambda: _simulate(ts=np.array([0.0, 0.1, 0.05])),
        ValueError,
        [r"ts", r"0\.05"],
    ),
    (
        "simulate-u-without-actuators",
        lambda: _simulate(u=[1.0]),
        ValueError,
        [r"\bu\b", r"\(1,\)", r"n_inputs = 0"],
    ),
    (
        "simulate-max_steps",
        lambda: _simulate(max_steps=0),
        ValueError,
        [r"max_steps", r"0"],
    ),
    (
        "simulate-u-nan",
        lambda: sj.simulate(_cable_rod(), 0.1, u=[NAN]),
        ValueError,
        [r"\bu\b", r"nan"],
    ),
    # files
    ("save-suffix", lambda: _save("run.txt"), ValueError, [r"\.txt", r"\.npz"]),
    ("save-exists", _save_twice, FileExistsError, [r"run\.npz", r"overwrite"]),
    (
        "load-missing",
        lambda: sj.load_trajectory("/nonexistent/run.npz"),
        FileNotFoundError,
        [r"/nonexistent/run\.npz"],
    ),
    (
        "load-not-a-trajectory",
        _load_not_a_trajectory,
        ValueError,
        [r"other\.npz", r"\bq\b|ts"],
    ),
    # sweeps
    (
        "sweep-unequal",
        lambda: _sweep(np.zeros(3), np.zeros(4)),
        ValueError,
        [r"3", r"4"],
    ),
    ("sweep-empty", lambda: _sweep(np.zeros((0, 2))), ValueError, [r"no cases", r"0"]),
    ("sweep-chunk", lambda: _sweep(np.zeros(3), chunk=0), ValueError, [r"chunk", r"0"]),
    # environment
    (
        "environment-period",
        lambda: _environment(period=0.0),
        ValueError,
        [r"period", r"0"],
    ),
    (
        "environment-period-nan",
        lambda: _environment(period=NAN),
        ValueError,
        [r"period", r"nan"],
    ),
    ("environment-dt", lambda: _environment(dt=-0.01), ValueError, [r"dt", r"-0\.01"]),
    (
        "environment-q0-shape",
        lambda: _environment(q0=jnp.zeros(4)),
        ValueError,
        [r"q0", r"\(4,\)"],
    ),
    (
        "environment-u0-shape",
        lambda: _environment(u0=jnp.zeros(3)),
        ValueError,
        [r"u0", r"\(3,\)"],
    ),
    (
        "environment-noise",
        lambda: _environment(noise=-0.1),
        ValueError,
        [r"noise", r"-0\.1"],
    ),
    (
        "environment-solver-auto",
        lambda: _environment(solver="auto"),
        ValueError,
        [r"solver", r"auto"],
    ),
    (
        "environment-dt-not-dividing",
        lambda: _environment(dt=0.03),
        ValueError,
        [r"dt", r"0\.03"],
    ),
    (
        "forward_dynamics-u-without-actuators",
        lambda: sj.forward_dynamics(_rod(), jnp.zeros(2), jnp.zeros(2), u=[2.0]),
        ValueError,
        [r"\bu has shape \(1,\)", r"n_inputs = 0"],
    ),
    # kinematics
    (
        "tip_pose-link",
        lambda: sj.tip_pose(_rod(), jnp.zeros(2), link=4),
        ValueError,
        [r"link", r"4"],
    ),
    (
        "forward_kinematics-q",
        lambda: sj.forward_kinematics(_rod(), jnp.zeros(5)),
        ValueError,
        [r"\bq\b", r"\(5,\)"],
    ),
    (
        "strain-collapsed",
        lambda: sj.strain_coordinates(
            sj.Linkage([_soft(modes=(0, 1, 0, 1, 0, 0))]),
            [0, 1.0, 0, 0, 0, 0],
            total=True,
        ),
        ValueError,
        [r"gx = 0", r"total=True"],
    ),
    # contact
    (
        "contact-law-stiffness",
        lambda: sj.ContactLaw(-1.0),
        ValueError,
        [r"stiffness", r"-1"],
    ),
    ("sphere-radius", lambda: sj.Sphere(-0.1), ValueError, [r"radius", r"-0\.1"]),
    (
        "plane-normal",
        lambda: sj.Plane(normal=(0.0, 0.0, 0.0)),
        ValueError,
        [r"normal", r"0"],
    ),
    (
        "capsule-end-nan",
        lambda: sj.Capsule(0.01, (0.0, 0.0, 0.0), (0.0, float("nan"), 1.0)),
        ValueError,
        [r"Capsule\.end", r"nan", r"not finite"],
    ),
    (
        "capsule-zero-axis",
        lambda: sj.Capsule(0.01, (0.0, 0.0, 0.1), (0.0, 0.0, 0.1)),
        ValueError,
        [r"Capsule\.start = Capsule\.end", r"Sphere"],
    ),
    (
        "sphere-centre-inf",
        lambda: sj.Sphere(0.1, (0.0, float("inf"), 0.0)),
        ValueError,
        [r"Sphere\.centre", r"inf"],
    ),
    (
        "plane-point-nan",
        lambda: sj.Plane(point=(float("nan"), 0.0, 0.0)),
        ValueError,
        [r"Plane\.point", r"nan"],
    ),
]


@pytest.mark.parametrize(
    ("call", "error", "patterns"),
    [pytest.param(c, e, p, id=i) for i, c, e, p in CASES],
)
def test_bad_input_is_refused_naming_field_and_value(call, error, patterns):
    """The call raises ``error``; its message matches every pattern (field, value)."""
    with pytest.raises(error) as info:
        call()
    message = str(info.value)
    missing = [p for p in patterns if not re.search(p, message)]
    assert not missing, f"message {message!r} lacks {missing}"


def test_cases_cover_the_public_api():
    """At least 50 cases, and every section above has some (a coverage floor)."""
    assert len(CASES) >= 50, len(CASES)
    prefixes = {i.split("-")[0] for i, *_ in CASES}
    for part in ("material", "circle", "basis", "division", "softlink", "rigidlink",
                 "joint", "linkage", "gravity", "wrench", "cable", "statics",
                 "simulate", "save", "load", "sweep", "environment"):  # fmt: skip
        assert part in prefixes, f"no case for {part}"


def test_strain_on_components_the_basis_lacks_is_warned_of_naming_them():
    """A rod bending about y and z has no torsion or shear to fit: the fit drops them
    and says so (a warning: fitting a measured strain field to a model that leaves
    modes out is a least-squares fit by design)."""
    with pytest.warns(UserWarning, match=r"does not carry.*torsion kx = 0\.5"):
        q = sj.strain_coordinates(_rod(), [0.5, 1.0, 0, 0, 0, 0])
    np.testing.assert_allclose(q, sj.strain_coordinates(_rod(), [0, 1.0, 0, 0, 0, 0]))
    with pytest.warns(UserWarning, match=r"shear gy = 0\.0\d+"):
        sj.strain_coordinates(
            _rod(), lambda s: jnp.stack([0.0, 1.0, 0.0, 0.0, 0.2 * s, 0.0])
        )
