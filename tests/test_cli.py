"""The console script's demo: solves the default scene and writes a PNG."""

import matplotlib

matplotlib.use("Agg")

from sorojax._cli import main  # noqa: E402


def test_demo_runs_and_writes_png(tmp_path, capsys):
    """The demo (compiled at LLVM -O0) and ``--optimised`` (XLA's default level)
    print the same equilibrium; each writes its PNG."""
    texts = []
    for flags in ([], ["--optimised"]):
        out = tmp_path / f"demo{len(flags)}.png"
        code = main(["demo", "-o", str(out), *flags])
        text = capsys.readouterr().out
        assert code == 0, text
        assert "ndof = 7" in text and "converged" in text and "tip position" in text
        assert out.stat().st_size > 10_000, "PNG too small to hold a rendered figure"
        texts.append(text)
    assert "LLVM -O0" in texts[0] and "default level" in texts[1]
    pose = [t[t.index("  q = ") : t.index("  time:")] for t in texts]
    assert pose[0] == pose[1], "the optimisation level changed the printed solution"


def test_demo_replaces_only_its_own_figure(tmp_path, capsys):
    """A file of the output's name that the demo did not write is refused before
    any computation (and kept byte for byte); ``--overwrite`` replaces it; the
    demo's own figure is marked and replaced when the demo runs again (README's
    first command can be run twice)."""
    import pytest

    from sorojax._cli import _written_by_demo

    out = tmp_path / "figure.png"
    out.write_bytes(b"a user's file")
    with pytest.raises(SystemExit, match="was not written by sorojax demo"):
        main(["demo", "-o", str(out)])
    assert out.read_bytes() == b"a user's file"
    assert not _written_by_demo(out)
    assert main(["demo", "-o", str(out), "--overwrite"]) == 0
    assert _written_by_demo(out) and out.stat().st_size > 10_000
    with open(out, "ab") as f:  # still the demo's figure (marked): replaced
        f.write(b"TRAILER")
    assert main(["demo", "-o", str(out)]) == 0, capsys.readouterr().out
    assert _written_by_demo(out) and not out.read_bytes().endswith(b"TRAILER")


def test_exported_demo_program_matches_the_code(tmp_path):
    """The demo's program exported ahead of time (``sorojax/data``) computes what
    the code as it is computes: the same result code and iterations, q and every
    pose to 1e-10 (a stale file -- a changed solver or scene -- fails here; rewrite
    it with ``write_demo_export``). A fresh export of the code round-trips too."""
    import jax
    import numpy as np

    from sorojax._cli import _demo_program, _exported_demo, write_demo_export
    from sorojax.scenes import demo_linkage

    live = jax.jit(_demo_program(demo_linkage()))()
    for path in (None, write_demo_export(tmp_path / "demo.jaxexport")):
        call = _exported_demo() if path is None else _exported_demo(path)
        assert call is not None, "the exported demo program cannot be loaded"
        got = jax.jit(call)()
        q, code, steps, _, stable, _, g = got
        assert int(code) == int(live[1]) == 0 and int(steps) == int(live[2])
        assert bool(stable) == bool(live[4])
        np.testing.assert_allclose(q, live[0], rtol=0, atol=1e-10)
        np.testing.assert_allclose(g, live[6], rtol=0, atol=1e-10)
    assert _exported_demo(tmp_path / "missing.jaxexport") is None


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
