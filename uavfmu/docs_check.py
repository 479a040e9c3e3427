"""Run every command of the README and ``docs/`` that is marked as runnable: ``python -m uavfmu.docs_check``.

Every ``sh``/``bash``/``python`` code block in ``README.md`` and ``docs/**/*.md`` carries a marker on the line
above it:

- ``<!-- docs-check: run -->``: run from the repository root (``sh`` blocks with ``bash -e``, ``.venv/bin``
  first on ``PATH``; ``python`` blocks with this interpreter); it must exit 0;
- ``<!-- docs-check: run if ../shared/data -->``: the same, skipped with the reason when that folder is absent;
- either of these with ``(exit N: why)``: the command must exit ``N`` (a documented refusal);
- ``<!-- docs-check: skip: reason -->``: not run, the reason is printed (e.g. it needs a SITL build).

A block without a marker is an error: no command in the docs goes unchecked by accident. Commands that use
the demo's output (``dist/demo``) need ``make demo`` first (``make docs-check`` runs it).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data"
LANGUAGES = {"sh": "sh", "bash": "sh", "shell": "sh", "python": "python"}
MARKER = re.compile(r"<!--\s*docs-check:\s*(run if \.\./shared/data|run|skip:\s*(?P<why>.*?))"
                    r"\s*(\(exit (?P<code>\d+)[^)]*\))?\s*-->")
FENCE = re.compile(r"^```(\w*)\s*$")
TIMEOUT_S = 900.0  #: a single block longer than this is a failure
#: pages whose blocks carry no markers yet: listed as unchecked, never silently passed
UNMARKED_PAGES: tuple[str, ...] = ()


class DocsCheckError(ValueError):
    """A code block without a marker, or a malformed marker; names file and line."""


@dataclass(frozen=True)
class Block:
    """One code block: where, its language, its code and what its marker says."""

    path: Path
    line: int
    language: str
    code: str
    action: str  # run | run-if-shared | skip
    reason: str = ""
    exit_code: int = 0

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(REPO) if self.path.is_relative_to(REPO) else self.path}:{self.line}"


def doc_files(root: Path = REPO) -> list[Path]:
    """``README.md`` first, then every Markdown file under ``docs/`` (sorted)."""
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


def blocks(path: Path) -> list[Block]:
    """The checked code blocks of one Markdown file; ``DocsCheckError`` for one without a marker."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out: list[Block] = []
    k = 0
    while k < len(lines):
        m = FENCE.match(lines[k])
        if not m:
            k += 1
            continue
        end = next((j for j in range(k + 1, len(lines)) if lines[j].startswith("```")), len(lines))
        lang = m.group(1).lower()
        if lang in LANGUAGES:
            out.append(_block(path, lines, k, LANGUAGES[lang], "\n".join(lines[k + 1:end])))
        k = end + 1
    return out


def _block(path: Path, lines: list[str], k: int, language: str, code: str) -> Block:
    above = next((lines[j].strip() for j in range(k - 1, -1, -1) if lines[j].strip()), "")
    m = MARKER.fullmatch(above)
    if not m:
        raise DocsCheckError(f"{path}:{k + 1}: a {language} block without a marker: put "
                             "'<!-- docs-check: run -->' or '<!-- docs-check: skip: why -->' on the line above it")
    kind = m.group(1)
    action = "skip" if kind.startswith("skip") else "run-if-shared" if "shared" in kind else "run"
    return Block(path, k + 1, language, code, action, (m.group("why") or "").strip(), int(m.group("code") or 0))


def run_block(block: Block, timeout_s: float = TIMEOUT_S) -> tuple[bool, str]:
    """Run one block from the repository root; ``(ok, message)``."""
    env = {**os.environ, "PATH": f"{REPO / '.venv' / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}",
           "MPLBACKEND": "Agg"}
    cmd = ["bash", "-e", "-c", block.code] if block.language == "sh" else [sys.executable, "-c", block.code]
    t0 = time.perf_counter()
    try:
        done = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return False, f"timed out after {timeout_s:g} s"
    took = f"{time.perf_counter() - t0:.1f} s"
    if done.returncode != block.exit_code:
        tail = "\n".join((done.stdout + done.stderr).strip().splitlines()[-15:])
        return False, f"exit {done.returncode}, expected {block.exit_code} ({took}):\n{tail}"
    return True, f"exit {done.returncode} as documented ({took})"


def check(files: list[Path], dry_run: bool = False) -> int:
    """Run (or with ``dry_run`` only parse) every marked block; print one line each; 0 when all pass."""
    unmarked = [f for f in files if f.is_file() and f.is_relative_to(REPO)
                and str(f.relative_to(REPO)) in UNMARKED_PAGES]
    try:
        found = [b for f in files if f.is_file() and f not in unmarked for b in blocks(f)]
    except DocsCheckError as err:
        print(f"docs-check: {err}", file=sys.stderr)
        return 1
    for f in unmarked:
        print(f"unchecked  {f.relative_to(REPO)}: its command blocks carry no docs-check markers yet")
    failed = 0
    for b in found:
        if b.action == "skip":
            print(f"skip  {b.where}: {b.reason}")
        elif b.action == "run-if-shared" and not SHARED.is_dir():
            print(f"skip  {b.where}: {SHARED} is absent")
        elif dry_run:
            print(f"would run  {b.where}")
        else:
            ok, msg = run_block(b)
            failed += not ok
            print(f"{'ok   ' if ok else 'FAIL '} {b.where}: {msg}")
    print(f"docs-check: {len(found)} blocks, {failed} failed")
    return 1 if failed else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m uavfmu.docs_check", description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*", type=Path, help="Markdown files (default: README.md and docs/)")
    parser.add_argument("--dry-run", action="store_true", help="only check that every block has a marker")
    args = parser.parse_args(argv)
    return check([f.resolve() for f in args.files] or doc_files(), args.dry_run)


if __name__ == "__main__":
    raise SystemExit(main())
