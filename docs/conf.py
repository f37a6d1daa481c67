"""Sphinx configuration of the suspension-toolkit documentation.

Build: ``sphinx-build -W --keep-going -b html docs docs/_build/html`` (warnings are errors).

The API reference covers every top-level package named in ``pyproject.toml``
(``[tool.setuptools] packages``): :func:`write_api_index` writes ``api/index.rst`` from that
list at each build, and autosummary walks each package recursively, so a module added, moved or
removed is picked up without editing the docs, and a module that cannot be imported is a
warning, hence a failed build.
"""

from __future__ import annotations

import re
import sys
import types
import tomllib
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))

project = "suspension-toolkit"
author = "the suspension-toolkit authors"
copyright = "the suspension-toolkit authors, MIT licence"
release = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "**/.ipynb_checkpoints"]
templates_path = ["_templates"]
html_theme = "furo"
html_title = "suspension-toolkit"
html_static_path: list[str] = []

myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "undoc-members": False, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"          # signatures carry the types; numpydoc sections the meaning
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()
# numba's dispatchers and dataclass fields are documented by their own docstrings
autodoc_mock_imports: list[str] = []


def packages() -> list[str]:
    """The project's top-level packages, from pyproject.toml (subpackages are walked)."""
    names = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    return sorted({name.split(".")[0] for name in names})


def write_api_index() -> None:
    """Write api/index.rst: one recursive autosummary over every top-level package."""
    lines = [
        "API reference",
        "=============",
        "",
        "Generated from the docstrings of every public module (the packages of",
        "``pyproject.toml``, walked recursively). Each page gives the module's model,",
        "equations, parameters and sources, then its functions and classes.",
        "",
        ".. autosummary::",
        "   :toctree: generated",
        "   :recursive:",
        "",
        *(f"   {name}" for name in packages()),
        "",
    ]
    text = "\n".join(lines)
    path = DOCS / "api" / "index.rst"
    path.parent.mkdir(exist_ok=True)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


write_api_index()

# A package's __main__ runs its command when imported: autosummary's walk of the packages
# gets an empty stand-in instead (the template leaves __main__ out of the lists).
for _name in packages():
    if (ROOT / _name / "__main__.py").exists():
        sys.modules[f"{_name}.__main__"] = types.ModuleType(f"{_name}.__main__")

# Docstrings are written as plain text with the paper's notation (|v|, |dz|, a*b), not as reST.
# Before numpydoc reads them, a '|' that is not a table border is escaped (an absolute value is
# not a substitution); a docstring that docutils still cannot parse (e.g. an aligned plain-text
# table) is shown verbatim as a literal block, so no docstring can break the build and none is
# dropped. Pages under docs/ are reST/Markdown proper and get no such help: their warnings fail
# the build.
_PIPE = re.compile(r"(?<!\\)\|")
_ROLE = re.compile(r":[\w.:+-]+:`([^`]*)`")
_DIRECTIVE = re.compile(r"^(\s*)\.\. ([\w:.-]+)::", re.MULTILINE)
_SYSTEM_MESSAGE_OK = ("Unknown interpreted text role", "Unknown directive type",
                      'No role entry for', 'No directive entry for', 'Unknown target name')


def _escape_pipes(line: str) -> str:
    stripped = line.strip()
    table_row = stripped.startswith("|") and stripped.endswith("|") and stripped.count("|") > 2
    if table_row or stripped.startswith(("| ", "+-", "+=")):   # a grid table or a line block
        return line
    return _PIPE.sub(r"\\|", line)


def _parse_errors(text: str) -> list[str]:
    """docutils' warnings and errors on ``text`` (unknown Sphinx roles and directives aside)."""
    from docutils import nodes
    from docutils.core import publish_doctree

    # Sphinx's roles and directives need a build: for this check a role becomes a literal and a
    # directive a comment (their own content is Sphinx's to check, with the page)
    text = _ROLE.sub(r"``\1``", _DIRECTIVE.sub(r"\1.. \2", text))
    messages: list[str] = []
    settings = {"report_level": 2, "halt_level": 5, "warning_stream": False}
    doctree = publish_doctree(text, settings_overrides=settings)
    found = [*doctree.findall(nodes.system_message), *doctree.transform_messages]
    for node in found:
        message = node.astext()
        if node["level"] >= 2 and not any(ok in message for ok in _SYSTEM_MESSAGE_OK):
            messages.append(message)
    return messages


_RAW: dict[str, list[str]] = {}
#: the docstrings shown verbatim in this build (reported at its end)
VERBATIM: list[str] = []


def escape_docstring(app, what, name, obj, options, lines):
    """autodoc-process-docstring hook, before numpydoc's: escape the pipes, keep the text."""
    _RAW[name] = list(lines)
    lines[:] = [_escape_pipes(line) for line in lines]


def verbatim_if_broken(app, what, name, obj, options, lines):
    """autodoc-process-docstring hook, after numpydoc's: a docstring docutils cannot parse is
    shown as it is written, its first line as the summary."""
    raw = _RAW.pop(name, None)
    if not raw or not _parse_errors("\n".join(lines)):
        return
    VERBATIM.append(name)
    first = raw[0].strip().replace("`", "'").replace("*", "\\*").replace("|", "\\|")
    lines[:] = [first, "", ".. code-block:: text", ""] + ["   " + line for line in raw[1:]] + [""]


def report_verbatim(app, exception):
    if VERBATIM:
        from sphinx.util import logging

        logging.getLogger(__name__).info(
            f"{len(set(VERBATIM))} docstring(s) are not valid reST and are shown verbatim: "
            + ", ".join(sorted(set(VERBATIM))))


def setup(app):
    app.connect("autodoc-process-docstring", escape_docstring, priority=100)
    app.connect("autodoc-process-docstring", verbatim_if_broken, priority=900)
    app.connect("build-finished", report_verbatim)
