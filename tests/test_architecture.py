"""The layout's rules, read from the code's own imports (every ``import``, top-level or inside a
function): the packages of ``components`` depend one way, in the order docs/architecture.md
gives; the orchestrator knows nothing of the domain; the plant knows neither; no module imports
itself back through a circle."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TOP = ("fmus", "orchestrator", "components")
# components' packages, left to right: a package imports only from packages to its left
LAYERS = ("errors", "progress", "model", "logs", "estimation", "diagnosis", "control", "simulation", "procedures",
          "navigation", "campaign", "cli")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    out = {}
    for top in TOP:
        for p in (ROOT / top).rglob("*.py"):
            out[_module_name(p)] = p
    return out


MODULES = _modules()


def _resolve(name: str) -> str | None:
    """The project module an import names (a name imported from a package may be a module)."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _imports(mod: str) -> set[str]:
    path = MODULES[mod]
    tree = ast.parse(path.read_text(), str(path))
    pkg = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            names = [f"{base}.{a.name}" for a in node.names] + [base]
        else:
            continue
        for n in names:
            r = _resolve(n)
            if r and r != mod and r.split(".")[0] in TOP:
                out.add(r)
    # importing a package runs its __init__: a package is not a dependency of its own modules
    return {r for r in out if not mod.startswith(r + ".")}


GRAPH = {m: _imports(m) for m in MODULES}


def _layer(mod: str) -> int | None:
    parts = mod.split(".")
    if parts[0] != "components" or len(parts) < 2:
        return None
    return LAYERS.index(parts[1]) if parts[1] in LAYERS else None


def test_every_components_module_lives_in_a_named_package():
    loose = [m for m in MODULES if m.startswith("components.") and _layer(m) is None]
    assert not loose, f"modules outside the layer packages {LAYERS}: {loose}"


def test_components_packages_depend_one_way():
    wrong = [(m, d) for m, deps in GRAPH.items() for d in deps
             if _layer(m) is not None and _layer(d) is not None and _layer(d) > _layer(m)]
    assert not wrong, "imports against the layer order (module -> what it imports): " + \
        ", ".join(f"{m} -> {d}" for m, d in wrong)


@pytest.mark.parametrize("low, high", [("orchestrator", "components"), ("fmus", "components"),
                                       ("fmus", "orchestrator")])
def test_lower_parts_do_not_know_the_higher(low, high):
    wrong = [(m, d) for m, deps in GRAPH.items() if m.split(".")[0] == low
             for d in deps if d.split(".")[0] == high]
    assert not wrong, f"{low} imports {high}: {wrong}"


def test_no_import_circles():
    # Tarjan's strongly connected components: any component of more than one module is a circle
    index, low, stack, on, circles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(GRAPH[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                circles.append(sorted(comp))

    for v in sorted(GRAPH):
        if v not in index:
            visit(v)
    assert not circles, f"import circles: {circles}"


def test_the_checker_sees_a_circle_and_a_wrong_way_import():
    """The graph above is not empty by accident: known edges are there."""
    assert "components.model.effects" in GRAPH["components.estimation.lsq"]
    assert "components.errors" in GRAPH["components.cli"]
    assert _layer("components.cli.demo") > _layer("components.model.effects")


def test_the_orchestrator_finds_the_plant_roles_without_importing_components():
    """The roles and ``builtin:`` FMUs reach the domain-free orchestrator through the installed
    entry point, in a fresh interpreter that never imports ``components`` itself."""
    import subprocess
    import sys

    code = ("import sys\nfrom orchestrator.roles import get_role\nfrom orchestrator.fmu_resolver import resolve_fmu\n"
            "from pathlib import Path\nr = get_role('imu')\np = resolve_fmu('builtin:imu', Path('.'))\n"
            "print(r.name, p.suffix)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["imu", ".fmu"]
