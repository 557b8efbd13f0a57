#!/usr/bin/env python3
"""Import cycles between the modules of a crate.

Builds the module graph from every `use` tree and inline `crate::`/`super::` path (comments and
inline #[cfg(test)] modules stripped; a path through a `pub use` re-export counts as an edge to
the module that defines the item) and prints every strongly connected component with more than
one module. Exits 1 if there is one. Usage: module_cycles.py <crate>/src [--edges]"""
import os, re, sys

root = sys.argv[1]  # e.g. kernel/src
show_edges = '--edges' in sys.argv[2:]
modules = {}
for dp, dn, fn in os.walk(root):
    for f in fn:
        if not f.endswith('.rs'):
            continue
        p = os.path.join(dp, f)
        rel = os.path.relpath(p, root)[:-3].split(os.sep)
        if rel == ['lib']:
            mod = ['crate']
        elif rel[-1] == 'mod':
            mod = ['crate'] + rel[:-1]
        else:
            mod = ['crate'] + rel
        modules['::'.join(mod)] = p

def strip(text):
    text = re.sub(r'/\*.*?\*/', '', text, flags=re.S)
    text = re.sub(r'//[^\n]*', '', text)
    text = re.sub(r'"(?:\\.|[^"\\])*"', '""', text)
    text = re.sub(r'\bpub\(in [^)]*\)', 'pub', text)  # a visibility path is not an import
    m = re.search(r'#\[cfg\(test\)\]\s*(#\[[^\]]*\]\s*)*(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{', text)
    if m:
        text = text[:m.start()]
    return text

def expand(tree):
    tree = tree.strip()
    m = re.match(r'^(.*?)::\{(.*)\}$', tree, re.S)
    if m:
        base, inner = m.group(1), m.group(2)
        parts, depth, cur = [], 0, ''
        for ch in inner:
            if ch == ',' and depth == 0:
                parts.append(cur); cur = ''
                continue
            depth += ch == '{'
            depth -= ch == '}'
            cur += ch
        parts.append(cur)
        out = []
        for p in parts:
            if p.strip():
                for e in expand(p):
                    out.append(base + '::' + e if e != 'self' else base)
        return out
    return [re.sub(r'\s+as\s+\w+$', '', tree)]

def resolve(mod, path):
    segs = path.split('::')
    cur = mod.split('::')
    # a file under foo/mod.rs is module foo; super is its parent
    if segs[0] == 'crate':
        cur, segs = ['crate'], segs[1:]
    elif '::'.join(cur + [segs[0]]) in modules:
        pass
    elif segs[0] in ('super', 'self'):
        while segs and segs[0] in ('super', 'self'):
            if segs[0] == 'super':
                cur = cur[:-1]
            segs = segs[1:]
    else:
        return None
    target = cur[:]
    for s in segs:
        if '::'.join(target + [s]) in modules:
            target.append(s)
        else:
            break
    return '::'.join(target)

texts = {m: strip(open(p).read()) for m, p in modules.items()}
ITEM = r'(?:pub(?:\([^)]*\))?\s+)?(?:const\s+fn|unsafe\s+fn|fn|struct|enum|const|static|type|trait|union|mod)\s+'
def follow(target, name, depth=0):
    # the module that defines `name` when reached as `target::name` (through `pub use` re-exports)
    if depth > 10 or target not in texts:
        return target
    t = texts[target]
    if re.search(r'(?m)^\s*' + ITEM + re.escape(name) + r'\b', t):
        return target
    for m in re.finditer(r'\bpub(?:\([^)]*\))?\s+use\s+([^;]+);', t):
        for e in expand(m.group(1)):
            e = e.strip()
            last = re.split(r'\s+as\s+', e)[-1].split('::')[-1]
            if last == name or e.endswith('::*'):
                path = e if not e.endswith('::*') else e[:-1] + name
                r = resolve(target, path)
                if r and r != target:
                    return follow(r, name, depth + 1) if '::'.join([r, name]) not in modules else r
    return target

edges = set()
for mod, p in modules.items():
    text = strip(open(p).read())
    paths = []
    for m in re.finditer(r'\buse\s+([^;]+);', text):
        paths += expand(m.group(1))
    for m in re.finditer(r'\b(?:crate|super)(?:::[A-Za-z_]\w*)+', text):
        paths.append(m.group(0))
    for path in paths:
        path = path.strip()
        t = resolve(mod, path)
        if t:
            # the first segment after the module path is an item name
            tail = [x for x in path.split('::') if x not in ('crate', 'super', 'self')]
            cand = [x for x in tail if '::'.join([t, x]) not in modules]
            if cand and cand[0] != '*':
                t = follow(t, re.sub(r'\s+as\s+\w+$', '', cand[0]))
        if t and t != mod:
            edges.add((mod, t))

# module granularity: a module and its ancestors are different nodes; report every SCC
nodes = sorted(modules)
adj = {n: sorted({b for a, b in edges if a == n}) for n in nodes}
index, low, stack, on, sccs, counter = {}, {}, [], set(), [], [0]
def strong(v):
    index[v] = low[v] = counter[0]; counter[0] += 1
    stack.append(v); on.add(v)
    for w in adj.get(v, []):
        if w not in index:
            strong(w); low[v] = min(low[v], low[w])
        elif w in on:
            low[v] = min(low[v], index[w])
    if low[v] == index[v]:
        comp = []
        while True:
            w = stack.pop(); on.discard(w); comp.append(w)
            if w == v:
                break
        sccs.append(comp)
sys.setrecursionlimit(10000)
for n in nodes:
    if n not in index:
        strong(n)
if show_edges:
    for a, b in sorted(edges):
        print(f'{a} -> {b}')
cycles = [c for c in sccs if len(c) > 1]
print(f'{len(nodes)} modules, {len(edges)} edges, {len(cycles)} cycles')
for c in cycles:
    print('CYCLE:', ' <-> '.join(sorted(c)))
sys.exit(1 if cycles else 0)
