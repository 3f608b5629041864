#!/usr/bin/env python3
"""Print the import cycles between the top-level modules of a Rust crate's src/ (from `crate::name` paths).
Usage: python3 scripts/module-cycles.py [SRC_DIR]   (default: src). Exit 1 when a cycle exists.
Test modules (`#[cfg(test)] mod tests { ... }` at the end of a file) and comments (doc links) are left out."""
import os, re, sys

src_dir = sys.argv[1] if len(sys.argv) > 1 else "src"
edges = {}
for root, _, files in os.walk(src_dir):
    for f in files:
        if not f.endswith(".rs"):
            continue
        rel = os.path.relpath(os.path.join(root, f), src_dir)
        top = rel.split(os.sep)[0].removesuffix(".rs")
        if top in ("main", "lib"):
            continue
        text = open(os.path.join(root, f), encoding="utf-8", errors="replace").read()
        text = re.sub(r"#\[cfg\(test\)\]\s*mod tests\s*\{.*", "", text, flags=re.S)
        text = re.sub(r"//[^\n]*", "", text)  # doc links and comments are not dependencies
        edges.setdefault(top, set()).update(m for m in re.findall(r"crate::(\w+)", text) if m != top)
edges = {a: {b for b in bs if b in edges} for a, bs in edges.items()}

index, low, stack, on, cycles = {}, {}, [], set(), []
def visit(v, counter=[0]):
    index[v] = low[v] = counter[0]; counter[0] += 1
    stack.append(v); on.add(v)
    for w in sorted(edges[v]):
        if w not in index:
            visit(w); low[v] = min(low[v], low[w])
        elif w in on:
            low[v] = min(low[v], index[w])
    if low[v] == index[v]:
        comp = []
        while True:
            w = stack.pop(); on.discard(w); comp.append(w)
            if w == v:
                break
        if len(comp) > 1:
            cycles.append(sorted(comp))
for v in sorted(edges):
    if v not in index:
        visit(v)

for a in sorted(edges):
    print(f"{a} -> {', '.join(sorted(edges[a])) or '-'}")
if cycles:
    for c in cycles:
        inside = [f"{a}->{b}" for a in c for b in sorted(edges[a]) if b in c]
        print(f"cycle among {len(c)} modules: {' '.join(inside)}")
    sys.exit(1)
print("no import cycles between top-level modules")
