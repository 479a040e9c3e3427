"""The docs: a README a newcomer reads in five minutes, config reference pages in sync with the schemas, and
every command block marked for ``make docs-check`` (which runs them)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from uavfmu import docs_check, docs_gen

REPO = Path(__file__).resolve().parents[2]
#: pages other engineers write in parallel (linked from here; docs-check lists them as unchecked)
PENDING_PAGES = set(docs_check.UNMARKED_PAGES)


def test_readme_is_short_and_names_its_figure_command() -> None:
    text = (REPO / "README.md").read_text()
    assert len(text.splitlines()) < 120
    for command in ("make demo", "make test", "uavfmu build", "uavfmu identify thrust", "uavfmu identify aero",
                    "uavfmu validate", "uavfmu hil"):
        assert command in text, command
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert images == ["docs/img/validation_overlay.png"]
    assert (REPO / images[0]).stat().st_size < 200_000
    assert "python -m uavfmu.readme_figure" in text  # the command that produced it


def test_reference_pages_match_the_schemas() -> None:
    assert docs_gen.out_of_sync() == [], "run `python -m uavfmu.docs_gen`"


def test_reference_page_lists_every_field_with_its_range() -> None:
    from identification.validation.output_map import SignalEntry

    page = docs_gen.render(next(p for p in docs_gen.PAGES if p.slug == "output-map"))
    for name in SignalEntry.model_fields:
        assert f"| `{name}` |" in page, name
    assert "| `max_theil` | number (optional) | none | > 0 |" in page
    assert "| `min_skill_persistence` | number | `0.0` | >= -100, < 1 |" in page


def test_out_of_sync_pages_are_found(tmp_path: Path) -> None:
    for name, text in docs_gen.pages().items():
        (tmp_path / name).write_text(text)
    assert docs_gen.out_of_sync(tmp_path) == []
    (tmp_path / "output-map.md").write_text("stale\n")
    (tmp_path / "old-file.md").write_text("gone\n")
    assert docs_gen.out_of_sync(tmp_path) == ["old-file.md", "output-map.md"]


def test_every_command_block_is_marked() -> None:
    found = [b for f in docs_check.doc_files() if f.is_file() and str(f.relative_to(REPO)) not in PENDING_PAGES
             for b in docs_check.blocks(f)]
    assert sum(b.action != "skip" for b in found) >= 8
    assert all(b.reason for b in found if b.action == "skip")


def test_unmarked_block_is_an_error_and_exit_codes_are_read(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text("text\n\n```sh\nls\n```\n")
    with pytest.raises(docs_check.DocsCheckError, match=r"page.md:3: a sh block without a marker"):
        docs_check.blocks(page)
    page.write_text("<!-- docs-check: run (exit 3: a baseline wins) -->\n```sh\nexit 3\n```\n"
                    "<!-- docs-check: skip: needs a SITL -->\n```python\nraise SystemExit(1)\n```\n")
    run, skip = docs_check.blocks(page)
    assert (run.action, run.exit_code, skip.action, skip.reason) == ("run", 3, "skip", "needs a SITL")
    assert docs_check.run_block(run)[0] is True
    assert docs_check.run_block(docs_check.Block(page, 1, "sh", "exit 0", "run", "", 3))[0] is False


def test_local_links_resolve() -> None:
    for f in docs_check.doc_files():
        for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", f.read_text()):
            path = (f.parent / target).resolve()
            if str(path.relative_to(REPO)) in PENDING_PAGES:
                continue
            assert path.exists(), f"{f.relative_to(REPO)}: link to {target}"


def test_architecture_diagram_is_the_code_import_graph() -> None:
    """docs/architecture.md's diagram is regenerated from the imports; a new arrow or room makes this fail."""
    r = subprocess.run([sys.executable, str(REPO / "docs" / "architecture_graph.py"), "--check"],
                       capture_output=True, text=True, timeout=120, cwd=REPO)
    assert r.returncode == 0, r.stderr


def test_architecture_check_sees_a_stale_diagram(tmp_path: Path) -> None:
    """The check compares against the code: a diagram with one arrow removed is reported stale."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("architecture_graph", REPO / "docs" / "architecture_graph.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    block = mod.mermaid()
    arrow = next(line for line in block.splitlines() if "-->" in line)
    doc = tmp_path / "architecture.md"
    doc.write_text(f"x\n{mod.BEGIN}\n{block.replace(arrow + chr(10), '')}\n{mod.END}\n")
    mod.DOC = doc
    assert mod.main(["--check"]) == 1
    mod.main(["--write"])
    assert mod.main(["--check"]) == 0
