#!/usr/bin/env python3
"""Reports dependency cycles among sibling modules of every crate under crates/*/src.

For each crate the module tree is built from the file layout and the `mod` declarations
(`mod x;` → `x.rs` or `x/mod.rs`, honouring `#[path = "…"]`; inline `mod x { … }` blocks
are modules too). For every module M, its direct children are the nodes of a graph with an
edge A → B when some file in A's subtree refers to something in B's subtree, through
`crate::…` paths, `super::…` chains, `self::…` paths or `use` declarations (use trees are
expanded; imports and re-exports such as `pub use b::Thing` in M are followed, so that
`super::Thing` counts as a reference to `b`). The crate root is such an M, so cycles among
the top-level modules are found too.

A reference from a module to one of its ancestors (a child using `super::Config` defined in
its parent) or to one of its own descendants is not a sibling edge. Comments, doc comments
and string literals are ignored: an intra-doc link is no dependency of the code.

Every strongly connected component of two or more siblings is printed with the references
that make its edges. Exit status 1 when there is any cycle, 0 otherwise.

Usage: scripts/check_module_cycles.py [WORKSPACE_ROOT]   (default: the parent of scripts/)
Python 3 standard library only.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
MAX_REFS_SHOWN = 6


# --------------------------------------------------------------------------------------
# Lexing: blank out comments and literals, keeping offsets and line numbers.


def strip_code(text: str) -> str:
    """The text with comments, string/char literals replaced by spaces (newlines kept)."""
    out = list(text)
    n = len(text)
    i = 0

    def blank(a: int, b: int) -> None:
        for k in range(a, min(b, n)):
            if out[k] != "\n":
                out[k] = " "

    while i < n:
        c = text[i]
        if c == "/" and i + 1 < n and text[i + 1] == "/":
            j = text.find("\n", i)
            j = n if j < 0 else j
            blank(i, j)
            i = j
        elif c == "/" and i + 1 < n and text[i + 1] == "*":
            depth = 1
            j = i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth += 1
                    j += 2
                elif text.startswith("*/", j):
                    depth -= 1
                    j += 2
                else:
                    j += 1
            blank(i, j)
            i = j
        elif c in "rb" and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")):
            m = re.compile(r'(?:br|rb|r|b)?(#*)"').match(text, i)
            if m and (m.group(0).startswith("r") or m.group(0).startswith("br")):
                hashes = m.group(1)
                end = text.find('"' + hashes, m.end())
                end = n if end < 0 else end + 1 + len(hashes)
                blank(i, end)
                i = end
            elif text.startswith('b"', i):
                i = skip_string(text, i + 1, blank)
            elif text.startswith("b'", i):
                m2 = re.compile(r"b'(\\.[^']*|[^\\'])'").match(text, i)
                if m2:
                    blank(i, m2.end())
                    i = m2.end()
                else:
                    i += 1
            else:
                i += 1
        elif c == '"':
            i = skip_string(text, i, blank)
        elif c == "'":
            m = re.compile(r"'(\\u\{[0-9a-fA-F]+\}|\\.|[^\\'\n])'").match(text, i)
            if m:
                blank(i, m.end())
                i = m.end()
            else:
                i += 1  # a lifetime
        else:
            i += 1
    return "".join(out)


def skip_string(text: str, i: int, blank) -> int:
    """Blanks the normal string literal starting at the quote `i`; returns its end."""
    j = i + 1
    n = len(text)
    while j < n:
        if text[j] == "\\":
            j += 2
        elif text[j] == '"':
            j += 1
            break
        else:
            j += 1
    blank(i, j)
    return j


# --------------------------------------------------------------------------------------
# Module tree.


@dataclass
class Module:
    path: tuple[str, ...]
    file: Path
    children: dict[str, "Module"] = field(default_factory=dict)
    # name → (module the `use` was written in, raw components) for module-level imports.
    imports: dict[str, tuple["Module", tuple[str, ...]]] = field(default_factory=dict)
    globs: list[tuple["Module", tuple[str, ...]]] = field(default_factory=list)
    parent: "Module | None" = None

    def name(self) -> str:
        return "::".join(self.path) or "crate"


@dataclass
class Reference:
    source: Module
    file: Path
    line: int
    text: str
    base: Module  # module the path is relative to
    comps: tuple[str, ...]  # components after crate/super/self resolution


@dataclass
class ParsedFile:
    refs: list[Reference]


MOD_RE = re.compile(
    r"(?P<attrs>(?:#\s*\[[^\]]*\]\s*)*)"
    r"(?:pub\s*(?:\([^)]*\))?\s*)?mod\s+(?P<name>" + IDENT + r")\s*(?P<end>[;{])"
)
USE_RE = re.compile(r"(?<![A-Za-z0-9_#])use\s+([^;]*);")
PATH_RE = re.compile(
    r"(?<![A-Za-z0-9_:])(?P<head>\$crate|crate|super|self)"
    r"(?P<rest>(?:\s*::\s*(?:" + IDENT + r"))+)"
)
PUB_IN_RE = re.compile(r"pub\s*\(\s*in\s+[^)]*\)")
PATH_ATTR_RE = re.compile(r'#\s*\[\s*path\s*=\s*"([^"]+)"\s*\]')


class Crate:
    def __init__(self, src: Path, root_file: Path):
        self.src = src
        self.root = Module((), root_file)
        self.refs: list[Reference] = []
        self.modules: list[Module] = []
        self._load(self.root, root_file, is_dir_owner=True)

    # A file `dir/x.rs` owns the folder `dir/x/` for its children; `mod.rs`, `lib.rs`,
    # `main.rs` own their own folder.
    def _child_dir(self, file: Path, is_dir_owner: bool) -> Path:
        return file.parent if is_dir_owner else file.parent / file.stem

    def _load(self, module: Module, file: Path, is_dir_owner: bool) -> None:
        self.modules.append(module)
        raw = file.read_text(encoding="utf-8")
        code = strip_code(raw)
        code = PUB_IN_RE.sub(lambda m: " " * len(m.group(0)), code)
        line_starts = [0]
        for k, ch in enumerate(code):
            if ch == "\n":
                line_starts.append(k + 1)

        def line_of(pos: int) -> int:
            lo, hi = 0, len(line_starts) - 1
            while lo < hi:
                mid = (lo + hi + 1) // 2
                if line_starts[mid] <= pos:
                    lo = mid
                else:
                    hi = mid - 1
            return lo + 1

        def line_text(pos: int) -> str:
            ln = line_of(pos)
            return raw.splitlines()[ln - 1].strip() if raw.splitlines() else ""

        # Scope stack of (module, brace depth inside it, folder for its `mod x;` children).
        base_dir = self._child_dir(file, is_dir_owner)
        events: list[tuple[int, str, re.Match | None]] = []
        for m in MOD_RE.finditer(code):
            events.append((m.start("name"), "mod", m))
        for m in USE_RE.finditer(code):
            events.append((m.start(), "use", m))
        for m in PATH_RE.finditer(code):
            events.append((m.start(), "path", m))
        for k, ch in enumerate(code):
            if ch in "{}":
                events.append((k, ch, None))
        # Braces sort after a `mod x {` match at the same offset is impossible (different
        # offsets); order by position, `mod` before the brace it opens.
        events.sort(key=lambda e: (e[0], 0 if e[1] == "mod" else 1))

        stack: list[tuple[Module, int, Path]] = [(module, 0, base_dir)]
        depth = 0
        pending_inline: list[tuple[Module, Path]] = []
        use_spans: list[tuple[int, int]] = []
        for pos, kind, m in events:
            cur, cur_depth, cur_dir = stack[-1]
            if kind == "{":
                depth += 1
                if pending_inline:
                    child, cdir = pending_inline.pop()
                    stack.append((child, depth, cdir))
            elif kind == "}":
                if len(stack) > 1 and stack[-1][1] == depth:
                    stack.pop()
                depth -= 1
            elif kind == "mod":
                assert m is not None
                name = m.group("name")
                path_attr = PATH_ATTR_RE.search(raw[m.start() : m.start("name")])
                if m.group("end") == "{":
                    child = Module(cur.path + (name,), file, parent=cur)
                    cur.children[name] = child
                    self.modules.append(child)
                    pending_inline.append((child, cur_dir / name))
                else:
                    if path_attr:
                        target = (file.parent / path_attr.group(1)).resolve()
                        owner = target.name == "mod.rs"
                    else:
                        cand = [cur_dir / f"{name}.rs", cur_dir / name / "mod.rs"]
                        found = [c for c in cand if c.is_file()]
                        if not found:
                            print(
                                f"warning: {file}:{line_of(pos)}: no file for `mod {name};`",
                                file=sys.stderr,
                            )
                            continue
                        target = found[0]
                        owner = target.name == "mod.rs"
                    child = Module(cur.path + (name,), target, parent=cur)
                    cur.children[name] = child
                    self._load(child, target, owner)
            elif kind == "use":
                assert m is not None
                use_spans.append((m.start(), m.end()))
                module_level = depth == cur_depth
                for comps, alias, is_glob in expand_use(m.group(1)):
                    if not comps:
                        continue
                    ref = self._make_ref(cur, file, line_of(pos), line_text(pos), comps)
                    if ref is not None:
                        self.refs.append(ref)
                    if module_level:
                        if is_glob:
                            cur.globs.append((cur, comps))
                        elif alias and alias != "_":
                            cur.imports[alias] = (cur, comps)
            elif kind == "path":
                assert m is not None
                if any(a <= pos < b for a, b in use_spans):
                    continue
                comps = (m.group("head"),) + tuple(
                    c.strip() for c in m.group("rest").split("::") if c.strip()
                )
                ref = self._make_ref(cur, file, line_of(pos), line_text(pos), comps)
                if ref is not None:
                    self.refs.append(ref)

    def _make_ref(self, cur: Module, file: Path, line: int, text: str, comps):
        """A reference for `comps` written in module `cur`, or None for non-local paths."""
        head = comps[0]
        if head in ("crate", "$crate"):
            return Reference(cur, file, line, text, self.root, tuple(comps[1:]))
        if head in ("super", "self"):
            base = cur
            k = 0
            while k < len(comps) and comps[k] in ("super", "self"):
                if comps[k] == "super":
                    if base.parent is None:
                        return None
                    base = base.parent
                k += 1
            return Reference(cur, file, line, text, base, tuple(comps[k:]))
        # A bare path: relative to `cur` (its child modules or its imports); anything else
        # (std, another crate) is not ours.
        if head in cur.children or head in cur.imports:
            return Reference(cur, file, line, text, cur, tuple(comps))
        return None

    def resolve(self, base: Module, comps: tuple[str, ...], seen=None) -> Module | None:
        """The deepest module of this crate that `comps`, read from `base`, names."""
        if seen is None:
            seen = set()
        mod = base
        for k, c in enumerate(comps):
            if c in mod.children:
                mod = mod.children[c]
                continue
            key = (mod.path, c)
            if c in mod.imports and key not in seen:
                seen.add(key)
                imp_mod, imp_comps = mod.imports[c]
                target = self._import_target(imp_mod, imp_comps, seen)
                if target is None:
                    return mod if mod is not base or k else None
                tbase, tcomps = target
                return self.resolve(tbase, tcomps + tuple(comps[k + 1 :]), seen)
            for imp_mod, imp_comps in mod.globs:
                key = (mod.path, "*", imp_comps)
                if key in seen:
                    continue
                seen.add(key)
                target = self._import_target(imp_mod, imp_comps, seen)
                if target is None:
                    continue
                tbase, tcomps = target
                glob_mod = self.resolve(tbase, tcomps, seen)
                if glob_mod is not None and (
                    c in glob_mod.children or c in glob_mod.imports
                ):
                    return self.resolve(glob_mod, tuple(comps[k:]), seen)
            return mod
        return mod

    def _import_target(self, mod: Module, comps: tuple[str, ...], seen):
        head = comps[0]
        if head in ("crate", "$crate"):
            return self.root, tuple(comps[1:])
        if head in ("super", "self"):
            base = mod
            k = 0
            while k < len(comps) and comps[k] in ("super", "self"):
                if comps[k] == "super":
                    if base.parent is None:
                        return None
                    base = base.parent
                k += 1
            return base, tuple(comps[k:])
        if head in mod.children or head in mod.imports:
            return mod, tuple(comps)
        return None


def expand_use(tree: str) -> list[tuple[tuple[str, ...], str | None, bool]]:
    """Expands a use tree into (components, bound name, is glob) triples."""
    tree = re.sub(r"\s+", " ", tree).strip()
    tree = re.sub(r"^::\s*", "", tree)
    results: list[tuple[tuple[str, ...], str | None, bool]] = []

    def split_top(s: str) -> list[str]:
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
        if cur.strip():
            parts.append(cur)
        return parts

    def go(prefix: tuple[str, ...], s: str) -> None:
        s = s.strip()
        if not s:
            return
        if s.startswith("{") and s.endswith("}"):
            for part in split_top(s[1:-1]):
                go(prefix, part)
            return
        brace = s.find("{")
        if brace >= 0:
            head = s[:brace].strip().rstrip(":").strip()
            comps = tuple(c.strip() for c in head.split("::") if c.strip())
            go(prefix + comps, s[brace:])
            return
        alias = None
        m = re.match(r"(.*?)\s+as\s+(" + IDENT + r")$", s)
        if m:
            s, alias = m.group(1), m.group(2)
        comps = tuple(c.strip() for c in s.split("::") if c.strip())
        if comps and comps[-1] == "*":
            results.append((prefix + comps[:-1], None, True))
            return
        if comps and comps[-1] == "self":
            full = prefix + comps[:-1]
            results.append((full, alias or (full[-1] if full else None), False))
            return
        full = prefix + comps
        results.append((full, alias or (full[-1] if full else None), False))

    go((), tree)
    return results


# --------------------------------------------------------------------------------------
# Cycles.


def tarjan(nodes: list[str], edges: dict[str, set[str]]) -> list[list[str]]:
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = [0]

    def strong(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                strong(w)
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

    sys.setrecursionlimit(10000)
    for v in nodes:
        if v not in index:
            strong(v)
    return out


def check_crate(src: Path, root_file: Path, workspace: Path) -> list[str]:
    crate = Crate(src, root_file)
    # edges[parent path][(a, b)] = references
    edges: dict[tuple[str, ...], dict[tuple[str, str], list[Reference]]] = {}
    for ref in crate.refs:
        target = crate.resolve(ref.base, ref.comps)
        if target is None:
            continue
        s, t = ref.source.path, target.path
        k = 0
        while k < len(s) and k < len(t) and s[k] == t[k]:
            k += 1
        if k == len(s) or k == len(t):
            continue  # ancestor or descendant: no sibling edge
        edges.setdefault(s[:k], {}).setdefault((s[k], t[k]), []).append(ref)

    report: list[str] = []
    by_path = {m.path: m for m in crate.modules}
    for parent_path in sorted(edges):
        parent = by_path[parent_path]
        graph: dict[str, set[str]] = {}
        for a, b in edges[parent_path]:
            graph.setdefault(a, set()).add(b)
        for comp in tarjan(sorted(parent.children), graph):
            if len(comp) < 2:
                continue
            where = parent.name()
            report.append(
                f"cycle among the children of `{where}` ({rel(parent.file, workspace)}): "
                + ", ".join(comp)
            )
            members = set(comp)
            for (a, b), refs in sorted(edges[parent_path].items()):
                if a in members and b in members:
                    lines = sorted(
                        {(rel(r.file, workspace), r.line, r.text) for r in refs}
                    )
                    report.append(f"  {a} -> {b}: {len(lines)} line(s)")
                    for f, ln, text in lines[:MAX_REFS_SHOWN]:
                        report.append(f"    {f}:{ln}: {text}")
                    if len(lines) > MAX_REFS_SHOWN:
                        report.append(f"    … and {len(lines) - MAX_REFS_SHOWN} more")
    return report, len(crate.modules)


def rel(p: Path, base: Path) -> str:
    try:
        return str(p.resolve().relative_to(base.resolve()))
    except ValueError:
        return str(p)


def main() -> int:
    workspace = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent
    crates = sorted(p for p in (workspace / "crates").glob("*/src") if p.is_dir())
    if not crates:
        print(f"no crates/*/src under {workspace}", file=sys.stderr)
        return 2
    any_cycle = False
    for src in crates:
        for root_name in ("lib.rs", "main.rs"):
            root = src / root_name
            if not root.is_file():
                continue
            label = f"{src.parent.name} ({root_name})"
            report, n_modules = check_crate(src, root, workspace)
            if report:
                any_cycle = True
                print(f"{label}: {n_modules} modules, CYCLES:")
                for line in report:
                    print("  " + line)
            else:
                print(f"{label}: {n_modules} modules, no cycle among siblings")
    return 1 if any_cycle else 0


if __name__ == "__main__":
    sys.exit(main())
