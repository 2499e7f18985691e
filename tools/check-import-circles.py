#!/usr/bin/env python3
"""Fails when modules of one crate import each other in a circle.

For every crate's `src` (the workspace's and the Python package's), each
`crate::...`, `super::...` and `self::...` path in a module's code is an
edge between the two sibling modules it joins: the first module of each
path below their common parent (`crate::run::X` in `launch/mod.rs` joins
`launch` and `run`; `super::y` in `a/x.rs` joins `a::x` and `a::y`). A
child naming its own ancestor's items joins nothing. Any circle among
siblings is printed with a line of each import that makes it, and the
script exits 1. Comments and doc comments are skipped; tests modules
count like any other module.

Usage: python3 tools/check-import-circles.py [ROOT]
"""

import re
import sys
from collections import defaultdict
from pathlib import Path

PATH = re.compile(r"\b(crate|super|self)((?:::(?:super|[A-Za-z_][A-Za-z0-9_]*))*)(::\{)?")
COMMENT = re.compile(r"//.*$")


def module_path(src: Path, file: Path) -> list[str]:
    """The module path of `file` inside the crate whose root is `src`."""
    parts = list(file.relative_to(src).with_suffix("").parts)
    if parts[-1] in ("mod", "lib", "main"):
        parts.pop()
    return parts


def group_heads(text: str, start: int) -> list[str]:
    """The first identifier of each item of the `{...}` group at `start`."""
    depth, item, heads = 0, "", []
    for char in text[start:]:
        if char == "{":
            depth += 1
            if depth == 1:
                continue
        elif char == "}":
            depth -= 1
            if depth == 0:
                heads.append(item)
                break
        if depth == 1 and char == ",":
            heads.append(item)
            item = ""
        elif depth >= 1:
            item += char
    names = (re.match(r"\s*([A-Za-z_][A-Za-z0-9_]*)", head) for head in heads)
    return [name.group(1) for name in names if name]


def targets(module: list[str], text: str):
    """Every module path `text` (the code of `module`) names, with its line."""
    for line_number, line in enumerate(text.splitlines(), 1):
        code = COMMENT.sub("", line)
        for match in PATH.finditer(code):
            anchor, rest = match.group(1), match.group(2)
            names = [n for n in rest.split("::") if n]
            if anchor == "crate":
                base = []
            else:
                base = list(module) if anchor == "self" else list(module[:-1])
            while names and names[0] == "super":
                base = base[:-1]
                names.pop(0)
            heads = [names]
            if match.group(3):
                brace = match.end() - 1
                after = text.splitlines()[line_number - 1 :]
                heads = [names + [h] for h in group_heads("\n".join(after), code.index("{", brace))]
            for path in heads:
                yield base + path, line_number, line.strip()


def edge(source: list[str], target: list[str]):
    """The sibling modules `source` and `target` join, if any."""
    common = 0
    while common < min(len(source), len(target)) and source[common] == target[common]:
        common += 1
    if common < len(source) and common < len(target):
        return tuple(source[: common + 1]), tuple(target[: common + 1])
    return None


def circles(graph: dict) -> list[list[tuple]]:
    """The strongly connected groups of more than one module (Tarjan)."""
    index, low, stack, on_stack, found, counter = {}, {}, [], set(), [], [0]

    def visit(node):
        index[node] = low[node] = counter[0]
        counter[0] += 1
        stack.append(node)
        on_stack.add(node)
        for other in graph.get(node, ()):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            group = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                group.append(top)
                if top == node:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for node in list(graph):
        if node not in index:
            visit(node)
    return found


def check_crate(src: Path) -> list[str]:
    """The circles of the crate rooted at `src`, described."""
    graph, evidence = defaultdict(set), defaultdict(list)
    modules = {}
    for file in sorted(src.rglob("*.rs")):
        modules[tuple(module_path(src, file))] = file
    for module, file in modules.items():
        for target, line_number, line in targets(list(module), file.read_text()):
            # Only paths that name a module of this crate.
            while target and tuple(target) not in modules:
                target = target[:-1]
            joined = edge(list(module), target)
            if joined and joined[1] in modules:
                graph[joined[0]].add(joined[1])
                shown = f"{file}:{line_number}: {line}"
                evidence[joined].append(shown)
    problems = []
    for group in circles(graph):
        names = ", ".join("::".join(m) for m in group)
        lines = [f"import circle in {src}: {names}"]
        for a in group:
            for b in sorted(graph[a]):
                if b in group:
                    lines.append("  " + evidence[(a, b)][0])
        problems.append("\n".join(lines))
    return problems


def main() -> int:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
    crates = sorted(root.glob("crates/*/src")) + [root / "python" / "src"]
    problems = [p for src in crates if src.is_dir() for p in check_crate(src)]
    for problem in problems:
        print(problem)
    print(f"import circles: {len(problems)} in {len(crates)} crates")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
