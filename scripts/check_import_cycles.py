#!/usr/bin/env python3
"""Finds import cycles between the modules of each Rust crate and each Python package.

A cycle between modules (a uses b, b uses a) means neither can be read, tested or
moved without the other: the newcomer's map of "who depends on whom" stops being a
tree. This check keeps it one.

Rust (every crate under rust/*/src): the module tree is followed from lib.rs / main.rs
through `mod` declarations. Every module with submodules is checked, the crate root
first: the nodes are its direct submodules (`foo.rs` or `foo/mod.rs` is `foo`), each
standing for itself and everything below it, so a crate's grouping folders (baffle-core's
`steps/`, `geometry/`, `analyses/`) are checked as nodes at the root and their modules
(`steps::seam`, `steps::patch`, ...) against each other inside the folder. An edge a -> b
is any `use crate::...`, `crate::...` path anywhere in a's code (function bodies too) or
`super::...` / `self::...` path that resolves into b. The parent itself is not a node
(its `pub use` re-exports are its public API; a path to a re-exported item counts for no
submodule). Test code is skipped: items under `#[cfg(test)]` (inline `mod tests { }` and
`mod tests;` files), files named tests.rs or under a tests/ folder, and
rust/*/{tests,benches,examples}. Comments, string and char literals are stripped first.

Python (slicer_module/BaffleDesigner/BaffleDesignerLib and python/baffle): the nodes
are the package's modules (`__init__` is not a node). An edge is any import of a
sibling module, at module level or inside a function (a function-level import hides
a cycle, it does not remove it): `import X`, `import pkg.X`, `from . import X`,
`from .X import ...`, `from pkg import X`, `from pkg.X import ...`.

Prints every cycle as `crate: a -> b -> a` (with where each edge comes from) and
exits 1 if there is any; otherwise prints a one-line summary and exits 0.
`--self-test` builds a small tree with a known Rust cycle and a known function-level
Python cycle and checks both are found and that an acyclic tree passes.
"""

import argparse
import ast
import os
import re
import sys
import tempfile
from pathlib import Path

PYTHON_PACKAGES = (
    ("slicer_module/BaffleDesigner/BaffleDesignerLib", "BaffleDesignerLib"),
    ("python/baffle", "baffle"),
)
MAX_CYCLES_PER_GROUP = 50


# ----------------------------------------------------------------------------- Rust


def strip_rust(text):
    """The code with comments, string and char literals blanked (newlines kept, so line numbers hold)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        nxt = text[i + 1] if i + 1 < n else ""
        if c == "/" and nxt == "/":
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif c == "/" and nxt == "*":
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif c == "r" and re.match(r'r#*"', text[i:i + 40]) and not (i and (text[i - 1].isalnum() or text[i - 1] == "_")):
            hashes = re.match(r'r(#*)"', text[i:]).group(1)
            end = text.find('"' + hashes, i + 2 + len(hashes))
            j = n if end < 0 else end + 1 + len(hashes)
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
        elif c == "'":
            # A char literal ('x', '\n', '\u{..}') or a lifetime ('a): only the former is skipped.
            if nxt == "\\":
                j = text.find("'", i + 3)
                j = n if j < 0 else j + 1
                out.append("' '")
                i = j
            elif i + 2 < n and text[i + 2] == "'":
                out.append("' '")
                i += 3
            else:
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def matching_brace(code, open_at):
    depth = 0
    for j in range(open_at, len(code)):
        if code[j] == "{":
            depth += 1
        elif code[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(code) - 1


CFG_TEST = re.compile(r"#\s*\[\s*cfg\s*\(\s*test\s*\)\s*\]")
ATTRIBUTE = re.compile(r"\s*#\s*!?\s*\[[^\]]*\]")
MOD_DECL = re.compile(r"^\s*(?:pub(?:\s*\([^)]*\))?\s+)?mod\s+(\w+)\s*;", re.M)


def drop_test_items(code):
    """The code without the items under `#[cfg(test)]`, and the names of `#[cfg(test)] mod x;` files."""
    test_mods = set()
    while True:
        m = CFG_TEST.search(code)
        if not m:
            return code, test_mods
        j = m.end()
        while True:  # further attributes on the same item
            a = ATTRIBUTE.match(code, j)
            if not a:
                break
            j = a.end()
        semi, brace = code.find(";", j), code.find("{", j)
        decl = re.match(r"\s*(?:pub(?:\s*\([^)]*\))?\s+)?mod\s+(\w+)\s*;", code[j:])
        if decl:
            test_mods.add(decl.group(1))
        if brace >= 0 and (semi < 0 or brace < semi):
            end = matching_brace(code, brace) + 1
        else:
            end = len(code) if semi < 0 else semi + 1
        code = code[:m.start()] + "\n" * code.count("\n", m.start(), end) + code[end:]


def expand_use_tree(tree):
    """`a::{b, c::{d, e}}` -> ['a::b', 'a::c::d', 'a::c::e'] (aliases dropped)."""
    tree = re.sub(r"\s+", "", re.sub(r"\s+as\s+\w+", "", tree))
    brace = tree.find("{")
    if brace < 0:
        return [tree] if tree else []
    prefix, inner = tree[:brace], tree[brace + 1:tree.rfind("}")]
    parts, depth, start = [], 0, 0
    for k, ch in enumerate(inner):
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(inner[start:k])
            start = k + 1
    parts.append(inner[start:])
    paths = []
    for part in parts:
        for sub in expand_use_tree(part):
            paths.append(prefix + sub if sub != "self" else prefix.rstrip(":"))
    return paths


USE_STMT = re.compile(r"\buse\s+([^;]*);")
PATH_USE = re.compile(r"(?<![\w$])((?:crate|super|self)(?:::\w+)+)")


def resolve(path, module):
    """The module path (a list, from the crate root) a `crate::` / `super::` / `self::` path names, or None."""
    parts = path.split("::")
    if parts[0] == "crate":
        rest = parts[1:]
    elif parts[0] in ("super", "self"):
        base = list(module)
        k = 0
        if parts[0] == "self":
            k = 1
        while k < len(parts) and parts[k] == "super":
            if not base:
                return None
            base.pop()
            k += 1
        rest = base + parts[k:]
    else:
        return None
    return rest or None


def rust_edges(code, module):
    """(target path from the crate root, line) for every crate-relative path in the stripped code."""
    found = []
    covered = []
    for m in USE_STMT.finditer(code):
        line = code.count("\n", 0, m.start()) + 1
        for path in expand_use_tree(m.group(1)):
            target = resolve(path, module)
            if target:
                found.append((target, line))
        covered.append((m.start(), m.end()))
    code = re.sub(r"\bpub\s*\(\s*in\s+[\w:]+\s*\)", lambda x: " " * len(x.group(0)), code)
    for m in PATH_USE.finditer(code):
        if any(a <= m.start() < b for a, b in covered):
            continue
        target = resolve(m.group(1), module)
        if target:
            found.append((target, code.count("\n", 0, m.start()) + 1))
    return found


def rust_crate_graphs(src, crate):
    """One graph per module with submodules: [(name, nodes, edges {(a, b): 'file:line'})],
    the crate root's first (named `crate`), then e.g. `crate::steps` for baffle-core's steps/."""
    root = src / "lib.rs" if (src / "lib.rs").exists() else src / "main.rs"
    modules, uses = {()}, []
    # (file, module path as a list, folder of its submodules)
    queue = [(root, [], src)]
    seen = set()
    while queue:
        path, module, subdir = queue.pop()
        if path in seen or not path.exists():
            continue
        seen.add(path)
        code, test_mods = drop_test_items(strip_rust(path.read_text(encoding="utf-8")))
        for m in MOD_DECL.finditer(code):
            name = m.group(1)
            if name in test_mods or name == "tests":
                continue
            child = module + [name]
            for candidate, child_dir in ((subdir / (name + ".rs"), subdir / name), (subdir / name / "mod.rs", subdir / name)):
                if candidate.exists():
                    modules.add(tuple(child))
                    queue.append((candidate, child, child_dir))
                    break
        if module:
            for target, line in rust_edges(code, module):
                uses.append((tuple(module), target, "%s:%d" % (path, line)))
    graphs = {}
    for parent in sorted(modules, key=lambda m: (len(m), m)):
        children = {m[-1] for m in modules if len(m) == len(parent) + 1 and m[:-1] == parent}
        if children:
            graphs[parent] = (children, {})
    for module, target, where in uses:
        # The edge counts in the deepest module holding both ends: there they are siblings.
        k = 0
        while k < len(module) and k < len(target) and module[k] == target[k]:
            k += 1
        if k == len(module) or k == len(target):
            continue  # into itself or an ancestor (the parent is no node)
        parent = module[:k]
        if tuple(target[:k + 1]) in modules:
            graphs[parent][1].setdefault((module[k], target[k]), where)
    return [("::".join((crate,) + parent), nodes, edges) for parent, (nodes, edges) in graphs.items()]


# --------------------------------------------------------------------------- Python


def python_package_graph(folder, package):
    """Nodes, edges {(a, b): 'file:line'} of one package's modules (imports in functions included)."""
    modules = {p.stem: p for p in folder.glob("*.py") if p.stem != "__init__"}
    edges = {}
    for name, path in sorted(modules.items()):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.Import):
                for alias in node.names:
                    parts = alias.name.split(".")
                    if parts[0] == package and len(parts) > 1:
                        targets.append(parts[1])
                    elif len(parts) == 1:
                        targets.append(parts[0])
            elif isinstance(node, ast.ImportFrom):
                parts = node.module.split(".") if node.module else []
                if node.level == 1:
                    rest = parts
                elif node.level == 0 and parts[:1] == [package]:
                    rest = parts[1:]
                else:
                    continue
                targets = [rest[0]] if rest else [alias.name for alias in node.names]
            for target in targets:
                if target in modules and target != name:
                    edges.setdefault((name, target), "%s:%d" % (path, node.lineno))
    return set(modules), edges


# ------------------------------------------------------------------------- cycles


def cycles(nodes, edges):
    """Every elementary cycle (as a node list, first node the smallest), at most MAX_CYCLES_PER_GROUP."""
    succ = {n: sorted(b for (a, b) in edges if a == n) for n in nodes}
    found = []
    for start in sorted(nodes):
        stack = [(start, [start])]
        while stack and len(found) < MAX_CYCLES_PER_GROUP:
            node, path = stack.pop()
            for nxt in succ.get(node, ()):
                if nxt == start:
                    found.append(path + [start])
                elif nxt > start and nxt not in path:
                    stack.append((nxt, path + [nxt]))
    return found


def check(repo, out=sys.stdout):
    groups = []
    n_crates = len(sorted((repo / "rust").glob("*/src")))
    for src in sorted((repo / "rust").glob("*/src")):
        groups.extend(rust_crate_graphs(src, src.parent.name))
    for folder, package in PYTHON_PACKAGES:
        if (repo / folder).is_dir():
            groups.append((folder, *python_package_graph(repo / folder, package)))
    n_cycles = n_nodes = n_edges = 0
    for name, nodes, edges in groups:
        n_nodes += len(nodes)
        n_edges += len(edges)
        for cyc in cycles(nodes, edges):
            n_cycles += 1
            print("%s: %s" % (name, " -> ".join(cyc)), file=out)
            for a, b in zip(cyc, cyc[1:]):
                where = edges[(a, b)]
                try:
                    where = os.path.relpath(where, repo)
                except ValueError:
                    pass
                print("    %s -> %s  (%s)" % (a, b, where), file=out)
    if n_cycles:
        print("%d import cycle(s): move the shared item to the module that owns it (or a small new one)" % n_cycles, file=out)
        return 1
    n_python = sum((repo / folder).is_dir() for folder, _ in PYTHON_PACKAGES)
    print("no import cycles: %d crates and %d packages (%d module graphs), %d modules, %d edges" % (n_crates, n_python, len(groups), n_nodes, n_edges), file=out)
    return 0


# ----------------------------------------------------------------------- self-test


def write_tree(root, files):
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


def self_test():
    import io

    acyclic = {
        "rust/demo/src/lib.rs": "pub mod a;\npub mod b;\nmod c;\n#[cfg(test)]\nmod helpers;\npub use a::A;\n",
        "rust/demo/src/a.rs": "use crate::b::B;\npub struct A(B);\n"
                              "#[cfg(test)]\nmod tests {\n    use crate::c::C;\n}\n",
        "rust/demo/src/b/mod.rs": "pub mod inner;\n#[cfg(test)]\nmod tests;\npub use inner::B;\nconst S: &str = \"crate::a::A\";\n",
        "rust/demo/src/b/inner.rs": "pub struct B; // use crate::a::A;\nfn f() -> super::super::c::C { crate::c::C }\n",
        "rust/demo/src/b/tests.rs": "use crate::a::A;\n",
        "rust/demo/src/c.rs": "pub struct C;\nfn f<'a>(x: &'a str) -> char { '\"' }\n",
        "rust/demo/src/helpers.rs": "use crate::a::A;\n",
        "rust/demo/tests/t.rs": "use demo::c;\n",
        "python/baffle/__init__.py": "from .design import design\n",
        "python/baffle/design.py": "from ._lib import lib\n\ndef design():\n    from . import render\n",
        "python/baffle/_lib.py": "import os\n",
        "python/baffle/render.py": "from baffle._lib import lib\n",
    }
    cyclic_rust = {"rust/demo/src/c.rs": "pub struct C;\nfn g() { let _ = super::a::A; }\n"}
    cyclic_python = {"python/baffle/render.py": "def draw():\n    from baffle.design import design\n"}
    grouped_use = {"rust/demo/src/c.rs": "use crate::{b::B, a::{self}};\npub struct C;\n"}
    # Two modules of one folder using each other: no cycle between the crate's top-level modules.
    in_folder = {
        "rust/demo/src/b/mod.rs": "pub mod inner;\npub mod inner2;\npub use inner::B;\n",
        "rust/demo/src/b/inner2.rs": "pub fn g() { super::inner::f() }\n",
        "rust/demo/src/b/inner.rs": "pub struct B;\npub fn f() { let _ = crate::b::inner2::g; }\nfn h() -> super::super::c::C { crate::c::C }\n",
    }
    cases = (
        ({}, 0, []),
        (cyclic_rust, 1, ["demo: a -> b -> c -> a"]),
        (cyclic_python, 1, ["python/baffle: design -> render -> design"]),
        (grouped_use, 1, ["demo: a -> b -> c -> a"]),
        (in_folder, 1, ["demo::b: inner -> inner2 -> inner"]),
    )
    for extra, want_rc, want_lines in cases:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp)
            write_tree(root, {**acyclic, **extra})
            buf = io.StringIO()
            rc = check(root, buf)
            text = buf.getvalue()
            assert rc == want_rc, "self-test: exit %d, expected %d for %s:\n%s" % (rc, want_rc, sorted(extra), text)
            for line in want_lines:
                assert line in text.splitlines(), "self-test: %r not reported:\n%s" % (line, text)
            if want_rc == 0:
                assert "(3 module graphs), 7 modules, 5 edges" in text, "self-test: wrong counts: " + text
    print("self-test passed: a Rust cycle (super:: in a function body, grouped use), one between two modules of a folder and a function-level Python cycle are found; the acyclic tree passes")
    return 0


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--self-test", action="store_true", help="prove the check finds known cycles in a temporary tree")
    parser.add_argument("--repo", type=Path, default=Path(__file__).resolve().parent.parent)
    args = parser.parse_args()
    if args.self_test:
        return self_test()
    return check(args.repo)


if __name__ == "__main__":
    sys.exit(main())
