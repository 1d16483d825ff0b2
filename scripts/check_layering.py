#!/usr/bin/env python3
"""Layering of src/: the library layers do not import the simulator, the pictures, the CLI or the
evaluation, and no two files import each other (or import each other through a longer cycle).

Reads every `use` tree and every inline `crate::`/`super::` path of each file under src/ (test
modules, from the first `#[cfg(test)]` on, are left out), resolves each path to the file that
defines it, and checks:
  1. none of pipeline, mcapio, msgs, transforms, formats, tracker imports sim, viz, cli, eval,
     fit or tune (so the exporters read MCAP through mcapio, not through eval);
  2. no import cycle between files (strongly connected components of more than one file), except
     the ones listed in KNOWN_CYCLES (reported as notes).
Exit 0 when both hold; otherwise prints each violation and exits 1.

It also prints, as notes that do not fail, every function over 100 lines and every file over 800
lines (both counted without the test module; generated code is not under src/), so that the
closing note of a change can list the exceptions.

Usage (from the repository root): scripts/check_layering.py [--self-test]
  --self-test   run the checks on a small made-up source tree (a cycle, a layering breach, a long
                function with braces in strings and comments) and verify their verdicts.
"""

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"
LOWER = ["pipeline", "mcapio", "msgs", "transforms", "formats", "tracker"]
UPPER = ["sim", "viz", "cli", "eval", "fit", "tune"]
# Import cycles known and being removed (a note, not a failure). Each entry is the exact set of
# files of the cycle; a cycle that changes (grows or shrinks) or a new one fails, and a known one
# that is gone is reported, to be removed from the list.
KNOWN_CYCLES: list = []
# Files importing an upper layer, reported as notes until their owners switch the import.
ALLOWED_LAYERING: set = set()
MAX_FN_LINES = 100
MAX_FILE_LINES = 800


def module_of(f: Path) -> list:
    rel = f.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "mod" or parts == ["lib"]:
        parts = parts[:-1]
    return parts


def file_of(parts: list):
    """The file defining the longest prefix of module path `parts` (None for the crate root)."""
    for n in range(len(parts), 0, -1):
        p = SRC.joinpath(*parts[:n])
        for cand in (p.with_suffix(".rs"), p / "mod.rs"):
            if cand.exists():
                return cand
    return None


def use_trees(text: str):
    """Expanded paths of every `use` declaration (brace groups flattened)."""
    for m in re.finditer(r"\buse\s+([^;]+);", text):
        yield from expand(re.sub(r"\s+", "", m.group(1)))


def expand(tree: str):
    i = tree.find("{")
    if i < 0:
        yield tree.split(" as ")[0]
        return
    prefix, inner = tree[:i], tree[i + 1 : tree.rindex("}")]
    depth, start = 0, 0
    for k, ch in enumerate(inner + ","):
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        elif ch == "," and depth == 0:
            item = inner[start:k]
            start = k + 1
            if item == "self":
                yield prefix.rstrip(":")
            elif item:
                yield from expand(prefix + item)


def resolve(path: str, here: list):
    parts = path.split("::")
    if parts[0] == "crate":
        return parts[1:]
    if parts[0] in ("super", "self"):
        base = list(here)
        while parts and parts[0] in ("super", "self"):
            if parts.pop(0) == "super":
                base = base[:-1]
        return base + parts
    return None


def imports(f: Path) -> set:
    text = f.read_text()
    cut = text.find("#[cfg(test)]")
    if cut >= 0:
        text = text[:cut]
    text = re.sub(r"//[^\n]*", "", text)
    here = module_of(f)
    if f.name != "mod.rs" and f.name != "lib.rs":
        here_mod = here  # a file module: `super` is its parent
    else:
        here_mod = here
    paths = set(use_trees(text))
    paths |= set(re.findall(r"\b(?:crate|super)(?:::\w+)+", text))
    out = set()
    for p in paths:
        parts = resolve(p, here_mod)
        if not parts:
            continue
        target = file_of(parts)
        if target and target != f:
            out.add(target)
    return out


def code_of(text: str) -> str:
    """`text` with comments, string and char literals blanked (newlines kept), so that braces
    and `fn` inside them do not count."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
        elif text.startswith("/*", i):
            j, depth = i + 2, 1
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
        elif (m := re.match(r'b?r(#*)"', text[i:i + 40])) and (i == 0 or not text[i - 1].isalnum()
                                                               and text[i - 1] != "_"):
            end = '"' + m.group(1)
            j = text.find(end, i + m.end())
            j = n if j < 0 else j + len(end)
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            j += 1
        elif c == "'" and (m := re.match(r"'(\\.[^']*|[^\\'])'", text[i:i + 12])):
            j = i + m.end()
        else:
            out.append(c)
            i += 1
            continue
        out.append(re.sub(r"[^\n]", " ", text[i:j]))
        i = j
    return "".join(out)


def size_notes(f: Path, name: str):
    """Functions over MAX_FN_LINES lines and the file over MAX_FILE_LINES (test module left
    out), as note lines."""
    text = f.read_text()
    cut = text.find("#[cfg(test)]")
    if cut >= 0:
        text = text[:cut]
    code = code_of(text)
    n_lines = code.count("\n")
    if n_lines > MAX_FILE_LINES:
        yield f"{name}: {n_lines} lines (over {MAX_FILE_LINES})"
    for m in re.finditer(r"\bfn\s+(\w+)", code):
        open_at = re.compile(r"[{;]").search(code, m.end())
        if not open_at or open_at.group() == ";":
            continue  # a declaration without body
        depth, j = 0, open_at.start()
        while j < len(code):
            depth += {"{": 1, "}": -1}.get(code[j], 0)
            if depth == 0:
                break
            j += 1
        first = code.count("\n", 0, m.start()) + 1
        last = code.count("\n", 0, j) + 1
        if last - first + 1 > MAX_FN_LINES:
            yield f"{name}:{first}: fn {m.group(1)} {last - first + 1} lines (over {MAX_FN_LINES})"


def sccs(graph: dict):
    index, low, stack, on, res = {}, {}, [], set(), []
    counter = [0]

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
            res.append(comp)

    sys.setrecursionlimit(10000)
    for v in graph:
        if v not in index:
            visit(v)
    return [c for c in res if len(c) > 1]


def main() -> int:
    files = sorted(SRC.rglob("*.rs"))
    graph = {f: imports(f) for f in files}
    rel = lambda f: str(f.relative_to(ROOT))
    bad = []
    for f, deps in graph.items():
        top = module_of(f)[:1]
        if top and top[0] in LOWER:
            for d in sorted(deps):
                dtop = module_of(d)[:1]
                if dtop and dtop[0] in UPPER:
                    line = f"layering: {rel(f)} imports {rel(d)}"
                    if rel(f) in ALLOWED_LAYERING:
                        print("note (left for later):", line)
                    else:
                        bad.append(line)
    cycles = [sorted(rel(f) for f in comp) for comp in sccs(graph)]
    for names in cycles:
        line = "import cycle: " + ", ".join(names)
        if set(names) in KNOWN_CYCLES:
            print("note (known, being removed):", line)
        else:
            bad.append(line)
    for known in KNOWN_CYCLES:
        if known not in [set(c) for c in cycles]:
            print("note: known cycle gone, remove it from KNOWN_CYCLES:", ", ".join(sorted(known)))
    for f in files:
        for line in size_notes(f, rel(f)):
            print("note (size):", line)
    for b in bad:
        print(b)
    print(f"check_layering: {len(files)} files, {len(bad)} violation(s)")
    return 1 if bad else 0


def self_test() -> int:
    """Checks the checker on a made-up tree: each rule must fire where it should, only there."""
    import contextlib
    import io
    import tempfile

    global ROOT, SRC, KNOWN_CYCLES
    KNOWN_CYCLES = []
    long_body = "".join(f"    let _x{i} = \"{{\"; // }} fn fake() {{\n" for i in range(101))
    tree = {
        "lib.rs": "pub mod formats;\npub mod sim;\n",
        "formats/mod.rs": "mod a;\nmod b;\nmod c;\n",
        # a <-> b: a cycle; c imports the simulator: a layering breach.
        "formats/a.rs": "use super::b::B;\npub struct A;\n",
        "formats/b.rs": "use crate::formats::a::A;\npub struct B;\n",
        "formats/c.rs": "use crate::sim::S;\nfn short() { let c = '{'; }\n",
        # 103 lines of function, braces in strings and comments; a test module left out.
        "sim/mod.rs": "pub struct S;\nfn long() {\n" + long_body + "}\n#[cfg(test)]\nmod t { use crate::formats::a::A; }\n",
    }
    with tempfile.TemporaryDirectory() as tmp:
        ROOT = Path(tmp)
        SRC = ROOT / "src"
        for name, text in tree.items():
            (SRC / name).parent.mkdir(parents=True, exist_ok=True)
            (SRC / name).write_text(text)
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = main()
    lines = out.getvalue().splitlines()
    want = [
        "layering: src/formats/c.rs imports src/sim/mod.rs",
        "import cycle: src/formats/a.rs, src/formats/b.rs",
        "note (size): src/sim/mod.rs:2: fn long 103 lines (over 100)",
        "check_layering: 6 files, 2 violation(s)",
    ]
    problems = [f"missing: {w}" for w in want if w not in lines]
    problems += [f"unexpected: {l}" for l in lines if l not in want]
    if code != 1:
        problems.append(f"exit status {code}, want 1")
    for p in problems:
        print("self-test:", p)
    print(f"check_layering self-test: {'failed' if problems else 'ok'}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(self_test() if sys.argv[1:] == ["--self-test"] else main())
