"""The package's architecture, checked statically from the import statements (no module is run).

Layers, each importing only the ones before it:
    core (the algorithm)  <-  sources, arms, sim  <-  LeRobot integration (robots/ included)  <-  scripts  <-  plugin
and no import cycle anywhere in lerobot_physvla, function-level (lazy) imports included.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "lerobot_physvla"
NAME = "lerobot_physvla"
RANK = {
    "core": 0,
    "sim": 1, "sources": 1, "arms": 1,
    "compat": 2, "flags": 2, "diagnostics": 2, "metrics": 2, "report": 2, "processor": 2, "envs": 2, "policies": 2, "replay": 2,
    "robots": 2,
    "scripts": 3,
    "plugin": 4,
}
ALGORITHM_MAY_IMPORT = {"numpy", "numba", "mujoco"}  # besides the standard library
NEVER_IN_ALGORITHM = {"lerobot", "torch", "robosuite", "libero", "gymnasium", "gymnasium_robotics"}


def module_name(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


MODULES = {module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def imports_of(source: str, module: str, is_package: bool) -> set[str]:
    """Every module named by an import statement anywhere in source (absolute names)."""
    out = set()
    package = module if is_package else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module
            out.add(mod)
            out.update(f"{mod}.{a.name}" for a in node.names if f"{mod}.{a.name}" in MODULES)
    return out


def internal_graph() -> dict[str, set[str]]:
    graph = {}
    for mod, path in MODULES.items():
        deps = imports_of(path.read_text(), mod, path.name == "__init__.py")
        graph[mod] = {d for d in deps if d in MODULES and d != mod and d != NAME}
    return graph


def top_level(name: str) -> str:
    return name.split(".")[1] if name.count(".") else ""


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in state and (c := visit(m)):
                return c
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state and (c := visit(n)):
            return c
    return None


def test_checker_sees_lazy_and_relative_imports():
    src = "import numpy\ndef f():\n    import torch\n    from ..sim import scenes\n    from . import corrector\n"
    found = imports_of(src, "lerobot_physvla.core.phase", False)
    assert {"numpy", "torch", "lerobot_physvla.sim", "lerobot_physvla.sim.scenes", "lerobot_physvla.core.corrector"} <= found
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


@pytest.mark.parametrize("mod", sorted(m for m in MODULES if m.startswith(f"{NAME}.core")))
def test_algorithm_imports_only_numpy_numba_mujoco(mod):
    path = MODULES[mod]
    for dep in imports_of(path.read_text(), mod, path.name == "__init__.py"):
        root = dep.split(".")[0]
        assert root not in NEVER_IN_ALGORITHM, f"{path.relative_to(PKG.parent)} imports {dep}"
        assert root in ALGORITHM_MAY_IMPORT or root in sys.stdlib_module_names or dep.startswith(f"{NAME}.core"), (
            f"{path.relative_to(PKG.parent)} imports {dep}: the algorithm may import only numpy, numba, "
            "mujoco, the standard library and lerobot_physvla.core")


def test_simulators_state_sources_and_arms_never_import_lerobot():
    for mod, path in MODULES.items():
        if top_level(mod) in ("sim", "sources", "arms"):
            deps = imports_of(path.read_text(), mod, path.name == "__init__.py")
            assert not any(d.split(".")[0] == "lerobot" for d in deps), f"{mod} imports lerobot"


def test_every_module_has_a_layer_and_imports_only_its_own_or_lower():
    graph = internal_graph()
    for mod, deps in graph.items():
        top = top_level(mod)
        if top in ("", "_moved"):  # the package root and the old-path aliases (imported by name at run time)
            continue
        assert top in RANK, f"{mod}: no layer for {top!r}; add it to RANK (README's Layout) first"
        for d in deps:
            assert top_level(d) in RANK and RANK[top_level(d)] <= RANK[top], (
                f"{mod} (layer {top}) imports {d} (layer {top_level(d)}): imports run core <- sim <- "
                "integration <- scripts <- plugin")


def test_no_import_cycle_in_the_package():
    cycle = find_cycle(internal_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


@pytest.mark.parametrize("page, limit", [("README.md", 12_000), ("docs/method.md", 35_000)])
def test_the_product_pages_stay_their_size_and_their_links_resolve(page, limit):
    """README.md (a product page: the full tables live in docs/results.md) and docs/method.md (the reference: the
    path to each decision lives in docs/decisions/) are held to their sizes, and every relative link in them
    resolves to a file of the repository."""
    path = ROOT / page
    assert path.stat().st_size <= limit, f"{page} is {path.stat().st_size} bytes (<= {limit}); move detail out"
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", path.read_text())
    relative = [x for x in links if "://" not in x]
    assert relative and not [x for x in relative if not (path.parent / x).exists()]
