"""The import graph of the package: layers, and no module importing itself through others.

Every ``import`` and ``from ... import`` of every module of the packages listed in
pyproject.toml is read from the source (those inside functions included), resolved to the
module it names (``from pkg import sub`` to ``pkg.sub`` when ``sub`` is a module, else to
``pkg``), and the circles are the strongly connected components of that graph (Tarjan).

Layers: ``runkit`` (no physics) imports no package of ours; ``rheology`` imports only itself
and ``runkit``; a tier (``rheometer``, ``shear1d``, ``mpm2d``) only itself, ``rheology`` and
``runkit``; ``validation`` anything.
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TIERS = ("rheometer", "shear1d", "mpm2d")
#: what each top-level package may import of ours (besides itself)
ALLOWED = {"runkit": (), "rheology": ("runkit",), "validation": None,
           **{t: ("rheology", "runkit") for t in TIERS}}

def modules() -> dict[str, tuple[Path, bool]]:
    """Module name -> (file, is a package) for every package in pyproject.toml."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    tops = sorted({p.split(".")[0] for p in cfg["tool"]["setuptools"]["packages"]})
    out = {}
    for top in tops:
        for f in sorted((ROOT / top).rglob("*.py")):
            parts = list(f.relative_to(ROOT).with_suffix("").parts)
            package = parts[-1] == "__init__"
            out[".".join(parts[:-1] if package else parts)] = (f, package)
    return out


def _base(name: str, package: bool, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module
    parts = name.split(".") if package else name.split(".")[:-1]
    parts = parts[:len(parts) - (node.level - 1)]
    return ".".join(parts + ([node.module] if node.module else []))


def graph(mods=None) -> dict[str, dict[str, list[tuple[int, bool]]]]:
    """module -> {imported module of ours -> [(line, inside a function)]}."""
    mods = mods if mods is not None else modules()
    out = {}
    for name, (path, package) in mods.items():
        tree = ast.parse(path.read_text(), str(path))
        inner = {id(n) for fn in ast.walk(tree)
                 if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef))
                 for n in ast.walk(fn) if isinstance(n, (ast.Import, ast.ImportFrom))}
        edges: dict[str, list] = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = _base(name, package, node)
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base
                           for a in node.names]
            else:
                continue
            for t in targets:
                if t in mods and t != name:
                    edges.setdefault(t, []).append((node.lineno, id(node) in inner))
        out[name] = edges
    return out


def circles(g) -> list[frozenset]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]
    for root in g:
        if root in index:
            continue
        work = [(root, iter(g[root]))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(g[w])))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = set()
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.add(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    found.append(frozenset(comp))
    return found


def _describe(g, comp) -> str:
    return "; ".join(f"{m}:{ln}{' (in a function)' if inner else ''} -> {t}"
                     for m in sorted(comp) for t, where in sorted(g[m].items()) if t in comp
                     for ln, inner in where)


G = graph()


def test_the_walk_sees_the_package():
    """The walk finds the modules and their imports (a guard against an empty walk)."""
    assert len(G) >= 90
    assert "rheology.materials" in G["rheology.steady"]
    inner = sum(inner for e in G.values() for w in e.values() for _, inner in w)
    assert inner > 0                     # imports inside functions are read too


def test_circles_are_found():
    """The circle finder on a small graph: a 3-cycle, a 2-cycle, a chain and a self-loop."""
    g = {"a": {"b": 0}, "b": {"c": 0}, "c": {"a": 0}, "d": {"e": 0}, "e": {"d": 0, "f": 0},
         "f": {}, "s": {"s": 0}}
    assert set(circles(g)) == {frozenset("abc"), frozenset("de")}


def test_layers():
    """runkit imports none of our packages; rheology only runkit; a tier no other tier."""
    bad = []
    for m, edges in G.items():
        top = m.split(".")[0]
        allowed = ALLOWED.get(top)
        if allowed is None:
            continue
        for t, where in edges.items():
            tt = t.split(".")[0]
            if tt != top and tt not in allowed:
                bad.append(f"{m}:{where[0][0]} imports {t}")
    assert not bad, "; ".join(bad)


def test_no_circles():
    """No two modules import each other, directly or through others."""
    found = circles(G)
    assert not found, " | ".join(_describe(G, c) for c in found)


def private_imports(mods=None) -> list[str]:
    """``from X import _name`` of one module of ours from another."""
    mods = mods if mods is not None else modules()
    out = []
    for name, (path, _) in mods.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                out += [f"{name}:{node.lineno} {a.name}" for a in node.names
                        if a.name.startswith("_") and not a.name.startswith("__")]
    return out


def test_no_private_name_imported():
    """No module imports a private name (``_x``) of another."""
    assert not private_imports()


def test_matplotlib_backend_is_set_once():
    """Only runkit.plotting calls ``matplotlib.use`` (the Agg backend, set once); every module
    that draws imports ``plt`` from it. validation.cases_intruder (its owner's branch) is the
    one module still to move."""
    setters = []
    for name, (path, _) in modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr == "use" and isinstance(node.func.value, ast.Name)
                    and node.func.value.id == "matplotlib"):
                setters.append(name)
    assert sorted(set(setters) - {"validation.cases_intruder"}) == ["runkit.plotting"], setters


def test_module_docstrings_state_the_model_in_at_most_60_lines():
    """A module docstring states model, equations, parameters, sources and choices; the
    measurements behind the choices are in docs/measurements.md. rheology.local_update and
    mpm2d.scenes.intruder are their owners' to cut."""
    long = {}
    for name, (path, _) in modules().items():
        doc = ast.get_docstring(ast.parse(path.read_text()), clean=False)
        if doc and doc.count("\n") + 1 > 60:
            long[name] = doc.count("\n") + 1
    assert set(long) <= {"rheology.local_update", "mpm2d.scenes.intruder"}, long
