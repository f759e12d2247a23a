#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Fails on a dependency cycle among the library's source files.

Two graphs over the modules of src/ (a module is NAME.c with NAME.h, if any):
- includes: A -> B when A.c or A.h includes "B.h" (a header without a .c of
  its own, such as internal.h, is a module of its own);
- symbols: A -> B when A.o uses a global symbol that B.o defines (from nm).
Every strongly connected component with more than one module is a cycle and
is printed with the edges that close it. Usage:
  check-cycles.py SRC_DIR OBJECT_DIR     (exit 1 when a cycle is found)
"""
import os
import re
import subprocess
import sys
from collections import defaultdict


def modules_and_includes(src):
    includes = defaultdict(set)
    files = []
    for root, _, names in os.walk(src):
        for name in names:
            if name.endswith(('.c', '.h')):
                files.append(os.path.join(root, name))
    module_of = {}
    for path in files:
        rel = os.path.relpath(path, src)
        module_of[rel] = os.path.splitext(rel)[0]
    for path in files:
        rel = os.path.relpath(path, src)
        me = module_of[rel]
        with open(path, encoding='utf-8', errors='replace') as f:
            for line in f:
                m = re.match(r'\s*#\s*include\s+"([^"]+)"', line)
                if not m:
                    continue
                target = os.path.normpath(os.path.join(os.path.dirname(rel), m.group(1)))
                if target not in module_of:
                    target = os.path.normpath(m.group(1))
                if target in module_of and module_of[target] != me:
                    includes[me].add(module_of[target])
    return set(module_of.values()), includes


def symbol_graph(objects, src):
    defined, used = {}, defaultdict(set)
    module_of_path = {}
    for root, _, names in os.walk(objects):
        for name in names:
            if not name.endswith('.c.o'):
                continue
            path = os.path.join(root, name)
            rel = os.path.relpath(path, objects)
            # CMake puts src/x.c's object at .../src/x.c.o
            m = re.search(r'(?:^|/)src/(.+)\.c\.o$', rel)
            if m:
                module_of_path[path] = m.group(1)
    # One nm for every object (each start of nm costs about 0.1 s): with
    # --print-file-name every line is "PATH:[VALUE] TYPE SYMBOL".
    paths = sorted(module_of_path)
    out = subprocess.run(['nm', '--print-file-name'] + paths, capture_output=True, text=True,
                         check=True).stdout if paths else ''
    for line in out.splitlines():
        path, _, rest = line.partition(':')
        module = module_of_path.get(path)
        if module is None:
            continue
        parts = rest.split()
        if len(parts) == 3 and parts[1] in 'TDBR':
            defined[parts[2]] = module
        elif len(parts) == 2 and parts[0] == 'U':
            used[module].add(parts[1])
    edges = defaultdict(set)
    for module, symbols in used.items():
        for symbol in symbols:
            owner = defined.get(symbol)
            if owner and owner != module:
                edges[module].add(owner)
    return edges


def cycles(nodes, edges):
    index, low, stack, on, result, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                result.append(sorted(component))

    sys.setrecursionlimit(10000)
    for v in sorted(nodes | set(edges)):
        if v not in index:
            visit(v)
    return result


def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    src, objects = sys.argv[1], sys.argv[2]
    nodes, includes = modules_and_includes(src)
    symbols = symbol_graph(objects, src)
    found = 0
    for kind, edges in (('include', includes), ('symbol', symbols)):
        for component in cycles(nodes, edges):
            found += 1
            inside = set(component)
            links = ', '.join(f'{a} -> {b}' for a in component for b in sorted(edges.get(a, ())) if b in inside)
            print(f'{kind} cycle among {", ".join(component)}: {links}')
    counted = len(nodes)
    if found:
        print(f'check-cycles: {found} cycle(s) among {counted} modules')
        return 1
    print(f'check-cycles: no include or symbol cycle among {counted} modules')
    return 0


if __name__ == '__main__':
    sys.exit(main())
