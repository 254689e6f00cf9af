#!/usr/bin/env python3
"""The file-level import graph of `src/`: cycles and imports that go up the stages.

Usage: scripts/check-imports.py [--src DIR] [--graph]

Builds one node per source file of the library (`src/lib.rs`) and of the binary
(`src/bin/trayecto/main.rs`), and an edge A -> B whenever A names an item that B defines:
`use crate::…`, `use super::…`, `use self::…`, paths such as `crate::a::b::f(…)` in code, paths
through a name a `use` brought in (`use crate::sampling::warp; warp::f(…)`), and, in the binary,
`trayecto::…` (the library). A path resolves to the file of the deepest module it names; an item a
module re-exports (`pub use child::Item`) resolves to the file that defines it.

What is not an edge: a module naming its own submodules (`mod x;`, `pub use x::Item`, `x::f(…)`
inside the module that declares `x`): a module owns its rooms, and only the way back up is an
import. A file's inline modules (`mod tests { … }`) belong to the file.

Reports every cycle (a strongly connected component of more than one file) and every import from
a lower stage to a higher one (the LAYERS table below, docs/DESIGN.md §1), and exits 1 if it found
either. Standard library only; output is sorted, so two runs print the same thing.
"""

import argparse
import bisect
import os
import re
import sys

# Stages from the bottom up (docs/DESIGN.md §1). A module may import from its own stage and every
# stage below it, never from one above. The key is the module path under the crate root (the
# longest name that matches wins: `material::texture` before `material`); "bin" is the binary.
LAYERS = [
    # 0: foundations (and the crate root, which holds only declarations and RENDER_IDENTITY)
    ("", 0),
    ("math", 0),
    ("phases", 0),
    # the memory budget and cancel flag a load charges (read by every decoder and the front ends)
    ("limits", 0),
    # 1: random numbers and shapes
    ("sampling", 1),
    ("geometry", 1),
    # 2: what scene descriptions are made of: images, spectra, materials and textures, and the
    # film (pixel filters, AOV layers and image writers are named by scenes and integrators)
    ("image_io", 2),
    ("spectrum", 2),
    ("material", 2),
    ("film", 2),
    ("denoise", 2),
    # 3: scene descriptions and their loaders (plain data in the file's terms)
    ("scene", 3),
    # 4: what the world is compiled from a scene into
    ("accel", 4),
    ("medium", 4),
    ("light", 4),
    ("camera", 4),
    # 5: the compiled world and its queries
    ("world", 5),
    # 6: where each path's fate is decided
    ("integrator", 6),
    # 7: the driver: passes, tiles, accumulation
    ("render", 7),
    # 8: sample ranges and partial films of the split pipeline
    ("split", 8),
    # 9: load -> build -> render -> write
    ("pipeline", 9),
    # 10: the front ends: the binary, and the web server's request and upload checks that the
    # library keeps for the fuzz targets
    ("server", 10),
    ("bin", 10),
]

# Cycles accepted, each with its reason (docs/DESIGN.md §1 says why): a cycle is reported unless
# its files are exactly one of these sets.
ALLOWED_CYCLES = [
    # One recursive type in two files: a `Texture` may be a pbrt-v4 procedural graph
    # (`Texture::procedural`) whose leaves are image textures (`Procedural::eval(textures, …)`).
    {"src/material/procedural.rs", "src/material/texture.rs"},
]

LIB_ROOT = "lib.rs"
BIN_ROOT = os.path.join("bin", "trayecto", "main.rs")
LIB_CRATE = "trayecto"  # how the binary names the library


TOKEN = re.compile(
    r"//[^\n]*"  # line comment
    r"|/\*"  # block comment (nested: scanned below)
    r"|(?<![A-Za-z0-9_])b?r(#*)\""  # raw string opening
    r"|(?<![A-Za-z0-9_])b?\"(?:[^\"\\]|\\.)*\""  # string
    r"|b?'(?:\\u\{[0-9a-fA-F]+\}|\\.|[^\\'\n])'",  # char literal (not a lifetime)
    re.S,
)
BLOCK = re.compile(r"/\*|\*/")
NOT_NEWLINE = re.compile(r"[^\n]")


def strip_code(text):
    """The text with comments, string and char literals blanked (offsets and newlines kept)."""
    out, pos, n = [], 0, len(text)
    while True:
        m = TOKEN.search(text, pos)
        if m is None:
            out.append(text[pos:])
            return "".join(out)
        out.append(text[pos:m.start()])
        tok = m.group(0)
        end = m.end()
        if tok == "/*":
            depth = 1
            for b in BLOCK.finditer(text, end):
                depth += 1 if b.group(0) == "/*" else -1
                if depth == 0:
                    end = b.end()
                    break
            else:
                end = n
        elif m.group(1) is not None:
            close = text.find('"' + m.group(1), end)
            end = n if close < 0 else close + 1 + len(m.group(1))
        out.append(NOT_NEWLINE.sub(" ", text[m.start():end]))
        pos = end


IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
MOD_DECL = re.compile(r"\b(?:pub(?:\s*\([^)]*\))?\s+)?mod\s+(" + IDENT + r")\s*([;{])")
PATH_ATTR = re.compile(r'#\[path\s*=')
USE_STMT = re.compile(r"\b(pub(?:\s*\([^)]*\))?\s+)?use\s+([^;]*);")
CODE_PATH = re.compile(r"(?<![A-Za-z0-9_:])(" + IDENT + r"(?:\s*::\s*" + IDENT + r")+)")


def expand_use_tree(tree):
    """`a::{b,c::{d as e,self},f::*}` (spaces squeezed but around `as`) ->
    [(["a","b"], "b"), (["a","c","d"], "e"), (["a","c"], "c"), (["a","f","*"], "*")]."""
    results = []

    def split_top(s):
        parts, depth, cur = [], 0, ""
        for ch in s:
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
            if ch == "," and depth == 0:
                parts.append(cur)
                cur = ""
            else:
                cur += ch
        if cur:
            parts.append(cur)
        return parts

    def walk(prefix, s):
        if not s:
            return
        brace = s.find("{")
        if brace >= 0 and s.endswith("}"):
            head = s[:brace].rstrip(":")
            segs = prefix + ([x for x in head.split("::") if x] if head else [])
            for part in split_top(s[brace + 1:-1]):
                walk(segs, part)
            return
        alias = None
        if " as " in s:
            s, alias = s.split(" as ")
        segs = prefix + [x for x in s.split("::") if x]
        if segs and segs[-1] == "self":
            segs = segs[:-1]
        if not segs:
            return
        results.append((segs, alias or segs[-1]))

    walk([], tree)
    return results


class Module:
    def __init__(self, path, file, crate):
        self.path = path  # tuple of segments under the crate root
        self.file = file  # the file that defines it (inline modules: their file)
        self.crate = crate
        self.children = {}  # name -> Module
        self.uses = []  # (segments, bound name, is_pub, line)
        self.reexports = {}  # name -> segments (resolved lazily)
        self.glob_reexports = []  # segments of `pub use x::*`


def parse_use(text):
    """use statements of stripped text: [(segments, alias, is_pub, offset)]."""
    out = []
    for m in USE_STMT.finditer(text):
        body = re.sub(r"\s+as\s+", " as ", m.group(2).strip())
        body = re.sub(r"\s+(?!as )", "", body.replace(" as ", "\x00")).replace("\x00", " as ")
        for segs, alias in expand_use_tree(body):
            out.append((segs, alias, bool(m.group(1)), m.start()))
    return out


class Crate:
    def __init__(self, name, src, root_rel):
        self.name = name
        self.src = src
        self.modules = {}  # path tuple -> Module
        self.files = {}  # file rel path -> stripped text
        self.scopes = []  # (file, module, start, end) of inline modules for `super` resolution
        self.test_regions = []  # (file, start, end) of `#[cfg(test)]` inline modules
        self.root = self.load_module((), root_rel, is_dir_owner=True)

    def load_module(self, path, rel, is_dir_owner):
        full = os.path.join(self.src, rel)
        with open(full, encoding="utf-8") as f:
            text = strip_code(f.read())
        self.files[rel] = text
        mod = Module(path, rel, self)
        self.modules[path] = mod
        # the folder a `mod x;` of this file looks in
        if is_dir_owner:
            base = os.path.dirname(rel)
        else:
            base = os.path.splitext(rel)[0]
        self.scan_items(mod, text, 0, len(text), base, path)
        return mod

    def scan_items(self, mod, text, start, end, base, path):
        """Record `mod` declarations (files and inline bodies) and `use` statements."""
        regions = []  # inline module bodies: (name, body_start, body_end)
        for m in MOD_DECL.finditer(text, start, end):
            if any(s <= m.start() < e for _, s, e in regions):
                continue
            name = m.group(1)
            if m.group(2) == ";":
                cand = [os.path.join(base, name + ".rs"), os.path.join(base, name, "mod.rs")]
                rel = next((c for c in cand if os.path.exists(os.path.join(self.src, c))), None)
                if rel is None:
                    continue
                child = self.load_module(path + (name,), rel, rel.endswith("mod.rs"))
                mod.children[name] = child
            else:
                body_start = m.end()
                is_test = re.search(r"#\[cfg\(test\)\]\s*(?:#\[[^\]]*\]\s*)*$", text[max(0, m.start() - 200):m.start()])
                depth, j = 1, body_start
                while j < end and depth:
                    if text[j] == "{":
                        depth += 1
                    elif text[j] == "}":
                        depth -= 1
                    j += 1
                regions.append((name, body_start, j - 1))
                if is_test:
                    # test-only code may reach anywhere for its fixtures; not part of the build
                    self.test_regions.append((mod.file, m.start(), j))
                    continue
                inner = Module(path + (name,), mod.file, self)
                self.modules[inner.path] = inner
                mod.children[name] = inner
                self.scopes.append((mod.file, inner, body_start, j - 1))
                self.scan_items(inner, text, body_start, j - 1, os.path.join(base, name), inner.path)
        for segs, alias, is_pub, off in parse_use(text[start:end]):
            off += start
            if any(s <= off < e for _, s, e in regions):
                continue
            mod.uses.append((segs, alias, is_pub, off))

    def module_at(self, file, offset):
        """The innermost module whose code `offset` of `file` is in."""
        best = None
        for f, m, s, e in self.scopes:
            if f == file and s <= offset < e and (best is None or len(m.path) > len(best.path)):
                best = m
        if best is not None:
            return best
        return next(m for m in self.modules.values() if m.file == file and not self.is_inline(m))

    def is_inline(self, m):
        return any(sm is m for _, sm, _, _ in self.scopes)


class Graph:
    def __init__(self, src):
        self.src = src
        self.lib = Crate("lib", src, LIB_ROOT)
        self.bin = Crate("bin", src, BIN_ROOT) if os.path.exists(os.path.join(src, BIN_ROOT)) else None
        self.crates = [c for c in (self.lib, self.bin) if c]
        self.edges = {}  # (from file, to file) -> first line number
        self.build()

    def absolute(self, crate, mod, segs, bindings):
        """Segments of a path written in `mod` -> (crate, absolute segments) or None."""
        if not segs:
            return None
        head = segs[0]
        if head == "crate":
            return crate, list(segs[1:])
        if head == LIB_CRATE and crate is self.bin:
            return self.lib, list(segs[1:])
        if head == "self":
            return crate, list(mod.path) + list(segs[1:])
        if head == "super":
            path = list(mod.path)
            rest = list(segs)
            while rest and rest[0] == "super":
                path = path[:-1]
                rest = rest[1:]
            return crate, path + rest
        if head in mod.children:
            return crate, list(mod.path) + list(segs)
        if head in bindings:
            c, base = bindings[head]
            return c, base + list(segs[1:])
        return None

    def bindings_of(self, crate, mod):
        """Names brought in by `use` in `mod`, resolved to absolute paths (one pass)."""
        b = {}
        for segs, alias, _, _ in mod.uses:
            if alias == "_" or alias == "*":
                continue
            r = self.absolute(crate, mod, segs, b)
            if r is not None:
                b[alias] = r
        return b

    def resolve(self, crate, segs, depth=0):
        """Absolute segments -> the file defining the item (following re-exports)."""
        node = crate.modules[()]
        i = 0
        while i < len(segs) and segs[i] in node.children:
            node = node.children[segs[i]]
            i += 1
        if i < len(segs) and depth < 16:
            name = segs[i]
            bindings = self.bindings_cache[(crate.name, node.path)]
            for usegs, alias, is_pub, _ in node.uses:
                if is_pub and alias == name:
                    r = bindings.get(name)
                    if r is not None:
                        return self.resolve(r[0], r[1] + segs[i + 1:], depth + 1)
            for usegs, alias, is_pub, _ in node.uses:
                if is_pub and alias == "*":
                    r = self.absolute(crate, node, usegs[:-1], bindings)
                    if r is not None:
                        target = self.resolve(r[0], r[1] + [name], depth + 1)
                        tnode = self.deepest(r[0], r[1])
                        if target != (r[0], tnode.file) or name in tnode.children:
                            return target
        return crate, node.file

    def deepest(self, crate, segs):
        node = crate.modules[()]
        for s in segs:
            if s not in node.children:
                break
            node = node.children[s]
        return node

    def owns(self, crate, mod, target_crate, target_file):
        """Whether `target_file` is `mod`'s own file or the file of one of its submodules."""
        if target_crate is not crate:
            return False
        for m in crate.modules.values():
            if m.file == target_file and tuple(m.path[: len(mod.path)]) == tuple(mod.path):
                return True
        return False

    def node_name(self, crate, file):
        return os.path.join("src", file)

    def build(self):
        self.bindings_cache = {}
        for c in self.crates:
            for path, mod in c.modules.items():
                self.bindings_cache[(c.name, path)] = self.bindings_of(c, mod)
        for c in self.crates:
            for file, text in c.files.items():
                lines = [0] + [k.end() for k in re.finditer("\n", text)]

                def line_of(off, lines=lines):
                    return bisect.bisect_right(lines, off)

                refs = []
                # use statements
                for mod in [m for m in c.modules.values() if m.file == file]:
                    b = self.bindings_cache[(c.name, mod.path)]
                    for segs, alias, is_pub, off in mod.uses:
                        if segs[-1] == "*":
                            segs = segs[:-1]
                        r = self.absolute(c, mod, segs, {})
                        if r is None:
                            r = self.absolute(c, mod, segs, b)
                        if r is not None:
                            refs.append((mod, r, off))
                # paths in code
                tests = [(s0, e0) for f0, s0, e0 in c.test_regions if f0 == file]
                for m in CODE_PATH.finditer(text):
                    if any(s0 <= m.start() < e0 for s0, e0 in tests):
                        continue
                    segs = [s.strip() for s in m.group(1).split("::")]
                    mod = c.module_at(file, m.start())
                    if text[max(0, m.start() - 40):m.start()].rstrip().endswith(("use", "{", ",")):
                        # inside a use tree: already handled above
                        pre = text[max(0, m.start() - 400):m.start()]
                        if re.search(r"\buse\s[^;]*$", pre):
                            continue
                    b = self.bindings_cache[(c.name, mod.path)]
                    r = self.absolute(c, mod, segs, b)
                    if r is not None:
                        refs.append((mod, r, m.start()))
                for mod, (tc, tsegs), off in refs:
                    tcrate, tfile = self.resolve(tc, tsegs)
                    if tcrate is c and tfile == file:
                        continue
                    if self.owns(c, self.file_module(c, file), tcrate, tfile):
                        continue
                    key = (self.node_name(c, file), self.node_name(tcrate, tfile))
                    ln = line_of(off)
                    if key not in self.edges or ln < self.edges[key]:
                        self.edges[key] = ln

    def file_module(self, crate, file):
        return next(m for m in crate.modules.values() if m.file == file and not crate.is_inline(m))

    def layer_of(self, node):
        rel = os.path.relpath(node, "src")
        if rel.startswith(os.path.join("bin", "")):
            return "bin", dict(LAYERS)["bin"]
        mod = self.file_module(self.lib, rel)
        key = "::".join(mod.path)
        best = None
        for name, rank in LAYERS:
            if key == name or (name and key.startswith(name + "::")):
                if best is None or len(name) > len(best[0]):
                    best = (name, rank)
        return best if best else (key, None)


def tarjan(nodes, succ):
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]
    sys.setrecursionlimit(10000)

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in succ.get(v, ()):
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
            out.append(sorted(comp))

    for v in sorted(nodes):
        if v not in index:
            visit(v)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--src", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src"))
    ap.add_argument("--graph", action="store_true", help="print every edge")
    args = ap.parse_args()
    g = Graph(os.path.normpath(args.src))

    succ = {}
    nodes = set()
    for (a, b) in g.edges:
        succ.setdefault(a, []).append(b)
        nodes.update((a, b))
    for v in succ:
        succ[v].sort()
    if args.graph:
        for (a, b), ln in sorted(g.edges.items()):
            print(f"{a}:{ln} -> {b}")

    cycles = sorted(
        c for c in tarjan(nodes, succ) if len(c) > 1 and set(c) not in ALLOWED_CYCLES
    )
    for comp in cycles:
        print(f"cycle ({len(comp)} files):")
        members = set(comp)
        for (a, b), ln in sorted(g.edges.items()):
            if a in members and b in members:
                print(f"  {a}:{ln} -> {b}")

    ups = []
    for (a, b), ln in sorted(g.edges.items()):
        (la, ra), (lb, rb) = g.layer_of(a), g.layer_of(b)
        if ra is None or rb is None:
            ups.append(f"no stage for {la if ra is None else lb}: {a}:{ln} -> {b}")
        elif rb > ra:
            ups.append(f"upward import ({la} {ra} -> {lb} {rb}): {a}:{ln} -> {b}")
    for u in ups:
        print(u)
    print(f"{len(g.edges)} imports between {len(nodes)} files; {len(cycles)} cycles; {len(ups)} upward imports")
    return 1 if cycles or ups else 0


if __name__ == "__main__":
    sys.exit(main())
