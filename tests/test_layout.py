"""The layout imports one way: no cycle among the Rust modules (their `use crate::`, `super::` and inline `crate::`
paths) nor among the Python modules of lamina (every import, those inside functions included).

Rust: at every level of the module tree the sibling modules (each folder's children, its own mod.rs left out: a
parent may declare and re-export its children, which use its items) must depend on each other without a cycle, and
so must the crate's top-level modules. Unit tests (after a file's `#[cfg(test)]`) may reach anywhere."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
PACKAGE = ROOT / "python" / "lamina"


def _module(path: Path) -> tuple:
    """The module path of a Rust source file: src/models/common/options.rs -> ("models", "common", "options")."""
    parts = path.relative_to(SRC).with_suffix("").parts
    if parts[-1] in ("mod", "lib"):
        parts = parts[:-1]
    return tuple(parts)


def _split_top(text: str) -> list:
    """`text` split at the commas outside braces."""
    out, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        depth += ch == "{"
        depth -= ch == "}"
        if ch == "," and depth == 0:
            out.append(text[start:i])
            start = i + 1
    return [p.strip() for p in out + [text[start:]] if p.strip()]


def _expand(tree: str) -> list:
    """A use tree as its paths: "a::{b, c::{d, e}}" -> ["a::b", "a::c::d", "a::c::e"]."""
    tree = re.sub(r"\s+as\s+\w+", "", tree.strip())
    if "{" not in tree:
        return [tree]
    head, rest = tree.split("{", 1)
    inner = rest[: rest.rindex("}")]
    return [head + path for part in _split_top(inner) for path in _expand(part)]


def _paths(code: str) -> list:
    """Every module path a Rust file names: its use trees, expanded, and inline crate::/super:: paths (comments and
    string literals left out)."""
    code = re.sub(r'"(?:[^"\\]|\\[\s\S])*"', '""', code)
    code = re.sub(r"//[^\n]*", "", code)
    found = []
    for tree in re.findall(r"\buse\s+([^;]+);", code, flags=re.S):
        found += _expand(tree)
    code = re.sub(r"\buse\s+[^;]+;", "", code, flags=re.S)
    found += re.findall(r"\b(?:crate|super|self)(?:::[A-Za-z_]\w*)+", code)
    return found


def _resolve(path: str, here: tuple, modules: set) -> tuple | None:
    """The module a path names from the module `here` (its longest prefix that is a module); None for a path that
    leaves the crate (std, glam, ...)."""
    parts = path.split("::")
    if parts[0] == "crate":
        base, rest = (), parts[1:]
    elif parts[0] == "self":
        base, rest = here, parts[1:]
    elif parts[0] == "super":
        base, rest = here, parts
        while rest and rest[0] == "super":
            base, rest = base[:-1], rest[1:]
    else:
        base, rest = here, parts  # a child module, or another crate
    for p in rest:
        if base + (p,) not in modules:
            break
        base += (p,)
    anchored = parts[0] in ("crate", "self", "super")
    return base if base in modules and (anchored or base != here) else None


def _rust_edges() -> dict:
    """(parent, child_from) -> {child_to}: the dependencies between siblings at every level of the module tree."""
    files = sorted(SRC.rglob("*.rs"))
    modules = {_module(f) for f in files}
    edges: dict = {}
    for f in files:
        here = _module(f)
        code = f.read_text().split("#[cfg(test)]")[0]
        for path in _paths(code):
            target = _resolve(path, here, modules)
            if target is None:
                continue
            common = 0
            while common < min(len(here), len(target)) and here[common] == target[common]:
                common += 1
            if common < len(here) and common < len(target):
                edges.setdefault(here[:common], {}).setdefault(here[common], set()).add(target[common])
    return edges


def _cycle(graph: dict) -> list | None:
    """A cycle of `graph` (node -> successors), as its nodes, or None."""
    state: dict = {}

    def visit(node, trail):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return trail[trail.index(nxt) :] + [nxt]
            if nxt not in state:
                found = visit(nxt, trail + [nxt])
                if found:
                    return found
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node, [node])
            if found:
                return found
    return None


def test_the_rust_modules_use_each_other_without_a_cycle():
    edges = _rust_edges()
    assert ("models",) in edges and () in edges, "the walk found the catalogue and the top level"
    # The walk sees the dependencies it must: models on tables, the reference on transport, the bindings on models.
    assert {"tables", "transport"} <= edges[()]["models"] and "models" in edges[()]["python"]
    for parent, graph in sorted(edges.items()):
        cycle = _cycle(graph)
        where = "::".join(("crate",) + parent)
        assert cycle is None, f"modules of {where} use each other in a cycle: {' -> '.join(cycle)}"


def _python_edges() -> dict:
    """module -> {modules it imports}, for lamina's own modules (the package itself as "__init__")."""
    names = {p.stem for p in PACKAGE.glob("*.py")}
    graph: dict = {}
    for p in PACKAGE.glob("*.py"):
        deps = graph.setdefault(p.stem, set())
        for line in p.read_text().splitlines():
            line = line.strip()
            m = re.match(r"from (\.|lamina)(\w*)(?:\.\w+)* import (.+)", line.replace("lamina.", "."))
            if m:
                module, imported = m.group(2), m.group(3)
                if module:
                    deps.add(module)
                else:  # from . import a, b as c: modules, the Rust extension, or names of the package itself
                    for name in re.findall(r"(\w+)(?:\s+as\s+\w+)?", imported.strip("()")):
                        if name != "_lamina":
                            deps.add(name if name in names else "__init__")
            m = re.match(r"import lamina\.(\w+)", line)
            if m:
                deps.add(m.group(1))
        deps.discard(p.stem)
        deps &= names
    return graph


def test_the_python_modules_import_each_other_without_a_cycle():
    graph = _python_edges()
    assert {"stack", "catalogue", "gpu"} <= graph["renderer"], "the walk found the renderer's imports"
    cycle = _cycle(graph)
    assert cycle is None, f"python/lamina imports in a cycle: {' -> '.join(cycle)}"


def test_the_checks_find_a_cycle():
    # The walk itself: a made-up pair of modules that import each other is a cycle, a chain is not.
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": {"c"}}) is None
    assert _expand("crate::models::{self, common::{block::BLOCK, options}, Args}") == [
        "crate::models::self",
        "crate::models::common::block::BLOCK",
        "crate::models::common::options",
        "crate::models::Args",
    ]
