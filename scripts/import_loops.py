#!/usr/bin/env python3
"""The import loops between the source files of each crate (`python3 scripts/import_loops.py`).

A file imports another when it names an item through that file's module path
(`crate::a::b::item`, `super::b::item`, `use b::...` from a parent module). Module roots
(`lib.rs`, `mod.rs`) only declare and re-export, so arrows into and out of them are left out;
unit tests (from `#[cfg(test)]` on) are left out too. Prints each loop (a strongly connected set
of files) with the names that tie it, and exits 1 if there is one and `--fail` is given.
Standard library only.
"""
import argparse
import os
import re
import sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
PATH_RE = re.compile(r"\b(crate|super|self)((?:::[A-Za-z_][A-Za-z0-9_]*)+)")
USE_RE = re.compile(r"\buse\s+([a-z_][a-z0-9_]*)::")


def crates():
    out = [("dvrk", os.path.join(ROOT, "src"))]
    base = os.path.join(ROOT, "crates")
    for name in sorted(os.listdir(base)):
        src = os.path.join(base, name, "src")
        if os.path.isdir(src):
            out.append((name, src))
    return out


def modules(src):
    """Module path (tuple) -> file, for every .rs file under src."""
    out = {}
    for d, _, files in os.walk(src):
        for f in files:
            if not f.endswith(".rs"):
                continue
            rel = os.path.relpath(os.path.join(d, f), src)[:-3].split(os.sep)
            if rel[-1] in ("mod", "lib", "main"):
                rel = rel[:-1]
            out[tuple(rel)] = os.path.join(d, f)
    return out


def is_root(path):
    return os.path.basename(path) in ("lib.rs", "mod.rs", "main.rs")


def edges(src):
    mods = modules(src)
    by_file = {f: m for m, f in mods.items()}
    out = {}
    for f, m in by_file.items():
        if is_root(f):
            continue
        text = open(f, encoding="utf-8").read()
        text = text.split("#[cfg(test)]")[0]
        text = re.sub(r"//[^\n]*", "", text)
        parent = m[:-1]
        found = {}
        refs = [(root, tail) for root, tail in PATH_RE.findall(text)]
        refs += [("child", "::" + name) for name in USE_RE.findall(text)]
        for root, tail in refs:
            parts = tail.strip(":").split("::")
            base = {"crate": (), "super": parent, "self": m, "child": m}[root]
            if root == "super":
                # super::super::x
                while parts and parts[0] == "super":
                    base = base[:-1]
                    parts = parts[1:]
            path = base + tuple(parts)
            # The longest prefix that is a module file.
            for k in range(len(path), 0, -1):
                target = mods.get(path[:k])
                if target is not None:
                    if target != f and not is_root(target):
                        item = path[k] if k < len(path) else path[k - 1]
                        found.setdefault(target, set()).add(item)
                    break
        out[f] = found
    return out


def loops(graph):
    """Strongly connected sets of more than one file (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, {}):
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
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in graph:
        if v not in index:
            visit(v)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--fail", action="store_true", help="exit 1 when a loop remains")
    a = ap.parse_args()
    total = 0
    for name, src in crates():
        graph = edges(src)
        for comp in loops(graph):
            total += 1
            print(f"{name}: loop of {len(comp)} files")
            for f in comp:
                for g, items in sorted(graph[f].items()):
                    if g in comp:
                        print(f"  {os.path.relpath(f, ROOT)} -> {os.path.relpath(g, ROOT)}: {', '.join(sorted(items))}")
    print(f"{total} import loop(s)")
    if a.fail and total:
        sys.exit(1)


if __name__ == "__main__":
    main()
