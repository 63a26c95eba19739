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
def test_the_product_pages_stay_their_size(page, limit):
    """README.md (a product page: the full tables live in docs/results.md) and docs/method.md (the reference: the
    path to each decision lives in docs/decisions/) are held to their sizes."""
    path = ROOT / page
    assert path.stat().st_size <= limit, f"{page} is {path.stat().st_size} bytes (<= {limit}); move detail out"


FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
INLINE_LINK = re.compile(r"\]\(\s*<?([^()<>\s]+)>?(?:\s+(?:\"[^\"]*\"|'[^']*'))?\s*\)")
REFERENCE_LINK = re.compile(r"^ {0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s|$)")
HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)(?:\s+#+)?\s*$")
HTML_ANCHOR = re.compile(r"<a\s+(?:name|id)=[\"']([^\"']+)[\"']", re.I)


def markdown_files() -> list[Path]:
    """Every markdown file of the repository: tracked, and new ones git does not ignore (git ls-files)."""
    import subprocess

    try:
        out = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "*.md"], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout.split("\n")
    except (OSError, subprocess.CalledProcessError):  # not a git checkout: every markdown file outside hidden folders
        return sorted(p for p in ROOT.rglob("*.md")
                      if not any(s.startswith(".") or s == "outputs" for s in p.relative_to(ROOT).parts))
    return sorted({ROOT / f for f in out if f and (ROOT / f).is_file()})


def prose_lines(text: str) -> list[str]:
    """The file's lines with fenced code blocks blanked (line numbers kept)."""
    out, fence = [], None
    for line in text.splitlines():
        m = FENCE.match(line)
        if fence is None and m:
            fence = m.group(1)[0] * len(m.group(1))
        elif fence is not None and m and m.group(1).startswith(fence) and not line.strip()[len(m.group(1)):]:
            fence = None
        elif fence is None:
            out.append(line)
            continue
        out.append("")
    return out


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: its text (links and tags dropped) lowercased, every character but letters,
    digits, '_', '-' and spaces removed, spaces turned into '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = re.sub(r"<[^>]+>", "", text)
    return re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")


def anchors(path: Path, _cache: dict = {}) -> set[str]:  # noqa: B006 - a cache for the one test run
    if path not in _cache:
        seen: dict[str, int] = {}
        found = set()
        for line in prose_lines(path.read_text()):
            found.update(HTML_ANCHOR.findall(line))
            if m := HEADING.match(line):
                s = slug(m.group(2))
                found.add(f"{s}-{seen[s]}" if s in seen else s)
                seen[s] = seen.get(s, 0) + 1
        _cache[path] = found
    return _cache[path]


def broken_links(path: Path) -> list[str]:
    """Each relative link (`file`, `file#anchor`, `#anchor`) in a markdown file that does not resolve; http(s) and
    other schemes, inline code and fenced code blocks are skipped."""
    from urllib.parse import unquote

    bad = []
    for n, line in enumerate(prose_lines(path.read_text()), 1):
        line = re.sub(r"(`+).*?\1", "", line)  # inline code
        for target in INLINE_LINK.findall(line) + REFERENCE_LINK.findall(line):
            if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target):
                continue
            file, _, anchor = target.partition("#")
            dest = (path.parent / unquote(file)).resolve() if file else path
            where = f"{path.relative_to(ROOT)}:{n}: ({target})"
            if not dest.exists():
                bad.append(f"{where} no such file")
            elif anchor and dest.suffix == ".md" and unquote(anchor) not in anchors(dest):
                bad.append(f"{where} no heading with that anchor in {dest.relative_to(ROOT)}")
    return bad


def test_anchor_slugs_are_githubs():
    assert slug("Presets -- `core/config.py` `PRESETS`") == "presets----coreconfigpy-presets"
    assert slug("Pose error -- `pose_error_m`, `sources/perception.py`") == "pose-error----pose_error_m-sourcesperceptionpy"
    assert slug("Blender (eq. 2) and [per-phase](x.md) authority") == "blender-eq-2-and-per-phase-authority"
    lines = prose_lines("# A\n```\n# not a heading [x](nowhere.md)\n```\n## A\n")
    assert lines == ["# A", "", "", "", "## A"]


def test_every_relative_link_and_anchor_in_the_markdown_resolves():
    """Every relative link in every markdown file of the repository (README.md, docs/, docs/decisions/, eval/, the
    study READMEs, backbones/, configs/) names a file that exists and, with '#anchor', a heading of that file (or of
    the same file): GitHub's slugs, the n-th repeat of a heading taking '-n'."""
    files = markdown_files()
    assert {"README.md", "docs/method.md", "docs/lerobot_eval.md"} <= {str(p.relative_to(ROOT)) for p in files}
    bad = [b for p in files for b in broken_links(p)]
    assert not bad, "broken links:\n" + "\n".join(bad)
