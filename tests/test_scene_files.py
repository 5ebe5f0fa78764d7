"""Scene files: every model saved and loaded back is the same pytree; bad files are
refused with the file, the key, its line and the value named.

Equality is exact: the same tree structure (static fields included: joint counts,
orders, hooks' functions) and every array leaf bit for bit with its dtype and shape.
Two equal pytrees run the same compiled programs on the same numbers, so their
statics agree exactly; a few scenes check that directly (1e-12, the acceptance's
figure)."""

import importlib.util
import inspect
import pathlib
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
import sorojax.scenes as scenes
from sorojax import _mechanisms
from sorojax.io._scene import SPECS, dumps_scene, key_reference, loads_scene

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"
DOCS = pathlib.Path(__file__).resolve().parent.parent / "docs"


def _example(name):
    """Import ``examples/<name>.py`` as the module ``name`` (importable by name, so
    that its functions save as ``name:function``)."""
    if name in sys.modules:
        return sys.modules[name]
    if str(EXAMPLES) not in sys.path:
        sys.path.append(str(EXAMPLES))
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def assert_same_model(a, b):
    leaves_a, tree_a = jax.tree.flatten(a)
    leaves_b, tree_b = jax.tree.flatten(b)
    assert tree_a == tree_b, "the structure (or a static field) changed"
    for x, y in zip(leaves_a, leaves_b, strict=True):
        x, y = np.asarray(x), np.asarray(y)
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x, y)


def _scene_linkages():
    out = {}
    for name, fn in inspect.getmembers(scenes, inspect.isfunction):
        if fn.__module__ != scenes.__name__:
            continue
        params = inspect.signature(fn).parameters.values()
        if any(p.default is inspect.Parameter.empty for p in params):
            continue
        value = fn()
        if isinstance(value, sj.Linkage):
            out[f"scenes.{name}"] = value
    out["mechanisms.cable_manipulator"] = _mechanisms.cable_manipulator()
    out["mechanisms.four_bar"] = _mechanisms.four_bar()
    out["mechanisms.slider_crank"] = _mechanisms.slider_crank()
    return out


def _example_linkages():
    bathe = _example("bathe_bolourchi")
    cable = _example("cable_manipulator")
    arm = _mechanisms.cable_manipulator()
    hook = cable.pd_hook(arm.tip_point(1), jnp.array([0.05, 0.1]), jnp.ones(4))
    l_beam = _example("l_beam_sorosim")
    return {
        "bathe_bolourchi.bend": bathe.bend(),
        "bathe_bolourchi.padded_bend": bathe.padded_bend(4),
        "cable_manipulator (PD hook)": _mechanisms.cable_manipulator(
            actuator_strength=hook
        ),
        "crawler_gait.crawler": _example("crawler_gait").crawler(0.5, 0.3),
        "design_optimization.build_arm": _example("design_optimization").build_arm(),
        "grasp.gripper": _example("grasp").gripper(),
        "l_beam_sorosim.l_beam": l_beam.l_beam(),
        "l_beam_sorosim.padded_l_beam": l_beam.padded_l_beam(),
        "learn_reach.make_env": _example("learn_reach").make_env().linkage,
    }


def test_every_scene_and_example_linkage_round_trips(tmp_path):
    """save_linkage then load_linkage gives the same pytree, for every built-in
    scene, the mechanisms and every example's linkage (hooks as equinox.Partial of
    module functions included)."""
    cases = {**_scene_linkages(), **_example_linkages()}
    assert len(cases) >= 20
    for k, (name, linkage) in enumerate(cases.items()):
        path = sj.save_linkage(tmp_path / f"scene{k}.toml", linkage)
        try:
            assert_same_model(sj.load_linkage(path), linkage)
        except AssertionError as err:
            raise AssertionError(f"{name}: {err}") from None


@pytest.mark.slow
def test_every_round_trip_solves_the_same_statics(tmp_path):
    """Every scene and example linkage, saved and loaded back, solves its statics
    (zero inputs, from the reference shape) to the same q as the original (1e-12)
    with the same result code, whether or not that solve converges."""
    cases = {**_scene_linkages(), **_example_linkages()}
    for name, linkage in cases.items():
        back = loads_scene(dumps_scene(linkage)).linkage
        a = sj.solve_statics(linkage, throw=False, warn_unstable=False)
        b = sj.solve_statics(back, throw=False, warn_unstable=False)
        assert a.result == b.result, name
        np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-12, err_msg=name)


def test_round_trip_statics_are_equal():
    """The reloaded demo and gripper finger solve to the same q (1e-12: the same
    programs on the same numbers give the same bits)."""
    for linkage in (scenes.demo_linkage(), scenes.gripper_finger()):
        back = loads_scene(dumps_scene(linkage)).linkage
        u = jnp.ones(linkage.n_inputs)
        a = sj.solve_statics(linkage, u=u)
        b = sj.solve_statics(back, u=u)
        np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-12)


def test_every_part_round_trips():
    """Parts no built-in scene uses: every joint type with axes, pitch and
    stiffness matrices; tapered and hollow sections, given properties and section
    models; monomial and custom bases; a curved reference and a custom profile;
    point wrenches of every kind; all cable paths and anchors; closed loops;
    added mass; every obstacle with poses, its own law and a motion; rigid contact
    shapes, radius overrides, rod pairs, tubes and self-contact."""
    law = sj.ContactLaw(1e4, 1e-4, damping=1.0, static_friction=0.5,
                        kinetic_friction=0.3, forward_friction=0.1,
                        stick_load=2.0)  # fmt: skip
    rot = np.asarray(scenes.rotation_z(0.3))
    sections = [
        sj.CircularSection((0.01, 0.006), torsion="polar", shear_coefficient=1.0),
        sj.RectangularSection(0.02, 0.01),
        sj.EllipticalSection(0.01, 0.006),
        sj.AnnularSection(0.02, 0.015),
        sj.SectionProperties(3e-4, 7e-9, 7e-9, 1.4e-8, shear_area_y=2.5e-4),
    ]
    divisions = [
        sj.Division(0.1, s, sj.MonomialBasis((1, 1, 1, 1, 0, 0), (1, 2, 0, 1, 0, 0)))
        for s in sections
    ]
    divisions[0] = sj.Division(
        0.1, sections[0], sj.LegendreBasis(), n_gauss=5, xi_ref=(0, 1.0, 0, 1, 0, 0)
    )
    tube = sj.SoftLink(
        sj.Division(0.3, sj.AnnularSection(0.02, 0.015)), sj.Material(1e6)
    )
    joints = [sj.Joint(k) for k in "NRPHUCASF"] + [
        sj.Joint("R", (0.3, -0.2, 0.9), stiffness=2.0, damping=0.1),
        sj.Joint("H", (0, 0, 1), pitch=0.01),
        sj.Joint("U", (0, 1, 0), stiffness=(1.0, 2.0)),
        sj.Joint("A", (0, 1, 0), stiffness=np.array([[2, 1, 0], [1, 2, 0], [0, 0, 1.0]])),
    ]  # fmt: skip
    links = [
        sj.SoftLink(divisions, sj.Material(2e6, 0.4, 1100, 50), sj.Joint("F"),
                    g_i=sj.translation(0.01), color="tab:red"),
        sj.RigidLink(sj.Joint("R", (0, 0, 1)), 0.1, sj.EllipticalSection(0.01, 0.02)),
        sj.RigidLink(sj.Joint("P"), 0.05, mass=0.2, inertia=np.diag([1e-4, 2e-4, 3e-4]),
                     g_i=rot, g_f=sj.translation(0.02)),
        tube,
        sj.SoftLink(sj.Division(0.2, sj.CircularSection(0.005)), sj.Material(1e6)),
    ] + [sj.RigidLink(j, 0.05) for j in joints]  # fmt: skip
    n = len(links)
    placements = np.stack([rot if i % 3 == 1 else np.eye(4) for i in range(n)])
    contact = sj.Contact(
        [
            sj.Plane((0, 0, -1.0), (0.1, 0, 1.0), name="floor"),
            sj.Sphere(0.05, (0.2, 0, 0), pose=rot),
            sj.Capsule(0.02, (0, 0, 0), (0, 0.1, 0)),
            sj.Box((0.1, 0.2, 0.3), motion=_moving_box),
        ],
        law,
        shapes={2: sj.ContactSphere(0.01, (0.01, 0, 0)), 3: sj.ContactBox((0.01,) * 3),
                6: sj.ContactCapsule(0.05, 0.01)},
        radius={1: 0.012},
        rod_pairs=[(1, 5), (5, 2)],
        self_contact=[1],
        inside=[(4, 5)],
        obstacle_laws={1: sj.ContactLaw(1e5, kind="barrier", smoothing=1e-3)},
        spacing=0.02,
        friction_in_rod_pairs=False,
        tangent_in_w=False,
        pair_capacity=64,
    )  # fmt: skip
    cables = [
        sj.Cable([sj.CableSpan(1, sj.ConstantPath(0.002, -0.001), (1, 2))], "c1"),
        sj.Cable(sj.CableSpan(1, sj.ObliquePath((0.002, 0), (0.001, 0.001)))),
        sj.Cable(sj.CableSpan(1, sj.HelicalPath(0.002, 1.5, 0.3))),
        sj.Cable(sj.CableSpan(1, sj.CustomPath(_path, jnp.array([0.001, 0.002])))),
        sj.Cable([sj.CableAnchor(0, (0.1, 0, 0)), sj.CableAnchor(1, (0, 0.001, 0), 2, 0.5),
                  sj.CableAnchor(3, at_tip=True)]),
    ]  # fmt: skip
    linkage = sj.Linkage(
        links,
        parents=[0, 1, 2, 0, 0] + [0] * (n - 5),
        placements=placements,
        gravity=(0, -9.81, 0),
        point_wrenches=[
            sj.PointWrench(1, np.arange(6.0), division=2, X1=0.5, follower=True),
            sj.PointWrench(2, _wrench, at_tip=True),
        ],
        actuators=[*cables, sj.JointActuator(2), sj.JointActuator(3, prescribed=True)],
        closed_loops=[sj.ClosedLoopJoint("R", 3, 0, g_B=rot),
                      sj.ClosedLoopJoint(sj.Joint("U", (0, 0, 1)), 2, 1)],
        custom_wrench=_hook,
        custom_actuation=eqx.Partial(_actuation, jnp.array([1.0, 2.0]), gain=3.0),
        baumgarte_time=0.05,
        contact=contact,
    )  # fmt: skip
    text = dumps_scene(linkage)
    assert_same_model(loads_scene(text).linkage, linkage)
    # a universal joint about a skew axis: its axis is read back from the cross
    # product of its free directions, exact to round-off only
    skew = sj.Joint("U", (0.3, -0.2, 0.9), stiffness=1.0)
    back = loads_scene(dumps_scene(sj.Linkage(sj.RigidLink(skew)))).linkage
    np.testing.assert_allclose(
        back.links[0].joint.directions, skew.directions, rtol=0, atol=4e-16
    )
    n_points = sj.Linkage(links[:2]).n_points
    small = sj.Linkage(links[:2], added_mass=jnp.full((n_points, 6, 6), 1e-3))
    assert_same_model(loads_scene(dumps_scene(small)).linkage, small)


def _moving_box(t):
    return sj.translation(0.1 * t)


def _path(X, params):
    return params * (1 - X)


def _wrench(t):
    return jnp.zeros(6) + t


def _hook(t, q, qd, kin):
    return jnp.zeros((kin.g.shape[0], 6))


def _actuation(a, t, q, qd, kin, u, gain):
    return jnp.zeros((kin.g.shape[0], 6))


def test_unsaveable_models_are_refused_by_name(tmp_path):
    """A lambda or a closure cannot be saved: the error names the key and says how
    to make it saveable; nothing is written."""
    rod = scenes.cantilever()
    lk = sj.Linkage(rod.links, custom_wrench=lambda t, q, qd, kin: 0.0)
    with pytest.raises(ValueError, match="custom_wrench .*module-level function"):
        sj.save_linkage(tmp_path / "x.toml", lk)
    assert not (tmp_path / "x.toml").exists()


def test_save_refuses_to_overwrite(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text("a user's file")
    with pytest.raises(FileExistsError, match="left unchanged"):
        sj.save_linkage(path, scenes.demo_linkage())
    assert path.read_text() == "a user's file"
    sj.save_linkage(path, scenes.demo_linkage(), overwrite=True)
    assert_same_model(sj.load_linkage(path), scenes.demo_linkage())


def test_settings_round_trip():
    """[statics] and [simulate] carry solve_statics's and simulate's arguments."""
    text = dumps_scene(
        scenes.demo_linkage(),
        statics={"u": [0.5], "load_steps": 4, "rtol": 1e-12},
        simulate={"t1": 2.0, "solver": "tsit5", "u": _wrench, "n_save": 11},
        description="the demo",
    )
    scene = loads_scene(text)
    assert scene.description == "the demo"
    assert scene.statics["load_steps"] == 4 and scene.statics["rtol"] == 1e-12
    np.testing.assert_array_equal(scene.statics["u"], [0.5])
    assert scene.simulate["u"] is _wrench and scene.simulate["solver"] == "tsit5"


def test_key_reference_in_docs_is_current():
    """docs/guide/scene-files.md holds the reference that the reader's schema
    generates (regenerate: python -m sorojax.io._scene > ...; see the page)."""
    page = (DOCS / "guide" / "scene-files.md").read_text()
    assert key_reference() in page, (
        "the key reference in docs/guide/scene-files.md is out of date: run "
        "`python docs/scene_reference.py`"
    )
    for name in SPECS:
        assert f"### {name}\n" in page


# ------------------------------------------------------------------ bad files
BASE = (pathlib.Path(__file__).parent / "data" / "scene_base.toml").read_text()

# (case, text replaced, replacement, key named, value named (None: the key's
# absence is the error)). Each replacement must occur in the base file.
BAD = [
    ("no format", 'format = "sorojax-scene"\n', "", "format", None),
    ("other format", 'format = "sorojax-scene"', 'format = "mjcf"', "format", "'mjcf'"),
    ("newer version", "version = 1", "version = 2", "version", "= 2"),
    ("version as text", "version = 1", 'version = "1"', "version", "'1'"),
    ("no version", "version = 1\n", "", "version", None),
    ("unknown top key", "gravity =", "gravty =", "gravty", "gravity"),
    ("gravity of two", "gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, -9.81]",
     "gravity", "(2,)"),
    ("NaN gravity", "gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, nan]",
     "gravity", "nan"),
    ("gravity as text", "gravity = [0.0, 0.0, -9.81]", 'gravity = "down"', "gravity",
     "'down'"),
    ("unknown link type", 'type = "rigid"', 'type = "elastic"', "links[0].type",
     "'elastic'"),
    ("link without type", 'type = "rigid"\n', "", "links[0].type", None),
    ("unknown joint type", 'type = "R"', 'type = "Q"', "links[0].joint.type", "'Q'"),
    ("zero joint axis", "axis = [0.0, 0.0, 1.0]", "axis = [0.0, 0.0, 0.0]",
     "links[0].joint.axis", "0.0"),
    ("negative joint stiffness", "stiffness = 1.0", "stiffness = -1.0",
     "links[0].joint.stiffness", "-1.0"),
    ("negative rigid length", "length = 0.2", "length = -0.2", "links[0].length",
     "-0.2"),
    ("material without E", "material = {E = 1e6, rho = 1000.0}",
     "material = {rho = 1000.0}", "links[1].material.E", None),
    ("E as text", "E = 1e6", 'E = "soft"', "links[1].material.E", "'soft'"),
    ("NaN E", "E = 1e6", "E = nan", "links[1].material.E", "nan"),
    ("Poisson ratio above 0.5", "rho = 1000.0}", "rho = 1000.0, poisson = 0.7}",
     "links[1].material.poisson", "0.7"),
    ("zero division length", "length = 0.3", "length = 0.0",
     "links[1].divisions[0].length", "0.0"),
    ("division without length", "length = 0.3\n", "", "links[1].divisions[0].length",
     None),
    ("negative radius", "radius = 0.01", "radius = -0.01",
     "links[1].divisions[0].section.radius", "-0.01"),
    ("unknown section type", 'type = "circular"', 'type = "hexagonal"',
     "links[1].divisions[0].section.type", "'hexagonal'"),
    ("mode flag 2", "modes = [0, 1, 1, 0, 0, 0]", "modes = [0, 1, 2, 0, 0, 0]",
     "links[1].divisions[0].basis.modes", "2"),
    ("negative order", "orders = 1", "orders = -1", "links[1].divisions[0].basis.orders",
     "-1"),
    ("misspelt key", "orders = 1", "order = 1", "links[1].divisions[0].basis.order",
     "orders"),
    ("fractional Gauss points", "length = 0.3", "length = 0.3\nn_gauss = 2.5",
     "links[1].divisions[0].n_gauss", "2.5"),
    ("parent out of range", "parent = 1", "parent = 5", "links[1].parent", "5"),
    ("link its own parent (a cycle)", "parent = 1", "parent = 2", "links[1].parent",
     "2"),
    ("parent after the link (a cycle)", 'type = "rigid"',
     'type = "rigid"\nparent = 2', "links[0].parent", "2"),
    ("wrench on a missing link", "link = 2\nwrench", "link = 9\nwrench",
     "point_wrenches[0].link", "9"),
    ("wrench of three", "wrench = [0.0, 0.0, 0.0, 0.0, 0.0, -0.1]",
     "wrench = [0.0, 0.0, -0.1]", "point_wrenches[0].wrench", "(3,)"),
    ("follower as text", "wrench = [0.0", 'follower = "yes"\nwrench = [0.0',
     "point_wrenches[0].follower", "'yes'"),
    ("cable outside its link", "y = 0.005", "y = 0.05",
     "actuators[0].route[0].path", "0.05"),
    ("cable span in a rigid link", "link = 2\npath", "link = 1\npath",
     "actuators[0].route[0].link", "1"),
    ("cable of one anchor", 'type = "span"\nlink = 2\npath = {type = "constant", y = 0.005}',
     'type = "anchor"\nlink = 2', "actuators[0].route", "single anchor"),
    ("hook that does not import", "gravity =",
     'custom_wrench = "no_such_module:f"\ngravity =', "custom_wrench",
     "'no_such_module:f'"),
    ("hook without a module", "gravity =", 'custom_wrench = "f"\ngravity =',
     "custom_wrench", "'f'"),
    ("hook missing in its module", "gravity =",
     'custom_wrench = "math:no_such_function"\ngravity =', "custom_wrench",
     "no_such_function"),
    ("law without stiffness", "law = {stiffness = 1e4, smoothing = 1e-4}",
     "law = {smoothing = 1e-4}", "contact.law.stiffness", None),
    ("unknown law kind", "smoothing = 1e-4}", 'smoothing = 1e-4, kind = "spring"}',
     "contact.law.kind", "'spring'"),
    ("negative smoothing", "smoothing = 1e-4}", "smoothing = -1e-4}",
     "contact.law.smoothing", "-0.0001"),
    ("unknown obstacle", 'type = "plane"', 'type = "cone"',
     "contact.obstacles[0].type", "'cone'"),
    ("statics input as text", "u = [1.0]", 'u = ["a"]', "statics.u", "'a'"),
    ("statics input of two", "u = [1.0]", "u = [1.0, 2.0]", "statics.u", "2"),
    ("TOML syntax", "length = 0.2", "length = = 0.2", "", "TOML"),
]  # fmt: skip


# errors of a whole table (the cable's route as one), at the table's header
TABLE_LEVEL = {"cable of one anchor"}


@pytest.mark.parametrize(
    ("case", "old", "new", "key", "value"), BAD, ids=[b[0] for b in BAD]
)
def test_bad_scene_file_is_refused(tmp_path, case, old, new, key, value):
    assert BASE.count(old) >= 1, f"{case}: the base file lacks {old!r}"
    text = BASE.replace(old, new, 1)
    path = tmp_path / "bad scene.toml"
    path.write_text(text)
    with pytest.raises(sj.SceneError) as info:
        scene = sj.load_scene(path)
        if case.startswith("statics input"):  # checked against the model by the CLI
            from sorojax._cli_scene import _sized_arguments

            _sized_arguments(scene, "statics")
    err = info.value
    message = str(err)
    assert str(path) in message, message
    assert key in message, message
    if value is not None:
        assert value in message, message
    else:
        assert "missing" in message, message
    if value is not None:  # the line of the changed text (or of its table)
        first = text[: text.index(new)].count("\n") + 1
        assert err.line is not None, message
        if case in TABLE_LEVEL:
            assert text.splitlines()[err.line - 1].startswith("[[actuators]]")
        else:
            assert first <= err.line <= first + new.count("\n"), (err.line, first)


def test_base_scene_is_valid():
    """The malformed files above differ from a valid file by one edit each."""
    scene = loads_scene(BASE)
    assert scene.linkage.n_dof == 5 and scene.linkage.contact is not None
    np.testing.assert_array_equal(scene.statics["u"], [1.0])
