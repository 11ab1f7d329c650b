"""The package's architecture, checked on the source (ast, no imports executed).

Imports point one way only (cli -> plots -> the batch commands scan, study (sweeps),
advise, bench, report, siblings that never import each other -> the rows layer (point
task, row schema) and the batch layer (launchers, lock, progress, parts; no physics)
-> extraction/simulation -> surfaces/signals -> core; ``errors``, ``io``,
``constants``, ``checks``, ``ranges``, ``interrupt`` usable from anywhere), there is no import cycle, and no
module -- in the package, the tests or the scripts -- imports another module's
``_private`` name or patches one.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "vetica_cli"
# top to bottom; a component may import its own modules, any component of a lower layer and the foundation
LAYERS = (
    {"__main__"},
    {"cli", "api"},
    {"plots"},
    {"scan", "study", "advise", "bench", "report", "curves", "export", "testing"},
    {"rows", "batch"},
    {"extraction", "simulation"},
    {"surfaces", "signals"},
    {"core"},
)
FOUNDATION = {"__init__", "errors", "io", "constants", "checks", "ranges", "interrupt"}


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def component(module: str) -> str:
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def layer(comp: str) -> int:
    return next(i for i, names in enumerate(LAYERS) if comp in names)


def is_module(name: str) -> bool:
    path = ROOT.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def imports(path: Path):
    """``(line, imported module, imported name or None)`` for every import of a vetica_cli
    module in ``path``, at any depth (function-level imports included)."""
    mod = module_name(path) if PKG in path.parents else None
    package = (mod if path.name == "__init__.py" else mod.rpartition(".")[0]) if mod else None
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name, None) for a in node.names if a.name.split(".")[0] == "vetica_cli"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            elif node.module and node.module.split(".")[0] == "vetica_cli":
                target = node.module
            else:
                continue
            for a in node.names:
                sub = f"{target}.{a.name}"
                out.append((node.lineno, sub, None) if is_module(sub) else (node.lineno, target, a.name))
    return out


PACKAGE_FILES = sorted(PKG.rglob("*.py"))
OTHER_FILES = sorted((ROOT / "tests").glob("*.py")) + sorted((ROOT / "scripts").glob("*.py"))


def test_batch_layer_knows_no_physics():
    """The batch layer imports only the foundation (no simulation, extraction, surfaces, rows)."""
    for path in sorted((PKG / "batch").glob("*.py")):
        for line, target, _ in imports(path):
            assert component(target) in FOUNDATION | {"batch"}, f"{path.name}:{line}: batch imports {target}"


def test_every_package_module_belongs_to_a_layer():
    comps = {component(module_name(f)) for f in PACKAGE_FILES}
    known = set().union(*LAYERS) | FOUNDATION
    assert comps <= known, comps - known


@pytest.mark.parametrize("path", PACKAGE_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_point_down_the_layers(path):
    src = component(module_name(path))
    for line, target, _ in imports(path):
        dst = component(target)
        if dst == src or dst in FOUNDATION:
            continue
        assert src not in FOUNDATION, f"{path.name}:{line}: foundation module imports {target}"
        assert layer(dst) > layer(src), f"{path.relative_to(ROOT)}:{line}: {src} may not import {target}"


def test_no_import_cycle():
    graph = {module_name(f): {t for _, t, _ in imports(f) if t != module_name(f)} for f in PACKAGE_FILES}
    state: dict[str, int] = {}

    def visit(node, stack):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(nxt) :] + [nxt]))
            if nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])


def _private(name: str | None) -> bool:
    return bool(name) and name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


@pytest.mark.parametrize("path", PACKAGE_FILES + OTHER_FILES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_private_name_crosses_a_module_boundary(path):
    """``from m import _x``, ``m._x`` on an imported vetica_cli module, and
    ``setattr(m, "_x", ...)`` (monkeypatching a private name) are all refused."""
    own = module_name(path) if PKG in path.parents else None
    bad = [f"{line}: from {target} import {name}" for line, target, name in imports(path)
           if _private(name) and target != own]  # fmt: skip
    tree = ast.parse(path.read_text())
    modules = set()  # names bound to imported vetica_cli modules
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if not (node.module or "").startswith("vetica_cli"):
                continue
            modules |= {a.asname or a.name for a in node.names if is_module(f"{node.module}.{a.name}")}
        elif isinstance(node, ast.Import):
            modules |= {a.asname or a.name.split(".")[0] for a in node.names if a.name.startswith("vetica_cli")}
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr) and getattr(node.value, "id", None) in modules:
            bad.append(f"{node.lineno}: {node.value.id}.{node.attr}")
        if isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) == "setattr":
            args = node.args
            if len(args) >= 2 and isinstance(args[1], ast.Constant) and _private(str(args[1].value)):
                bad.append(f"{node.lineno}: setattr(..., {args[1].value!r}) patches a private name")
    assert not bad, f"{path.relative_to(ROOT)}: " + "; ".join(bad)
