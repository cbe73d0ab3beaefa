#!/usr/bin/env python3
"""Checks the layout rules of the workspace: no source file over 500 lines
(tests excluded), no function over 120 lines, and no cycle among the modules
of a crate (through `use crate::...`/`super::...` imports and paths). Each
binary is a module tree of its own: `src/bin/<name>.rs`, or the directory
`src/bin/<name>/` rooted at its `main.rs` (and `src/main.rs` where the crate
also has a `src/lib.rs`), checked apart from the library's tree.

    python3 scripts/check-layout.py            # report and exit 1 on a breach
    python3 scripts/check-layout.py --list 10  # also list the longest functions
"""
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CRATES = ["model", "datasets", "clip", "field-ops", "train", "eval", "fuzz-harness", "viewer", "bench", "batch"]
MAX_FILE, MAX_FN = 500, 120


def rust_files(crate):
    src = os.path.join(ROOT, crate, "src")
    for d, _, names in os.walk(src):
        for n in names:
            if n.endswith(".rs"):
                yield os.path.join(d, n)


def strip_tests(text):
    """The file without its `#[cfg(test)] mod tests { ... }` block."""
    m = re.search(r"^#\[cfg\(test\)\]\s*\n\s*mod \w+", text, re.M)
    return text[: m.start()] if m else text


def module_of(crate, path):
    """(tree, module) of a source file: the tree is `lib` for the library
    (or a binary crate's `src/main.rs` tree), `bin <name>` for a binary, and
    the module its path inside that tree (`""` for the tree's root)."""
    src = os.path.join(ROOT, crate, "src")
    parts = os.path.relpath(path, src)[:-3].split(os.sep)
    tree = "lib"
    if parts[0] == "bin":
        tree = f"bin {parts[1]}"
        parts = parts[2:]
    elif parts == ["main"] and os.path.exists(os.path.join(src, "lib.rs")):
        tree = "bin main"
    if parts and parts[-1] in ("mod", "lib", "main"):
        parts = parts[:-1]
    return tree, "::".join(parts)


def functions(text):
    """(name, first line, line count) of every `fn` with a body, by braces."""
    lines = text.split("\n")
    out = []
    for i, line in enumerate(lines):
        m = re.match(r"\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?fn\s+(\w+)", line)
        if not m:
            continue
        depth, started = 0, False
        for j in range(i, len(lines)):
            code = re.sub(r'"(\\.|[^"\\])*"', '""', lines[j].split("//")[0])
            if not started and ";" in code and "{" not in code:
                break
            depth += code.count("{") - code.count("}")
            started = started or "{" in code
            if started and depth <= 0:
                out.append((m.group(5), i + 1, j - i + 1))
                break
    return out


def use_tree(s, i):
    """The paths of the use tree (or path) at `s[i:]`: `a::b`, `a::{b, c::d}`,
    `{a, b}`, each as a list of segments (`self` and `*` dropped), and the
    index after it."""
    i = len(s) - len(s[i:].lstrip())
    if s.startswith("{", i):
        out, i = [], i + 1
        while i < len(s):
            i = len(s) - len(s[i:].lstrip())
            if s.startswith("}", i):
                return out, i + 1
            sub, j = use_tree(s, i)
            out += sub
            j = len(s) - len(s[j:].lstrip())
            i = j + 1 if s.startswith(",", j) else max(j, i + 1)
        return out, i
    m = re.compile(r"\w+|\*").match(s, i)
    if not m:
        return [[]], i
    seg, i = m.group(), m.end()
    j = len(s) - len(s[i:].lstrip())
    if s.startswith("::", j):
        sub, i = use_tree(s, j + 2)
        return [[seg] + p for p in sub], i
    rename = re.compile(r"\s+as\s+\w+").match(s, i)
    return [[seg]], rename.end() if rename else i


def imports(crate, module, text):
    """Modules of the same crate (or binary) that `module` names through
    `crate::` and `super::` paths, brace groups included, resolved to paths."""
    found = set()
    body = "\n".join(l.split("//")[0] for l in strip_tests(text).split("\n"))
    parent = module.split("::")[:-1] if module else []
    for m in re.finditer(r"(?<!::)\b(crate|super)::", body):
        base = [] if m.group(1) == "crate" else list(parent)
        for parts in use_tree(body, m.end())[0]:
            while parts and parts[0] == "super":
                base, parts = base[:-1], parts[1:]
            parts = [p for p in parts if p not in ("self", "*")]
            found.add("::".join(base + parts))
    return found


def main():
    listing = int(sys.argv[sys.argv.index("--list") + 1]) if "--list" in sys.argv else 0
    breaches, all_fns = [], []
    for crate in CRATES:
        trees = {}
        for path in rust_files(crate):
            text = open(path, encoding="utf-8").read()
            code = strip_tests(text)
            rel = os.path.relpath(path, ROOT)
            n = code.count("\n")
            if n > MAX_FILE:
                breaches.append(f"{rel}: {n} lines outside tests (most {MAX_FILE})")
            for name, line, count in functions(code):
                all_fns.append((count, f"{rel}:{line} {name}"))
                if count > MAX_FN:
                    breaches.append(f"{rel}:{line}: fn {name} has {count} lines (most {MAX_FN})")
            tree, mod = module_of(crate, path)
            trees.setdefault(tree, {})[mod] = text
        for tree, texts in sorted(trees.items()):
            name = crate if tree == "lib" else f"{crate} ({tree})"
            for cycle in cycles(module_graph(crate, texts)):
                breaches.append(f"{name}: module cycle " + " -> ".join(cycle))
    for b in breaches:
        print(b)
    if listing:
        for count, where in sorted(all_fns, reverse=True)[:listing]:
            print(f"{count:5} {where}")
    print(f"{len(breaches)} breaches")
    return 1 if breaches else 0


def module_graph(crate, texts):
    """Which modules of one tree each module imports. An import names the
    longest module path it starts with; the root's imports and a module's
    imports of its own submodules are no edges."""
    graph = {}
    for mod, text in texts.items():
        targets = set()
        for target in imports(crate, mod, text):
            parts = target.split("::")
            for k in range(len(parts), 0, -1):
                cand = "::".join(parts[:k])
                if cand in texts and cand != mod:
                    # A module's own submodules are its rooms, not a cycle.
                    if not cand.startswith(mod + "::") and not (mod == ""):
                        targets.add(cand)
                    break
        graph[mod] = targets
    return graph


def cycles(graph):
    """One representative cycle per strongly connected component."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
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
                out.append(sorted(comp) + [sorted(comp)[0]])

    sys.setrecursionlimit(10000)
    for v in list(graph):
        if v not in index:
            visit(v)
    return out


if __name__ == "__main__":
    sys.exit(main())
