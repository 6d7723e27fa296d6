#!/usr/bin/env python3
"""Checks that the Rust source files depend on each other in layers: no two
files import each other, and no longer cycle either.

A file depends on another when it names an item defined there: through
`use crate::…` or `use super::…` or a path written out in the code
(`crate::model::number(…)`; re-exports of a `mod.rs` followed to the file
that defines the item), or by adding methods to a type defined there
(`impl Type { … }` in another file: the two halves of one type are one idea
split over two files). `mod.rs` files that only declare and re-export
modules are not nodes of their own.

    python scripts/check_imports.py [SRC_DIR]      (default: src)

Prints every cycle and exits 1 if there is one; prints the layer count and
exits 0 otherwise. tests/python/test_layers.py runs it in CI.
"""

import re
import sys
from pathlib import Path

ITEM = re.compile(
    r"^\s*(?:pub(?:\([^)]*\))?\s+)?(?:unsafe\s+)?(?:const\s+fn|fn|struct|enum|trait|type|const|static|mod|macro_rules!)\s+([A-Za-z_][A-Za-z0-9_]*)",
    re.M,
)
USE = re.compile(r"^\s*(?:pub(?:\([^)]*\))?\s+)?use\s+([^;]+);", re.M)
IMPL = re.compile(
    r"^\s*impl(?:<[^>]*>)?\s+(?:[A-Za-z_:<>, ]+\s+for\s+)?([A-Za-z_][A-Za-z0-9_]*)\s*(?:<[^>{]*>)?\s*\{", re.M
)


def strip_comments(text):
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def strip_tests(text):
    """Drops `#[cfg(test)] mod … { … }` blocks: tests may use anything."""
    out, i = [], 0
    for m in re.finditer(r"#\[cfg\(test\)\]\s*mod\s+\w+\s*\{", text):
        if m.start() < i:
            continue
        out.append(text[i : m.start()])
        depth, j = 1, m.end()
        while j < len(text) and depth:
            depth += {"{": 1, "}": -1}.get(text[j], 0)
            j += 1
        i = j
    out.append(text[i:])
    return "".join(out)


def expand(tree):
    """`a::{b, c::{d, e}}` -> ['a::b', 'a::c::d', 'a::c::e']."""
    tree = re.sub(r"\s+", "", tree)
    m = re.match(r"^(.*?)\{(.*)\}$", tree)
    if not m:
        return [re.sub(r"as\w+$", "", tree) if "as" in tree.split("::")[-1] else tree]
    prefix, inner = m.group(1), m.group(2)
    parts, depth, cur = [], 0, ""
    for ch in inner:
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
            continue
        depth += {"{": 1, "}": -1}.get(ch, 0)
        cur += ch
    parts.append(cur)
    return [p for part in parts if part for p in expand(prefix + part)]


class Crate:
    def __init__(self, src):
        self.src = src
        self.files = sorted(p for p in src.rglob("*.rs") if p.name != "lib.rs" or p.parent == src)
        self.text = {p: strip_tests(strip_comments(p.read_text())) for p in self.files}

    def module_path(self, f):
        rel = f.relative_to(self.src).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] in ("mod", "lib"):
            parts = parts[:-1]
        return parts

    def file_of(self, parts):
        base = self.src.joinpath(*parts) if parts else self.src / "lib"
        for cand in (base.with_suffix(".rs"), base / "mod.rs"):
            if cand in self.text:
                return cand
        if not parts:
            return self.src / "lib.rs"
        return None

    def defines(self, f, name):
        return any(m.group(1) == name for m in ITEM.finditer(self.text[f]))

    def reexport(self, f, name):
        """Where a `pub use` of module file `f` takes `name` from."""
        for m in USE.finditer(self.text[f]):
            if not m.group(0).lstrip().startswith("pub"):
                continue
            for path in expand(m.group(1)):
                last = path.split("::")[-1]
                if last == name or last == "*":
                    full = path if last == name else path[:-1] + name
                    return self.absolute(f, full.split("::"))
        return None

    def absolute(self, f, segs):
        here = self.module_path(f)
        own = here
        if segs[0] == "crate":
            return segs[1:]
        if segs[0] == "self":
            return own + segs[1:]
        out = list(own)
        while segs and segs[0] == "super":
            out = out[:-1]
            segs = segs[1:]
        if out == own and segs:
            # A plain path: a child module of this one, or an external crate.
            return own + segs if self.file_of(own + segs[:1]) else None
        return out + segs

    def resolve(self, parts, seen=None):
        """The file that defines crate path `parts` (module path + item)."""
        seen = seen or set()
        key = tuple(parts)
        if key in seen or not parts:
            return None
        seen.add(key)
        whole = self.file_of(parts)
        if whole is not None:
            return whole  # a module: depends on the module's file
        module, name = parts[:-1], parts[-1]
        f = self.file_of(module)
        if f is None:
            return None
        if self.defines(f, name):
            return f
        target = self.reexport(f, name)
        return self.resolve(target, seen) if target else f

    def dependencies(self, f):
        deps = set()
        for m in USE.finditer(self.text[f]):
            for path in expand(m.group(1)):
                segs = path.split("::")
                if segs[0] not in ("crate", "super", "self"):
                    continue
                parts = self.absolute(f, segs)
                if parts is None:
                    continue
                target = self.resolve(parts)
                if target is not None and target != f:
                    deps.add(target)
        # Paths written out in the code: `crate::model::number(…)`.
        body = USE.sub("", self.text[f])
        for m in re.finditer(r"\b(crate(?:::[A-Za-z_][A-Za-z0-9_]*)+)", body):
            target = self.resolve(m.group(1).split("::")[1:])
            if target is not None and target != f:
                deps.add(target)
        for m in IMPL.finditer(self.text[f]):
            ty = m.group(1)
            if self.defines(f, ty):
                continue
            for other in self.files:
                if other != f and re.search(
                    rf"^\s*(?:pub(?:\([^)]*\))?\s+)?(?:struct|enum)\s+{ty}\b", self.text[other], re.M
                ):
                    deps.add(other)
        return deps

    def is_reexport_only(self, f):
        body = re.sub(r"#!?\[[^\]]*\]", "", self.text[f])
        body = USE.sub("", body)
        body = re.sub(r"^\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+\w+\s*;", "", body, flags=re.M)
        return not body.strip()


def strongly_connected(graph):
    """Tarjan's strongly connected components of ``graph`` (node -> set of nodes), each a
    list; tests/python/test_package_imports.py uses it on the Python package too."""
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
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
            comps.append(comp)

    sys.setrecursionlimit(10000)
    for v in graph:
        if v not in index:
            visit(v)
    return comps


def main():
    src = Path(sys.argv[1] if len(sys.argv) > 1 else "src")
    crate = Crate(src)
    nodes = [f for f in crate.files if not crate.is_reexport_only(f) and f.parent != src / "bin"]
    graph = {f: {d for d in crate.dependencies(f) if d in nodes} for f in nodes}
    comps = strongly_connected(graph)
    cycles = [c for c in comps if len(c) > 1]
    for c in cycles:
        members = set(c)
        print("cycle: " + ", ".join(sorted(str(p) for p in c)))
        for a in sorted(c):
            for b in sorted(graph[a] & members):
                print(f"    {a} -> {b}")
    if cycles:
        print(f"check_imports: {len(cycles)} cycle(s) among {len(nodes)} files")
        return 1
    # Layers: longest path from a file to the bottom.
    depth = {}

    def layer(v):
        if v not in depth:
            depth[v] = 1 + max((layer(w) for w in graph[v]), default=0)
        return depth[v]

    top = max(layer(v) for v in nodes)
    print(f"check_imports: {len(nodes)} files, no cycles, {top} layers")
    return 0


if __name__ == "__main__":
    sys.exit(main())
