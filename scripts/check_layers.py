#!/usr/bin/env python3
"""Layer check for segloc (see ARCHITECTURE.md): which module may import which.

Reads every `src/**/*.rs` of the root crate except the binary (`src/main.rs`, `src/cli/`,
the top layer, which may use anything) and `src/lib.rs` (which only declares the modules),
finds every path that names a top-level module through the crate root -- `use crate::x`,
inline paths such as `crate::graph::VarKey`, each member of `use crate::{a, b::c}`,
`$crate::x` in macros and `super::super::x` chains that climb to the root -- and fails if

  * a module refers to a module of a higher layer, or to one outside the table below;
  * a module with an allow-list (`ALLOWED`) refers to a module not on it;
  * same-layer references form a cycle.

Comments (doc comments included, so intra-doc links such as [`crate::mission`] in prose are
not dependencies), string and character literals are blanked out before the scan. Test
code (`#[cfg(test)] mod tests`, `*_tests.rs`) obeys the same rule: it is compiled into the
crate, and a test that needs a higher layer belongs in `tests/`.

It also checks the workspace crates: `maps/` and `clipper/` never mention `segloc::` and do
not depend on the root crate, and `clipper/src` does no I/O (no `std::fs`, `std::io`,
`std::net`, `std::process`, `std::env`; no dependency on `segloc-maps`).

Exit status 0 when clean, 1 with one line per violation (file:line and the edge).
Python 3 standard library only.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

# The layer table: a module may refer to modules of its own layer (without cycles) and of
# lower layers. Layer 0 holds the two workspace crates (`crate::maps`, `crate::clipper` are
# their re-exports in lib.rs) and the leaf modules of src that import no other module.
# The binary (src/main.rs, src/cli/) sits above layer 5 and is not checked.
LAYERS: list[tuple[str, list[str]]] = [
    ("foundation", ["maps", "clipper", "spatial", "ipex", "font", "memory", "field_error"]),
    ("geometry", ["graph", "align"]),
    ("landmarks and relocalization", ["landmarks", "relocalize"]),
    ("engine users", [
        "localizer", "perception", "planning", "mapping", "merge", "io", "vo", "image_stream",
    ]),
    ("simulation", ["sim"]),
    ("applications", ["mission", "eval"]),
]

# Modules held to a narrower set than their layer allows. The online localizer is fed by
# recorded streams and must stay free of the simulator, the planner and the applications.
ALLOWED: dict[str, set[str]] = {
    "localizer": {
        "maps", "clipper", "graph", "align", "landmarks", "relocalize", "spatial", "ipex",
        "field_error",
    },
}

# Paths of the binary (top layer) and the crate root, relative to src/.
UNCHECKED = {"main.rs", "lib.rs"}
UNCHECKED_DIRS = {"cli"}

# What clipper (pure math) may not touch.
CLIPPER_IO = re.compile(r"\bstd\s*::\s*(fs|io|net|process|env)\b")

IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
PATH_STRING = re.compile(r"\$?crate(?:::" + IDENT + r")+")


def layer_of() -> dict[str, int]:
    table: dict[str, int] = {}
    for index, (_, modules) in enumerate(LAYERS):
        for module in modules:
            assert module not in table, f"{module} listed twice in LAYERS"
            table[module] = index
    return table


def blank(text: str, start: int, end: int, out: list[str]) -> None:
    """Blank out text[start:end] in `out`, keeping newlines so line numbers survive."""
    for i in range(start, end):
        if out[i] != "\n":
            out[i] = " "


def strip_comments_and_literals(text: str) -> str:
    """The source with comments, string literals and char literals replaced by spaces."""
    out = list(text)
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            blank(text, i, j, out)
            i = j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            blank(text, i, j, out)
            i = j
        elif (m := re.compile(r'b?r(#*)"').match(text, i)) and (
            i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")
        ):
            closing = '"' + m.group(1)
            j = text.find(closing, m.end())
            j = n if j < 0 else j + len(closing)
            blank(text, i, j, out)
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            # a string that is a path (`#[serde(with = "crate::x::f")]`) is a reference: keep it
            if not PATH_STRING.fullmatch(text, i + 1, j):
                blank(text, i, j + 1, out)
            i = j + 1
        elif c == "'":
            # a char literal ('a', '\n', '\u{1F600}') or a lifetime / label ('a, 'static)
            if i + 1 < n and text[i + 1] == "\\":
                j = text.find("'", i + 2)
                j = n if j < 0 else j
                blank(text, i, j + 1, out)
                i = j + 1
            elif i + 2 < n and text[i + 2] == "'":
                blank(text, i, i + 3, out)
                i += 3
            else:
                i += 1
        else:
            i += 1
    return "".join(out)


def module_path(rel: Path) -> list[str]:
    """Module path of a file under src/ from its location (mod.rs names its directory)."""
    parts = list(rel.with_suffix("").parts)
    if parts and parts[-1] == "mod":
        parts.pop()
    return parts


PATH_ATTR = re.compile(r'#\s*\[\s*path\s*=\s*"([^"]+)"\s*\]\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(' + IDENT + r")")


def path_attribute_modules(src: Path, files: list[Path]) -> dict[Path, list[str]]:
    """Files loaded by `#[path = "x.rs"] mod name;` and the module path they really have."""
    result: dict[Path, list[str]] = {}
    for file in files:
        text = file.read_text(encoding="utf-8")
        for m in PATH_ATTR.finditer(text):
            target = (file.parent / m.group(1)).resolve()
            result[target] = module_path(file.relative_to(src)) + [m.group(2)]
    return result


INLINE_MOD = re.compile(r"\bmod\s+" + IDENT + r"\s*\{|[{}]")


def inline_mod_depths(code: str) -> list[tuple[int, int]]:
    """(position, number of enclosing inline `mod x { }` blocks from there on)."""
    marks = [(0, 0)]
    stack: list[bool] = []  # one entry per open brace: does it open an inline module?
    depth = 0
    for m in INLINE_MOD.finditer(code):
        token = m.group(0)
        if token == "}":
            if stack and stack.pop():
                depth -= 1
                marks.append((m.end(), depth))
        else:
            is_mod = token != "{"
            stack.append(is_mod)
            if is_mod:
                depth += 1
                marks.append((m.end(), depth))
    return marks


def depth_at(marks: list[tuple[int, int]], pos: int) -> int:
    depth = 0
    for start, d in marks:
        if start > pos:
            break
        depth = d
    return depth


def matching_brace(code: str, open_pos: int) -> int:
    depth = 0
    for j in range(open_pos, len(code)):
        if code[j] == "{":
            depth += 1
        elif code[j] == "}":
            depth -= 1
            if depth == 0:
                return j
    return len(code)


def group_heads(code: str, open_pos: int) -> list[tuple[int, str]]:
    """(position, first segment) of each member of the `{ ... }` group opening at open_pos."""
    close = matching_brace(code, open_pos)
    heads: list[tuple[int, str]] = []
    depth, start = 0, open_pos + 1
    for j in range(open_pos + 1, close + 1):
        ch = code[j]
        if ch == "{":
            depth += 1
        elif ch == "}" and depth > 0:
            depth -= 1
        elif (ch == "," and depth == 0) or j == close:
            member = code[start:j]
            m = re.match(r"\s*(" + IDENT + r"|\*)", member)
            if m:
                heads.append((start + m.start(1), m.group(1)))
            start = j + 1
    return heads


CRATE_PATH = re.compile(r"(?<![A-Za-z0-9_$:])(\$crate|crate)\s*::\s*(" + IDENT + r"|\{|\*)")
SUPER_CHAIN = re.compile(r"(?<![A-Za-z0-9_$:])((?:super\s*::\s*)+)(" + IDENT + r"|\{|\*)")


def references(code: str, own_depth: int) -> list[tuple[int, str, str]]:
    """(position, top-level module, the path as written) for each reference to the root."""
    refs: list[tuple[int, str, str]] = []

    def add(pos: int, head: str, shown: str) -> None:
        if head == "{":
            for member_pos, member in group_heads(code, pos):
                if member != "self":
                    refs.append((member_pos, member, f"{shown}{{{member}, ..}}"))
        elif head not in ("self", "super"):
            rest = re.match(IDENT + r"(?:\s*::\s*" + IDENT + r")*", code[pos:])
            refs.append((pos, head, shown + re.sub(r"\s+", "", rest.group(0) if rest else head)))

    for m in CRATE_PATH.finditer(code):
        add(m.start(2), m.group(2), re.sub(r"\s+", "", code[m.start(1) : m.start(2)]))
    marks = inline_mod_depths(code)
    for m in SUPER_CHAIN.finditer(code):
        supers = m.group(1).count("super")
        if supers >= own_depth + depth_at(marks, m.start()):
            add(m.start(2), m.group(2), re.sub(r"\s+", "", m.group(1)))
    return sorted(refs)


def line_of(code: str, pos: int) -> int:
    return code.count("\n", 0, pos) + 1


def check_src(root: Path, problems: list[str]) -> tuple[int, int, dict]:
    src = root / "src"
    layers = layer_of()
    files = sorted(
        f
        for f in src.rglob("*.rs")
        if str(f.relative_to(src)) not in UNCHECKED
        and f.relative_to(src).parts[0] not in UNCHECKED_DIRS
    )
    path_modules = path_attribute_modules(src, files)
    # same-layer edges: (from, to) -> first place seen
    same_layer: dict[tuple[str, str], str] = {}
    edges = 0
    for file in files:
        rel = file.relative_to(src)
        mod_path = path_modules.get(file.resolve(), module_path(rel))
        here = mod_path[0]
        shown_file = f"src/{rel.as_posix()}"
        if here not in layers:
            problems.append(f"{shown_file}:1: module `{here}` is not in the layer table of scripts/check_layers.py")
            continue
        code = strip_comments_and_literals(file.read_text(encoding="utf-8"))
        for pos, target, written in references(code, len(mod_path)):
            if target == here:
                continue
            edges += 1
            where = f"{shown_file}:{line_of(code, pos)}"
            if target == "*":
                problems.append(f"{where}: {here} -> glob import of the crate root ({written})")
                continue
            if target not in layers:
                problems.append(f"{where}: {here} -> {target}: `{target}` is not in the layer table ({written})")
                continue
            if layers[target] > layers[here]:
                problems.append(
                    f"{where}: {here} (layer {layers[here]}) -> {target} (layer {layers[target]}): "
                    f"a higher layer ({written})"
                )
            elif here in ALLOWED and target not in ALLOWED[here]:
                problems.append(f"{where}: {here} -> {target}: not on {here}'s allow-list ({written})")
            elif layers[target] == layers[here]:
                same_layer.setdefault((here, target), where)
    for cycle in cycles(same_layer):
        hops = ", ".join(f"{a} -> {b} ({same_layer[(a, b)]})" for a, b in zip(cycle, cycle[1:] + cycle[:1]))
        problems.append(f"same-layer cycle {' -> '.join(cycle + cycle[:1])}: {hops}")
    return len(files), edges, same_layer


def cycles(edges: dict[tuple[str, str], str]) -> list[list[str]]:
    """One cycle through each strongly connected component with more than one module."""
    graph: dict[str, list[str]] = {}
    for a, b in edges:
        graph.setdefault(a, []).append(b)
        graph.setdefault(b, [])
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(component)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    found = []
    for component in components:
        members = set(component)
        # walk from the smallest member until a module repeats
        path = [min(component)]
        while True:
            nxt = min(w for w in graph[path[-1]] if w in members)
            if nxt in path:
                found.append(path[path.index(nxt) :])
                break
            path.append(nxt)
    return found


def dependency_names(cargo_toml: Path) -> list[tuple[str, str]]:
    """(package name, its spec as text) for every dependency table of a Cargo.toml."""
    text = cargo_toml.read_text(encoding="utf-8")
    try:
        import tomllib  # Python 3.11+
    except ImportError:
        return dependency_names_by_lines(text)
    data = tomllib.loads(text)
    tables = [data.get(k, {}) for k in ("dependencies", "dev-dependencies", "build-dependencies")]
    for target in data.get("target", {}).values():
        tables += [target.get(k, {}) for k in ("dependencies", "dev-dependencies", "build-dependencies")]
    deps = []
    for table in tables:
        for name, spec in table.items():
            package = spec.get("package", name) if isinstance(spec, dict) else name
            deps.append((package, str(spec)))
    return deps


def dependency_names_by_lines(text: str) -> list[tuple[str, str]]:
    """dependency_names without tomllib: `name = spec` lines of `[*dependencies*]` tables
    (and `[dependencies.name]` tables), `package = "…"` honoured."""
    deps: list[tuple[str, str]] = []
    table = ""
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if line.startswith("["):
            table = line.strip("[] ")
            m = re.fullmatch(r"(?:target\.[^\]]+\.)?(?:dev-|build-)?dependencies\.([\w-]+)", table)
            if m:
                deps.append((m.group(1), table))
            continue
        m = re.match(r'([\w-]+)(?:\.[\w.-]+)?\s*=\s*(.*)', line)
        in_deps = re.fullmatch(r"(?:target\.[^\]]+\.)?(?:dev-|build-)?dependencies", table)
        if m and in_deps:
            package = re.search(r'package\s*=\s*"([^"]+)"', m.group(2))
            deps.append((package.group(1) if package else m.group(1), m.group(2)))
        elif m and m.group(1) == "package" and re.search(r"dependencies\.", table):
            deps.append((m.group(2).strip('"'), table))
    return deps


def check_crates(root: Path, problems: list[str]) -> None:
    mention = re.compile(r"(?<![A-Za-z0-9_-])segloc\s*::")
    for crate in ("maps", "clipper"):
        base = root / crate
        for file in sorted(base.rglob("*.rs")):
            if "target" in file.relative_to(base).parts:
                continue
            text = file.read_text(encoding="utf-8")
            for m in mention.finditer(text):
                problems.append(
                    f"{file.relative_to(root).as_posix()}:{line_of(text, m.start())}: "
                    f"the {crate} crate mentions `segloc::` (the root crate depends on it, not the reverse)"
                )
        for package, spec in dependency_names(base / "Cargo.toml"):
            if package == "segloc":
                problems.append(f"{crate}/Cargo.toml: depends on the root crate segloc ({spec})")
            if crate == "clipper" and package == "segloc-maps":
                problems.append("clipper/Cargo.toml: depends on segloc-maps (clipper is pure math, no I/O)")
    for file in sorted((root / "clipper" / "src").rglob("*.rs")):
        code = strip_comments_and_literals(file.read_text(encoding="utf-8"))
        for m in CLIPPER_IO.finditer(code):
            problems.append(
                f"{file.relative_to(root).as_posix()}:{line_of(code, m.start())}: "
                f"clipper uses `{m.group(0)}` (clipper is pure math, no I/O)"
            )


def main() -> int:
    # the repository root; another one may be given (used to test the checker itself)
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent
    problems: list[str] = []
    files, edges, same_layer = check_src(root, problems)
    check_crates(root, problems)
    if problems:
        print(f"layer check: {len(problems)} violation(s) (layers in scripts/check_layers.py, see ARCHITECTURE.md)")
        for problem in problems:
            print(f"  {problem}")
        return 1
    same = ", ".join(f"{a} -> {b}" for a, b in sorted(same_layer)) or "none"
    print(f"layer check: ok ({files} files, {edges} cross-module references; same-layer edges: {same})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
