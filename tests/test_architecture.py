"""The package's shape (issue 33): no import cycles among its modules (imports inside
functions included), the parameter layer on the ground floor, and no function over 150
lines or 12 parameters outside the independent test plant and the compiled step loops
(EXEMPT says why)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "turntable_env"
MAX_LINES = 150
MAX_PARAMETERS = 12
EXEMPT = {
    "turntable_env/testing/independent_plant.py",  # written apart, on purpose
    "turntable_env/testing/second_plant.py",  # written apart, on purpose (issue 31)
    # The compiled step loops stay whole: split into @njit phases that take (model, state,
    # scratch) NamedTuples (commit 469253a), the reduced model ran 6x and the 3-D model 2.8x
    # slower (`python experiments/bench_compare.py 469253a`); inline="always" won back part
    # of it, not all (numba increments and decrements every array of a tuple at each call).
    "turntable_env/reduced_kernel.py",
    "turntable_env/integrator.py",
    "turntable_env/friction/gms2d.py",
}


def _modules() -> dict[str, Path]:
    out = {}
    for p in sorted(PACKAGE.rglob("*.py")):
        parts = p.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = p
    return out


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package's modules ``name`` imports anywhere in its file: ``from X import y``
    counts as X.y where that is a module, else as X."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name in modules}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for a in node.names:
                sub = f"{target}.{a.name}"
                if sub in modules:
                    out.add(sub)
                elif target in modules:
                    out.add(target)
    out.discard(name)
    return out


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
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
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {m: _imports(m, p, modules) for m, p in modules.items()}


def test_no_import_cycle_among_the_package_modules():
    assert _cycles(_graph()) == []


def test_the_cycle_finder_finds_a_cycle():
    """The check above can fail: a two-module cycle and a self-contained chain."""
    assert _cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_the_parameter_layer_imports_nothing_above_it():
    """params sits on the ground floor: nothing it imports, directly or through others,
    reaches the plant, the simulation, the envs or the calibration."""
    graph = _graph()
    seen, todo = set(), ["turntable_env.params"]
    while todo:
        m = todo.pop()
        for w in graph[m] - seen:
            seen.add(w)
            todo.append(w)
    above = ("turntable_env.plant", "turntable_env.envs", "turntable_env.calibration",
             "turntable_env.simulation", "turntable_env.report", "turntable_env.cli")  # fmt: skip
    assert not [m for m in seen if m.startswith(above)]


def _functions():
    for p in sorted(PACKAGE.rglob("*.py")):
        rel = str(p.relative_to(ROOT))
        if rel in EXEMPT:
            continue
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                a = node.args
                n = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs)
                n += (a.vararg is not None) + (a.kwarg is not None)
                if a.args and a.args[0].arg in ("self", "cls"):
                    n -= 1
                yield rel, node, node.end_lineno - node.lineno + 1, n


@pytest.mark.parametrize("limit", ["lines", "parameters"])
def test_no_function_is_a_wall(limit):
    bad = [
        f"{rel}:{node.lineno} {node.name} ({lines} lines, {n} parameters)"
        for rel, node, lines, n in _functions()
        if (lines > MAX_LINES if limit == "lines" else n > MAX_PARAMETERS)
    ]
    assert bad == []
