"""The scene commands: ``sorojax check | statics | simulate | plot`` on the manual's
models as files (examples/scenes/), giving the figures of their Python examples.

The files are the Python examples' models (equal pytrees), so the command line's
solutions equal the API's to round-off: compared to 1e-12.
"""

import math
import pathlib

import jax.numpy as jnp
import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

from test_scene_files import _example, assert_same_model  # noqa: E402

import sorojax as sj  # noqa: E402
from sorojax import _mechanisms, scenes  # noqa: E402
from sorojax._cli import main  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENES = ROOT / "examples" / "scenes"


def test_scene_files_are_the_examples_models():
    """examples/scenes/*.toml hold exactly the Python examples' linkages."""
    models = {
        "manual_hybrid": scenes.manual_hybrid(),
        "cable_manipulator": _mechanisms.cable_manipulator(
            order=2, eta=_example("cable_manipulator").ETA
        ),
        "gripper_finger": scenes.gripper_finger(),
        "grasp": _example("grasp").gripper(),
    }
    assert sorted(p.stem for p in SCENES.glob("*.toml")) == sorted(models)
    for name, linkage in models.items():
        assert_same_model(sj.load_linkage(SCENES / f"{name}.toml"), linkage)


def test_manual_hybrid_statics_by_command_line(tmp_path, capsys):
    """`sorojax statics examples/scenes/manual_hybrid.toml`: the revolute torque
    (-0.8168 N m, examples/manual_hybrid.py) and every tip pose equal the API's
    solve of the same scene to 1e-12; the solution and the figure are written,
    and `sorojax plot` draws the solution again from the file alone."""
    out, fig = tmp_path / "hybrid.npz", tmp_path / "hybrid.png"
    code = main(["statics", str(SCENES / "manual_hybrid.toml"), "-o", str(out),
                 "--figure", str(fig)])  # fmt: skip
    text = capsys.readouterr().out
    assert code == 0, text
    assert "converged" in text and "-0.8168" in text
    saved = np.load(out)
    lk = scenes.manual_hybrid()
    sol = sj.solve_statics(lk, u=jnp.array([-math.pi / 4, 50.0]), throw=False)
    assert sol.result == sj.RESULTS.successful
    np.testing.assert_allclose(saved["efforts"], sol.efforts, rtol=0, atol=1e-12)
    assert abs(float(saved["efforts"][0]) + 0.8168) < 1e-4
    g = np.asarray(sj.forward_kinematics(lk, sol.q))
    tips = np.stack([g[lk.tip_point(i)] for i in range(1, lk.n_links + 1)])
    np.testing.assert_allclose(saved["tips"], tips, rtol=0, atol=1e-12)
    assert fig.stat().st_size > 10_000
    plot = tmp_path / "again.png"
    assert main(["plot", str(out), "-o", str(plot)]) == 0
    assert plot.stat().st_size > 10_000


def test_finger_and_arm_statics_by_command_line(tmp_path, capsys):
    """The gripper finger at 8 N curls past 90 degrees (examples/gripper_finger.py)
    and the cable arm's tip under 5 N on its +y cable (examples/cable_manipulator.py's
    tip_of) moves in the y-z plane only: both equal the API's solve to 1e-12."""
    out = tmp_path / "finger.npz"
    assert main(["statics", str(SCENES / "gripper_finger.toml"), "-o", str(out),
                 "--figure", ""]) == 0  # fmt: skip
    finger = scenes.gripper_finger()
    sol = sj.solve_statics(finger, u=jnp.array([8.0]), throw=False)
    q = np.load(out)["q"]
    np.testing.assert_allclose(q, sol.q, rtol=0, atol=1e-12)
    assert math.degrees(scenes.finger_curl(finger, q)) > 90
    out = tmp_path / "arm.npz"
    assert main(["statics", str(SCENES / "cable_manipulator.toml"), "-o", str(out),
                 "--figure", ""]) == 0  # fmt: skip
    ex = _example("cable_manipulator")
    arm = _mechanisms.cable_manipulator(order=2, eta=ex.ETA)
    tip, _ = ex.tip_of(arm, [5.0, 0.0, 0.0, 0.0])
    saved = np.load(out)["tips"][-1][:3, 3]
    np.testing.assert_allclose(saved, tip, rtol=0, atol=1e-12)
    assert abs(saved[0]) < 1e-12 and saved[1] > 0.05
    capsys.readouterr()


def test_check_help_and_exit_codes(tmp_path, capsys):
    """check prints the model (exit 0); a bad file exits 2 naming file, key and
    line; an existing output exits 3 and is left unchanged; a trajectory without
    its scene exits 2; every command has --help."""
    for name in ("manual_hybrid", "cable_manipulator", "gripper_finger", "grasp"):
        assert main(["check", str(SCENES / f"{name}.toml")]) == 0
        text = capsys.readouterr().out
        assert "ndof = " in text and "total mass" in text and "actuator 1" in text
    assert "closed loop 1: joint N" in (
        main(["check", str(SCENES / "manual_hybrid.toml")]) or capsys.readouterr().out
    )
    bad = tmp_path / "bad.toml"
    bad.write_text((SCENES / "gripper_finger.toml").read_text().replace(
        "E = 1000000.0", "E = -1.0", 1))  # fmt: skip
    assert main(["check", str(bad)]) == 2
    err = capsys.readouterr().err
    line = (
        bad.read_text()
        .splitlines()
        .index(next(x for x in bad.read_text().splitlines() if "E = -1.0" in x))
    )
    assert str(bad) in err and "links[0].material.E" in err and "-1.0" in err
    assert f"line {line + 1}:" in err
    taken = tmp_path / "taken.npz"
    taken.write_bytes(b"a user's file")
    code = main(["statics", str(SCENES / "gripper_finger.toml"), "-o", str(taken)])
    assert code == 3 and taken.read_bytes() == b"a user's file"
    assert "--overwrite" in capsys.readouterr().err
    traj = tmp_path / "t.npz"
    np.savez(traj, t=np.zeros(1))
    assert main(["plot", str(traj)]) == 2
    assert "--scene" in capsys.readouterr().err
    for command in ("check", "statics", "simulate", "plot"):
        with pytest.raises(SystemExit) as info:
            main([command, "--help"])
        assert info.value.code == 0
        assert "exit codes" in capsys.readouterr().out


def test_simulate_by_command_line(tmp_path, capsys):
    """`sorojax simulate` integrates the finger with [simulate]'s settings (t1 from
    the command line) and writes the trajectory that simulate gives (1e-12) and a
    figure; `sorojax plot --scene` draws it again."""
    out, fig = tmp_path / "finger.npz", tmp_path / "finger.png"
    path = SCENES / "gripper_finger.toml"
    code = main(["simulate", str(path), "--t1", "0.05", "-o", str(out), "--figure",
                 str(fig), "--no-progress"])  # fmt: skip
    assert code == 0, capsys.readouterr().out
    traj = sj.load_trajectory(out)
    scene = sj.load_scene(path)
    kw = {k: v for k, v in scene.simulate.items() if k != "t1"}
    kw["u"] = jnp.asarray(kw["u"])
    ref = sj.simulate(scene.linkage, 0.05, throw=False, **kw)
    np.testing.assert_allclose(traj.q, ref.q, rtol=0, atol=1e-12)
    assert len(traj.t) == 41 and fig.stat().st_size > 10_000
    plot = tmp_path / "plot.png"
    assert main(["plot", str(out), "--scene", str(path), "-o", str(plot)]) == 0
    assert plot.stat().st_size > 10_000


@pytest.mark.slow
def test_grasp_by_command_line(tmp_path, capsys):
    """`sorojax simulate examples/scenes/grasp.toml` (1 s, linearly implicit Euler
    at 2 ms, tension 4 N) holds the ball as examples/grasp.py's grasp() does: the
    ball's final height equals the example's to 1e-9 m; --video writes an
    animation."""
    out = tmp_path / "grasp.npz"
    code = main(["simulate", str(SCENES / "grasp.toml"), "-o", str(out),
                 "--figure", "", "--video", str(tmp_path / "grasp.gif"),
                 "--no-progress"])  # fmt: skip
    assert code == 0, capsys.readouterr().out
    ex = _example("grasp")
    lk = ex.gripper()
    _, ball, _ = ex.grasp(lk, 4.0, 1.0)
    q = sj.load_trajectory(out).q
    g = np.asarray(sj.forward_kinematics(lk, q[-1]))
    height = g[lk.layout.links[3].cm_point, 2, 3]
    assert abs(height - ball[-1]) < 1e-9, (height, ball[-1])
    assert height > 0.04, "the ball was lifted"
    assert (tmp_path / "grasp.gif").stat().st_size > 10_000
