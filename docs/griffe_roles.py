"""Griffe extension for the documentation site: Sphinx roles in docstrings as links.

sorojax's docstrings name other objects with Sphinx roles (``:func:`sorojax.simulate```,
``:class:`~sorojax.Trajectory```). mkdocstrings does not read them; this extension
rewrites each into an optional mkdocs-autorefs cross-reference: a link where the
target is documented on the site, plain code text where it is not (no warning).
Loaded by mkdocs.yml (``extensions`` of the python handler); not part of the package.
"""

import html
import re

import griffe

_ROLES = "func|class|meth|attr|data|mod|obj|exc|const"
_ROLE = re.compile(rf":(?:py:)?(?:{_ROLES}):`(~?)([^`<>]+?)`")


def _link(match: re.Match) -> str:
    short, target = match.group(1), match.group(2).strip()
    if target.endswith("()"):
        target = target[:-2]
    title = target.rsplit(".", 1)[-1] if short else target
    return (
        f'<autoref identifier="{html.escape(target)}" optional>'
        f"<code>{html.escape(title)}</code></autoref>"
    )


_LITERAL = re.compile(r"(?<=\S)::$", re.M)


def rewrite(text: str) -> str:
    """The docstring text with its Sphinx roles as optional cross-references.

    A paragraph that ends in ``::`` (reStructuredText's literal-block marker) ends in
    ``:``; the indented block after it is a code block in Markdown too.
    """
    return _LITERAL.sub(":", _ROLE.sub(_link, text))


class SphinxRoles(griffe.Extension):
    """Rewrite Sphinx roles in every docstring of the loaded package."""

    def on_package(self, *, pkg: griffe.Module, **kwargs) -> None:
        """Walk the package once it is loaded."""
        seen: set[int] = set()

        def visit(obj) -> None:
            if id(obj) in seen or obj.is_alias:
                return
            seen.add(id(obj))
            if obj.docstring is not None:
                obj.docstring.value = rewrite(obj.docstring.value)
            for member in obj.members.values():
                visit(member)

        visit(pkg)
