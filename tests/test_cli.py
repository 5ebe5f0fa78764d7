"""The console script's demo: solves the default scene and writes a PNG."""

import matplotlib

matplotlib.use("Agg")

from sorojax._cli import main  # noqa: E402


def test_demo_runs_and_writes_png(tmp_path, capsys):
    out = tmp_path / "demo.png"
    code = main(["demo", "-o", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "ndof = 7" in text and "converged" in text and "tip position" in text
    assert out.stat().st_size > 10_000, "PNG too small to hold a rendered figure"


def test_compilation_cache_keeps_a_folder_already_set(tmp_path, monkeypatch):
    """A cache folder set before (here by the test configuration) is kept; "off" is off.

    Scripts call ``enable_compilation_cache`` unconditionally, so it must not move a
    cache the user (or JAX_COMPILATION_CACHE_DIR) chose.
    """
    import jax

    import sorojax as sj
    from sorojax._cache import default_cache_dir

    current = jax.config.jax_compilation_cache_dir
    assert current, "the test configuration sets a cache folder"
    assert str(sj.enable_compilation_cache(tmp_path / "other")) == current
    assert jax.config.jax_compilation_cache_dir == current
    monkeypatch.setenv("SOROJAX_CACHE_DIR", "off")
    assert sj.enable_compilation_cache() is None
    monkeypatch.setenv("SOROJAX_CACHE_DIR", str(tmp_path / "mine"))
    assert default_cache_dir() == tmp_path / "mine"
    monkeypatch.delenv("SOROJAX_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert default_cache_dir() == tmp_path / "sorojax" / "jax"
