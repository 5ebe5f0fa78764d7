"""The documentation pages outside the user guide and the API reference: getting
started, coming from other tools, workflows, accuracy, performance, limitations,
gallery, development, and README.md. Every ```python block runs, as in
``test_docs.py`` (which holds the runner and the guide's pages)."""

import pytest
from test_docs import GUIDE, PAGES, _rel, run_page

OTHERS = [p for p in PAGES if p not in GUIDE]


@pytest.mark.parametrize("page", OTHERS, ids=_rel)
def test_page_snippets(page, tmp_path, monkeypatch):
    """Every ```python block of the page runs without error or warning."""
    run_page(page, tmp_path, monkeypatch)
