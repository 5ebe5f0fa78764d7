"""Trajectory animation (GIF / mp4) and time-series plots, on the Agg backend."""

import matplotlib

matplotlib.use("Agg")

import math  # noqa: E402

import jax.numpy as jnp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib import animation  # noqa: E402
from PIL import Image  # noqa: E402

import sorojax  # noqa: E402
import sorojax.scenes  # noqa: E402
from sorojax.viz import animate, plot_configuration, plot_time_series  # noqa: E402
from sorojax.viz._animate import _interpolate_q, _motion_bounds, frame_times  # noqa: E402

SMALL = {"figsize": (2.0, 2.0), "dpi": 50, "n_circle": 6, "n_sub": 1}
HAS_FFMPEG = animation.writers.is_available("ffmpeg")


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _trajectory(n_dof, t1=0.1, n_save=5):
    """A smooth hand-built motion (no simulation: nothing to compile)."""
    t = jnp.linspace(0.0, t1, n_save)
    shape = jnp.asarray([0.4, 2.0, -3.0, 1.0, 2.0, 3.0, 2.0][:n_dof])
    q = jnp.outer(jnp.sin(10.0 * t), shape)
    qd = jnp.outer(10.0 * jnp.cos(10.0 * t), shape)
    return sorojax.Trajectory(
        t=t,
        q=q,
        qd=qd,
        result=sorojax.RESULTS.successful,
        num_steps=jnp.asarray(3),
        num_accepted_steps=jnp.asarray(3),
        num_rejected_steps=jnp.asarray(0),
    )


@pytest.fixture(scope="module")
def demo():
    """The demo linkage (rigid bar + soft rod, 7 DoF; shared with test_viz) moving."""
    lk = sorojax.scenes.demo_linkage()
    return lk, _trajectory(lk.n_dof)


def _gif_frames(path):
    with Image.open(path) as im:
        assert im.format == "GIF"
        return im.n_frames


def test_frame_times_play_at_real_time_over_speed():
    tf = frame_times(0.0, 1.0, 30, 1.0)
    assert len(tf) == 31 and tf[-1] == pytest.approx(1.0)
    np.testing.assert_allclose(np.diff(tf), 1 / 30)
    tf = frame_times(0.0, 1.0, 10, 0.5)  # slow motion: 2 s of video
    assert len(tf) == 21
    np.testing.assert_allclose(np.diff(tf), 0.05)
    assert len(frame_times(0.2, 0.2, 30, 1.0)) == 1


def test_q_is_interpolated_linearly_in_time():
    t = np.array([0.0, 1.0, 3.0])
    q = np.array([[0.0, 1.0], [2.0, 1.0], [6.0, -1.0]])
    got = _interpolate_q(t, q, np.array([0.5, 2.0, 3.0]))
    np.testing.assert_allclose(got, [[1.0, 1.0], [4.0, 0.0], [6.0, -1.0]])


@pytest.mark.parametrize(("fps", "speed"), [(30, 1.0), (20, 0.5)])
def test_gif_has_one_frame_per_video_tick(tmp_path, demo, fps, speed):
    lk, traj = demo
    path = animate(lk, traj, tmp_path / "motion.gif", fps=fps, speed=speed, **SMALL)
    assert path == tmp_path / "motion.gif" and path.stat().st_size > 0
    duration = 0.1 / speed  # video seconds
    expected = math.floor(duration * fps + 1e-9) + 1  # both ends included
    assert 3 <= expected <= 5
    assert _gif_frames(path) == expected, "GIF frame count"


def test_axis_limits_hold_the_whole_motion(demo):
    lk, traj = demo
    tf = frame_times(0.0, 0.1, 30, 1.0)
    qf = _interpolate_q(np.asarray(traj.t), np.asarray(traj.q), tf)
    lo, hi = _motion_bounds(lk, qf)
    fig = plt.figure()
    ax = fig.add_subplot(projection="3d")
    for q in qf:
        ax.cla()
        plot_configuration(lk, q, ax, n_circle=6, n_sub=1)
        for coll in ax.collections:
            rings = coll.sorojax_rings.reshape(-1, 3)
            # 1e-12 m: rounding of the same forward kinematics.
            assert np.all(rings >= lo - 1e-12) and np.all(rings <= hi + 1e-12)


def test_mp4_without_ffmpeg_writes_gif_and_warns(tmp_path, demo, monkeypatch):
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    lk, traj = demo
    with pytest.warns(UserWarning, match=r"ffmpeg is not available.*motion\.gif"):
        path = animate(lk, traj, tmp_path / "motion.mp4", **SMALL)
    assert path == tmp_path / "motion.gif"
    assert not (tmp_path / "motion.mp4").exists()
    assert _gif_frames(path) == 4


def test_mp4_uses_the_ffmpeg_writer_when_available(tmp_path, demo, monkeypatch):
    # Branch check without ffmpeg: a Pillow writer stands in for FFMpegWriter.
    used = []

    class FakeFFMpegWriter(animation.PillowWriter):
        def __init__(self, fps):
            used.append(fps)
            super().__init__(fps=fps)

        def finish(self):  # Pillow picks the format from the name; force GIF
            self._frames[0].save(
                self.outfile,
                format="GIF",
                save_all=True,
                append_images=self._frames[1:],
            )

    monkeypatch.setattr(animation.writers, "is_available", lambda name: True)
    monkeypatch.setattr(animation, "FFMpegWriter", FakeFFMpegWriter)
    lk, traj = demo
    path = animate(lk, traj, tmp_path / "motion.mp4", fps=30, **SMALL)
    assert path == tmp_path / "motion.mp4" and path.stat().st_size > 0
    assert used == [30]


@pytest.mark.skipif(not HAS_FFMPEG, reason="ffmpeg is not available to matplotlib")
def test_mp4_with_real_ffmpeg(tmp_path, demo):
    lk, traj = demo
    path = animate(lk, traj, tmp_path / "motion.mp4", **SMALL)
    assert path.suffix == ".mp4"
    assert path.read_bytes()[4:8] == b"ftyp", "an MP4 container"


def test_existing_video_is_not_overwritten(tmp_path, demo, monkeypatch):
    lk, traj = demo
    gif = tmp_path / "motion.gif"
    gif.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        animate(lk, traj, gif, **SMALL)
    # The mp4 -> gif fallback checks the file it would really write.
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    with pytest.raises(FileExistsError, match=r"motion\.gif"):
        animate(lk, traj, tmp_path / "motion.mp4", **SMALL)
    assert gif.read_bytes() == b"precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["motion.gif"]


def test_failed_trajectory_is_animated_up_to_the_failure(tmp_path, demo):
    lk, traj = demo
    bad = traj.q.at[-1].set(jnp.inf)  # as simulate leaves states after a failure
    traj = sorojax.Trajectory(
        t=traj.t,
        q=bad,
        qd=traj.qd,
        result=sorojax.RESULTS.max_steps_reached,
        num_steps=traj.num_steps,
        num_accepted_steps=traj.num_accepted_steps,
        num_rejected_steps=traj.num_rejected_steps,
    )
    with pytest.warns(UserWarning, match=r"non-finite states from t = 0\.1 s"):
        path = animate(lk, traj, tmp_path / "motion.gif", **SMALL)
    assert _gif_frames(path) == math.floor(0.075 * 30) + 1  # up to t = 0.075 s


def test_bad_arguments(tmp_path, demo):
    lk, traj = demo
    with pytest.raises(ValueError, match=r"'\.avi'.*\.mp4 or \.gif"):
        animate(lk, traj, tmp_path / "motion.avi", **SMALL)
    with pytest.raises(ValueError, match="fps = 0"):
        animate(lk, traj, tmp_path / "motion.gif", fps=0, **SMALL)
    assert not list(tmp_path.iterdir())


def test_time_series_of_states(demo):
    lk, traj = demo
    fig = plot_time_series(traj, quantities=("q", "qd"))
    assert isinstance(fig, matplotlib.figure.Figure)
    assert [len(a.get_lines()) for a in fig.axes] == [lk.n_dof, lk.n_dof]
    np.testing.assert_array_equal(fig.axes[1].get_lines()[2].get_ydata(), traj.qd[:, 2])
    with pytest.raises(ValueError, match="need the linkage"):
        plot_time_series(traj, quantities=("tip",))
    with pytest.raises(ValueError, match="'speed'"):
        plot_time_series(traj, lk, quantities=("speed",))


def test_time_series_of_tip_and_energy():
    # A 1-DoF rod keeps the energy and tip compiles small.
    lk = sorojax.scenes.cantilever(
        modes=(0, 1, 0, 0, 0, 0), order=0, gravity=(0.0, 0.0, -9.81)
    )
    traj = _trajectory(lk.n_dof)
    fig, axes = plt.subplots(2, 1)
    out = plot_time_series(traj, lk, quantities=("tip", "energy"), ax=axes)
    assert out is fig
    assert [len(a.get_lines()) for a in axes] == [3, 4]
    kin, grav, ela, total = (np.asarray(l.get_ydata()) for l in axes[1].get_lines())
    np.testing.assert_allclose(total, kin + grav + ela, rtol=1e-12)  # one sum
    q, qd = traj.q[3], traj.qd[3]
    np.testing.assert_allclose(kin[3], sorojax.kinetic_energy(lk, q, qd), rtol=1e-12)
    tip = np.asarray(sorojax.tip_pose(lk, q))[:3, 3]
    got = [l.get_ydata()[3] for l in axes[0].get_lines()]
    np.testing.assert_allclose(got, tip, rtol=1e-12, atol=1e-15)
