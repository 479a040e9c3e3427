"""Draw the package diagram of ``docs/architecture.md`` from the code's own imports.

``python docs/architecture_graph.py`` prints a Mermaid flowchart (GitHub renders it as a picture) of the
packages and subpackages and who imports whom, with edges implied by longer paths left out (transitive
reduction) so the layers read at a glance; ``--write`` puts it between the markers in ``docs/architecture.md``,
``--check`` exits 1 when the file's diagram differs from the code's (the test suite runs it).
Needs ``grimp`` (installed with import-linter by ``make test``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "architecture.md"
BEGIN, END = "<!-- import graph: begin (docs/architecture_graph.py --write) -->", "<!-- import graph: end -->"
ROOTS = ("uavfmu", "hil_adapter", "identification", "fmu_models")
#: packages shown by their subpackages (one node each); other roots are one node
SPLIT = ("identification", "fmu_models")


def node_of(module: str) -> str:
    """The diagram node a module belongs to: ``identification.thrust.model`` -> ``identification.thrust``."""
    parts = module.split(".")
    if parts[0] in SPLIT and len(parts) > 1:
        return ".".join(parts[:2])
    return parts[0]


def edges() -> tuple[list[str], set[tuple[str, str]]]:
    """Nodes and the node-level import edges (importer, imported) of the repository's packages."""
    import grimp

    sys.path.insert(0, str(REPO))
    graph = grimp.build_graph(*ROOTS)
    nodes, out = set(), set()
    for m in graph.modules:
        a = node_of(m)
        if a == m and m in SPLIT:
            continue  # the bare package's __init__
        nodes.add(a)
        for imported in graph.find_modules_directly_imported_by(m):
            b = node_of(imported)
            if b != a and b not in SPLIT:
                out.add((a, b))
    return sorted(nodes), out


def reduce(nodes: list[str], e: set[tuple[str, str]]) -> set[tuple[str, str]]:
    """Transitive reduction: drop a -> b when b is reachable from a another way."""
    succ = {n: {b for a, b in e if a == n} for n in nodes}

    def reach(start: str, skip: tuple[str, str]) -> set[str]:
        seen, todo = set(), [start]
        while todo:
            x = todo.pop()
            for y in succ.get(x, ()):
                if (x, y) != skip and y not in seen:
                    seen.add(y)
                    todo.append(y)
        return seen

    return {(a, b) for a, b in e if b not in reach(a, (a, b))}


def mermaid() -> str:
    """The diagram as a fenced Mermaid block."""
    nodes, e = edges()
    ident = {n: n.replace(".", "_") for n in nodes}
    lines = ["```mermaid", "flowchart TD"]
    for root in ROOTS:
        members = [n for n in nodes if n.split(".")[0] == root]
        if root in SPLIT:
            lines.append(f"  subgraph {root}")
            lines += [f"    {ident[n]}[{n.split('.', 1)[1]}]" for n in members]
            lines.append("  end")
        else:
            lines.append(f"  {ident[root]}[{root}]")
    lines += [f"  {ident[a]} --> {ident[b]}" for a, b in sorted(reduce(nodes, e))]
    lines.append("```")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--write", action="store_true", help="write the diagram into docs/architecture.md")
    g.add_argument("--check", action="store_true", help="exit 1 if docs/architecture.md's diagram is stale")
    args = ap.parse_args(argv)
    block = mermaid()
    if not (args.write or args.check):
        print(block)
        return 0
    text = DOC.read_text(encoding="utf-8")
    if BEGIN not in text or END not in text:
        print(f"{DOC}: markers {BEGIN!r} ... {END!r} not found", file=sys.stderr)
        return 1
    head, rest = text.split(BEGIN, 1)
    old, tail = rest.split(END, 1)
    new = f"{head}{BEGIN}\n{block}\n{END}{tail}"
    if args.check:
        if old.strip() != block.strip():
            print(f"{DOC}: the import diagram is stale; run python docs/architecture_graph.py --write",
                  file=sys.stderr)
            return 1
        print(f"{DOC}: import diagram in sync with the code")
        return 0
    DOC.write_text(new, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
