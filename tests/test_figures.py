"""docs/figures.md as the benches write it (``tileviz.testing.figures``): a bench replaces its own
block and nothing else, so what a person wrote around the blocks stays; and the docs' tables stay
readable (no cell over 200 characters in README.md or docs/*.md)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tileviz.testing.figures import MAX_CELL, Machine, write_block

REPO = Path(__file__).resolve().parents[1]


def test_a_bench_rewrites_its_own_block_and_keeps_the_rest(tmp_path: Path) -> None:
    doc = tmp_path / "figures.md"
    doc.write_text("# Figures\n\n## Speed\n\nA person's reading.\n\n<!-- figures:speed -->\n"
                   "old\n<!-- /figures:speed -->\n\nAfter the block.\n", encoding="utf-8")
    write_block("speed", "Speed", [("frames", "1.5-1.7 ms")], machine=Machine(),
                command="python bench/x.py --quick", path=doc)
    text = doc.read_text(encoding="utf-8")
    assert "A person's reading." in text and "After the block." in text and "old" not in text
    assert text.count("<!-- figures:speed -->") == 1
    line = text.split("<!-- figures:speed -->\n")[1].splitlines()[0]
    assert line.startswith("`python bench/x.py --quick` · ") and "commit " in line
    assert re.search(r"\d+ (of \d+ )?cores, load \d", line)
    assert "| frames | 1.5-1.7 ms |" in text
    write_block("other", "Other figures", [("a", "1")], machine=Machine(), command="c",
                path=doc)
    text = doc.read_text(encoding="utf-8")
    assert text.index("After the block.") < text.index("## Other figures")
    assert "| frames | 1.5-1.7 ms |" in text  # the first block untouched


def test_a_cell_longer_than_the_limit_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="longer than 200"):
        write_block("x", "X", [("what", "y" * (MAX_CELL + 1))], machine=Machine(), command="c",
                    path=tmp_path / "f.md")
    assert not (tmp_path / "f.md").exists()


@pytest.mark.parametrize("doc", ["README.md", *sorted(
    str(p.relative_to(REPO)) for p in (REPO / "docs").glob("*.md"))])
def test_no_table_cell_of_the_docs_is_longer_than_the_limit(doc: str) -> None:
    for k, line in enumerate((REPO / doc).read_text(encoding="utf-8").splitlines(), 1):
        if line.startswith("|"):
            for cell in line.strip("|").split("|"):
                assert len(cell.strip()) <= MAX_CELL, f"{doc}:{k}: {cell.strip()[:60]}..."
