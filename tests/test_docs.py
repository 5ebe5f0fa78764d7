"""The documentation: the site builds with ``mkdocs build --strict``, every ```python
block of docs/**/*.md and README.md runs, and the API reference covers every public
name.

Code blocks: the ```python blocks of one page run in order in one shared namespace, in
a temporary working directory, with matplotlib's Agg backend; nothing is pre-imported.
A block whose first line starts with ``# not run:`` (followed by the reason: a long
compile or solve) is shown on the site and left out of the default run; the slow tests
(``-m slow``) run those pages with every block. Under the suite's ``filterwarnings = error`` a snippet that
warns fails, as a user would want to know. A failure names the page, the block's number
on the page and the line in the page's file. Each block's time is printed (shown
with ``-s`` or ``-rP``).
"""

import ast
import importlib
import importlib.util
import os
import pathlib
import re
import subprocess
import sys
import time
import traceback

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.rglob("*.md")) + [ROOT / "README.md"]
GUIDE = [p for p in PAGES if p.parent.name in ("guide", "api")]
"""The user guide's and the API's pages: this file runs them; the others run in
``test_docs_pages.py``, so that the two halves share the test workers."""
SKIP_MARK = "# not run:"

_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})[ \t]*(?P<info>[^`\s]*)")


def python_blocks(text: str) -> list[tuple[int, str]]:
    """The ```python blocks of a Markdown text as (first code line number, code).

    Blocks indented inside admonitions or lists are dedented by their fence's indent.
    """
    blocks = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, info = m["indent"], m["fence"], m["info"].lower()
        close = re.compile(rf"^{re.escape(indent)}{fence[0]}{{{len(fence)},}}[ \t]*$")
        j = i + 1
        while j < len(lines) and not close.match(lines[j]):
            j += 1
        if info in ("python", "py"):
            body = [
                ln[len(indent) :] if ln.startswith(indent) else ln.lstrip()
                for ln in lines[i + 1 : j]
            ]
            blocks.append((i + 2, "\n".join(body) + "\n"))
        i = j + 1
    return blocks


def _rel(page: pathlib.Path) -> str:
    return page.relative_to(ROOT).as_posix()


@pytest.mark.parametrize("page", GUIDE, ids=_rel)
def test_page_snippets(page, tmp_path, monkeypatch):
    """Every ```python block of the page runs without error or warning."""
    run_page(page, tmp_path, monkeypatch)


LONG = [
    p
    for p in PAGES
    if any(c.lstrip().startswith(SKIP_MARK) for _, c in python_blocks(p.read_text()))
]
"""Pages with blocks left out of the default run."""


@pytest.mark.slow
@pytest.mark.parametrize("page", LONG, ids=_rel)
def test_page_snippets_with_long_blocks(page, tmp_path, monkeypatch):
    """The pages with ``# not run:`` blocks, every block run."""
    run_page(page, tmp_path, monkeypatch, everything=True)


def run_page(page, tmp_path, monkeypatch, everything=False):
    """Run a page's ```python blocks in order in one namespace (see the module).

    ``everything``: also the blocks marked ``# not run:``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    blocks = python_blocks(page.read_text(encoding="utf-8"))
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__main__"}
    try:
        for k, (line0, code) in enumerate(blocks, start=1):
            if code.lstrip().startswith(SKIP_MARK) and not everything:
                continue
            filename = f"{_rel(page)} [block {k}]"
            # line numbers in the compiled code are those of the page's file
            tree = ast.parse(code, filename=filename)
            ast.increment_lineno(tree, line0 - 1)
            start = time.perf_counter()
            try:
                exec(compile(tree, filename, "exec"), namespace)
            except Exception as e:
                tb = traceback.extract_tb(e.__traceback__)
                at = [f for f in tb if f.filename == filename]
                line = at[-1].lineno if at else line0
                pytest.fail(
                    f"{_rel(page)}: python block {k} (starting at line {line0}) failed "
                    f"at line {line}: {type(e).__name__}: {e}\n"
                    + "".join(traceback.format_exception(e)[-12:]),
                    pytrace=False,
                )
            # shown with -s, -rP or on failure: which blocks cost the time
            print(f"{filename} (line {line0}): {time.perf_counter() - start:.2f} s")
    finally:
        plt.close("all")


def test_python_blocks_parser():
    """Fences, indented fences, other languages and the skip marker are read right."""
    text = "\n".join(
        [
            "# T",
            "```python",
            "x = 1",
            "```",
            "```bash",
            "echo no",
            "```",
            '!!! note "n"',
            "    ```python",
            "    # not run: reason",
            "    y = 2",
            "    ```",
            "````python",
            "s = '```'",
            "````",
        ]
    )
    blocks = python_blocks(text)
    assert [b[0] for b in blocks] == [3, 10, 14]
    assert blocks[0][1] == "x = 1\n"
    assert blocks[1][1].startswith(SKIP_MARK)
    assert blocks[2][1] == "s = '```'\n"


def test_mkdocs_build_strict(tmp_path):
    """``mkdocs build --strict`` passes: every link, nav entry and API entry resolves."""
    if importlib.util.find_spec("mkdocs") is None:
        pytest.skip("mkdocs is not installed (pip install -e '.[docs]')")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    r = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-q"]
        + ["-f", str(ROOT / "mkdocs.yml"), "-d", str(tmp_path / "site")],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, f"mkdocs build --strict failed:\n{r.stdout}\n{r.stderr}"
    assert (tmp_path / "site" / "index.html").exists()


def _resolve(path: str):
    """The object a ``::: dotted.path`` entry names (module, or attribute of one)."""
    parts = path.split(".")
    for n in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:n]))
        except ImportError:
            continue
        for p in parts[n:]:
            obj = getattr(obj, p)
        return obj
    raise ImportError(path)


def test_api_reference_covers_all():
    """Every name of ``sorojax.__all__`` has a ``::: ...`` entry in docs/api."""
    import sorojax

    entries = []
    for page in sorted((DOCS / "api").glob("*.md")):
        entries += re.findall(
            r"^:::\s+([\w.]+)", page.read_text(encoding="utf-8"), re.M
        )
    documented = set()
    for e in entries:
        obj = _resolve(e)
        documented.add(id(obj))
        if type(obj).__name__ == "module":  # a module entry renders its public names
            documented.update(
                id(v)
                for k, v in vars(obj).items()
                if not k.startswith("_")
                and getattr(v, "__module__", "").startswith(obj.__name__)
            )
    missing = [n for n in sorojax.__all__ if id(getattr(sorojax, n)) not in documented]
    assert not missing, (
        f"public names without a '::: sorojax.NAME' entry in docs/api: {missing}"
    )
