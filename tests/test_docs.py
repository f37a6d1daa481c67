"""The documentation cannot go stale: its code runs, and what a user reads resolves.

- Every ```python block of README.md and docs/ runs (each file's blocks in one fresh process, in
  order, each block in a fresh namespace), and so does every shell block marked runnable (an HTML
  comment ``<!-- runnable -->`` on the line before its fence: cheap commands only), in a
  temporary folder, with the shipped examples' documented paths pointing into the repository.
- No development-log wording (commit hashes, dates of our work, "this stop", "the issue", "main
  at ...") and no citation of a file outside the repository (DESIGN.md, /work/...) in the README,
  the docs, the module, class and function docstrings of every package, the ``--help`` of
  every command and subcommand, or what ``mpm2d show`` prints for every scene.
- Every module of the packages imports (the API reference walks them; a module that cannot be
  imported would be missing from it).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import inspect
import io
import os
import pkgutil
import re
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
OWN_PAGES_SKIPPED = {"_build", "generated"}


def pages() -> list[Path]:
    """README.md and the docs' Markdown pages (generated API pages excluded)."""
    found = [ROOT / "README.md"]
    found += sorted(p for p in DOCS.rglob("*.md")
                    if not OWN_PAGES_SKIPPED.intersection(p.relative_to(DOCS).parts))
    return found


FENCE = re.compile(r"^(?P<marker>[ \t]*<!--\s*runnable\s*-->[ \t]*\n)?"
                   r"^(?P<fence>```|~~~)(?P<lang>[\w+-]*)[^\n]*\n(?P<body>.*?)^(?P=fence)[ \t]*$",
                   re.MULTILINE | re.DOTALL)


def blocks(path: Path) -> list[tuple[str, bool, str, int]]:
    """The fenced blocks of a page: (language, marked runnable, code, line)."""
    text = path.read_text(encoding="utf-8")
    return [(m["lang"], bool(m["marker"]), m["body"], text.count("\n", 0, m.start("fence")) + 1)
            for m in FENCE.finditer(text)]


def test_block_extraction_sees_fences_and_markers():
    page = "a\n\n<!-- runnable -->\n```bash\necho 1\n```\n\n```python\nx = 1\n```\n"
    p = Path(os.environ.get("TMPDIR", "/tmp")) / "_test_docs_extraction.md"
    p.write_text(page)
    try:
        assert blocks(p) == [("bash", True, "echo 1\n", 4), ("python", False, "x = 1\n", 8)]
    finally:
        p.unlink()


PY_PAGES = [p for p in pages() if any(lang == "python" for lang, _, _, _ in blocks(p))]
SH_PAGES = [p for p in pages() if any(run and lang in ("bash", "sh", "console")
                                      for lang, run, _, _ in blocks(p))]


EXAMPLES = re.compile(r"(?<![\w/.])((?:rheometer|mpm2d)/examples/)")


def _at_examples(code: str) -> str:
    """The block with the shipped examples' documented paths (``rheometer/examples/...``)
    pointing into the repository, so that it runs from any folder."""
    return EXAMPLES.sub(lambda m: f"{ROOT}/{m.group(1)}", code)


RUNNER = textwrap.dedent("""
    import sys, traceback
    for line, code in BLOCKS:
        try:
            exec(compile(code, f"{PAGE}:{line}", "exec"), {"__name__": "__docs__"})
        except BaseException:
            traceback.print_exc()
            sys.exit(f"{PAGE}: the python block at line {line} failed")
""")


def test_pages_have_python_blocks():
    assert ROOT / "README.md" in PY_PAGES and DOCS / "getting-started.md" in PY_PAGES


@pytest.mark.parametrize("page", PY_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_python_blocks_run(page, tmp_path):
    code = [(line, _at_examples(body)) for lang, _, body, line in blocks(page)
            if lang == "python"]
    script = f"PAGE = {str(page.relative_to(ROOT))!r}\nBLOCKS = {code!r}\n" + RUNNER
    env = {**os.environ, "MPLBACKEND": "Agg"}
    res = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-4000:]
    assert res.stdout.strip(), f"{page.name}: the python blocks printed nothing"


@pytest.mark.parametrize("page", SH_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_runnable_shell_blocks_run(page, tmp_path):
    for lang, runnable, body, line in blocks(page):
        if not (runnable and lang in ("bash", "sh", "console")):
            continue
        res = subprocess.run(["bash", "-euo", "pipefail", "-c", _at_examples(body)], cwd=tmp_path,
                             env={**os.environ, "MPLBACKEND": "Agg"}, capture_output=True,
                             text=True, timeout=600)
        assert res.returncode == 0, (f"{page.name}:{line}: exit {res.returncode}\n{body}\n"
                                     f"{res.stdout[-2000:]}{res.stderr[-3000:]}")


# ------------------------------------------------------------------------------------ wording
#: (pattern, what it is): development-log wording and citations a user cannot follow
FORBIDDEN = [
    (re.compile(r"\bthis stop\b", re.I), "development-log wording ('this stop')"),
    (re.compile(r"\bthe issue(?:'s)?\b", re.I), "development-log wording ('the issue')"),
    (re.compile(r"\bwithin the issue", re.I), "development-log wording ('within the issue')"),
    (re.compile(r"\bmain at\b", re.I), "development-log wording ('main at')"),
    (re.compile(r"\b(?:19|20)\d\d-[01]\d-[0-3]\d\b"), "a date"),
    (re.compile(r"(?<![\w/.-])(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}(?![\w-])"),
     "a commit hash"),
    (re.compile(r"DESIGN\.md"), "a file outside the repository (DESIGN.md)"),
    (re.compile(r"/work/|/shared/|/tmp/[\w.-]+/"), "a path outside the repository"),
]


#: repositories other than ours: a commit hash on a line naming one cites that repository
EXTERNAL_REPOSITORIES = ("aaronbaumgarten/mpm_3d",)


def wording_hits(text: str, where: str) -> list[str]:
    hits = []
    for n, line in enumerate(text.splitlines(), 1):
        for pattern, what in FORBIDDEN:
            if what == "a commit hash" and any(r in line for r in EXTERNAL_REPOSITORIES):
                continue
            m = pattern.search(line)
            if m:
                hits.append(f"{where}:{n}: {what}: {m.group(0)!r} in {line.strip()[:100]!r}")
    return hits


def test_wording_patterns_catch_and_pass():
    bad = ["measured before this stop's engine changes", "main at d840772",
           "within the issue's 5 minutes", "until 2026-11-29", "see DESIGN.md section 5",
           "from /work/shared/fixtures/a.csv", "the issue's example"]
    good = ["phi = 0.52, gdot_DST = 0.46 1/s", "Hermes et al., J. Rheol. 60, 905 (2016)",
            "the file's SHA-256", "a deadbeef-free string", "cafe", "1e-10 to 2.5e-3",
            "colour #1f77b4 is matplotlib's", "an issue of wall slip",
            "the author's code (aaronbaumgarten/mpm_3d, commit 9aa6448)"]
    assert all(wording_hits(t, "x") for t in bad), [t for t in bad if not wording_hits(t, "x")]
    assert not [h for t in good for h in wording_hits(t, "x")]


def packages() -> list[str]:
    names = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    return sorted({name.split(".")[0] for name in names})


def modules() -> list[str]:
    found = []
    for pkg in packages():
        found.append(pkg)
        path = [str(ROOT / pkg)]
        for info in pkgutil.walk_packages(path, prefix=f"{pkg}."):
            if not info.name.rsplit(".", 1)[-1].startswith("_"):
                found.append(info.name)
    return found


def test_every_module_imports():
    failed = []
    for name in modules():
        try:
            importlib.import_module(name)
        except Exception as exc:   # the API reference would miss it: say which and why
            failed.append(f"{name}: {type(exc).__name__}: {exc}")
    assert not failed, "\n".join(failed)


def docstrings() -> list[tuple[str, str]]:
    """(qualified name, docstring) of every module and of every class, function and method
    defined in it."""
    found = []
    for name in modules():
        mod = importlib.import_module(name)
        found.append((name, inspect.getdoc(mod) or ""))
        for attr, obj in vars(mod).items():
            if getattr(obj, "__module__", None) != name:
                continue
            if inspect.isclass(obj) or callable(obj):
                found.append((f"{name}.{attr}", inspect.getdoc(obj) or ""))
            if inspect.isclass(obj):
                for meth, member in vars(obj).items():
                    doc = inspect.getdoc(member) if callable(member) else None
                    if doc:
                        found.append((f"{name}.{attr}.{meth}", doc))
    return found


class _Parsed(Exception):
    """Raised by the patched parse_known_args: carries the command's root parser."""


def _walk(parser: argparse.ArgumentParser, name: str) -> list[tuple[str, str]]:
    texts = [(name, parser.format_help())]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, subparser in action.choices.items():
                texts += _walk(subparser, f"{name} {sub}")
    return texts


def help_texts() -> list[tuple[str, str]]:
    """The --help of every command and subcommand: each command's main() is stopped at its
    first parse, and its parser tree is walked (every subcommand, however its help is shown)."""
    commands = {"rheometer": "rheometer.cli", "shear1d": "shear1d.cli", "mpm2d": "mpm2d.cli",
                "python -m validation": "validation.__main__"}
    texts = []
    original = argparse.ArgumentParser.parse_known_args

    def stop(self, *args, **kwargs):
        raise _Parsed(self)

    for command, module in commands.items():
        main = importlib.import_module(module).main
        argparse.ArgumentParser.parse_known_args = stop
        try:
            with contextlib.redirect_stdout(io.StringIO()), \
                    contextlib.redirect_stderr(io.StringIO()):
                main(["--help"])
        except _Parsed as parsed:
            texts += _walk(parsed.args[0], command)
        finally:
            argparse.ArgumentParser.parse_known_args = original
    return texts


def scene_texts() -> list[tuple[str, str]]:
    """What ``mpm2d show SCENE`` prints for every built-in scene (docstring and parameters)."""
    from mpm2d.cli import main
    from mpm2d.scenes import SCENES

    texts = []
    for scene in SCENES:
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert main(["show", scene]) == 0
        texts.append((f"mpm2d show {scene}", out.getvalue()))
    return texts


@pytest.fixture(scope="module")
def user_texts():
    texts = [(str(p.relative_to(ROOT)), p.read_text(encoding="utf-8")) for p in pages()]
    texts += [(f"docstring of {name}", doc) for name, doc in docstrings()]
    texts += [(f"{cmd} --help", text) for cmd, text in help_texts()]
    return texts + scene_texts()


def test_help_texts_are_collected(user_texts):
    names = {where for where, _ in user_texts}
    for needed in ("rheometer flow-curve --help", "shear1d annular --help", "mpm2d run --help",
                   "python -m validation report --help", "mpm2d show intruder"):
        assert needed in names


def test_no_development_log_wording_or_outside_citations(user_texts):
    hits = [h for where, text in user_texts for h in wording_hits(text, where)]
    assert not hits, f"{len(hits)} hit(s):\n" + "\n".join(hits)


def test_docs_extra_and_build_command_are_declared():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extra = " ".join(project["optional-dependencies"]["docs"])
    for need in ("sphinx", "myst-parser", "numpydoc", "furo"):
        assert need in extra
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "sphinx-build -W" in readme and 'pip install -e ".[docs]"' in readme
    ci = (ROOT / ".ci" / "run").read_text()
    assert "sphinx-build -W" in ci and ".[test,docs]" in ci
    assert len(readme.splitlines()) <= 200


def test_readme_figures_exist_and_are_small():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    images = re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", readme)
    assert len(images) >= 4
    for image in images:
        path = ROOT / image
        assert path.is_file(), image
        assert path.stat().st_size < 150_000, f"{image}: {path.stat().st_size} bytes"


def test_docs_conf_renders_plain_text_docstrings():
    """conf.py's docstring helpers: |x| is an absolute value, not a reST substitution; grid
    tables and line blocks are kept; a docstring docutils cannot parse is detected (it is then
    shown verbatim rather than breaking the build)."""
    pytest.importorskip("docutils", reason="docutils comes with the docs extra (Sphinx)")
    before = set(sys.modules)
    sys.path.insert(0, str(DOCS))
    try:
        conf = importlib.import_module("conf")
    finally:
        sys.path.remove(str(DOCS))
        for name in set(sys.modules) - before:    # conf's stand-ins for the __main__ modules
            if name == "conf" or name.endswith(".__main__"):
                del sys.modules[name]
    assert conf._escape_pipes("max |v - v_N|/u_i") == r"max \|v - v_N\|/u_i"
    for kept in ("| a | b |", "+---+---+", "| a line block"):
        assert conf._escape_pipes(kept) == kept
    assert conf._parse_errors("a |v| b") and not conf._parse_errors(conf._escape_pipes("a |v| b"))
    assert not conf._parse_errors("see :func:`rheology.steady.gdot_dst`\n\n.. math::\n\n   x\n")
    assert conf._parse_errors("a\n    b\n  c")                 # unexpected indentation
    assert set(conf.packages()) == set(packages())
