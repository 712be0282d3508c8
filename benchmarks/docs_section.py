"""Writes one generated section of a Markdown file in docs/, leaving the other sections as they are."""

from __future__ import annotations

import re
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"


def write_section(filename: str, title: str, key: str, lines: list[str]) -> Path:
    """Replaces (or appends) the block between <!-- begin KEY --> and <!-- end KEY --> in docs/FILENAME."""
    path = DOCS / filename
    text = path.read_text() if path.exists() else f"# {title}\n"
    block = f"<!-- begin {key} -->\n" + "\n".join(lines).rstrip() + f"\n<!-- end {key} -->\n"
    pattern = re.compile(rf"<!-- begin {re.escape(key)} -->.*?<!-- end {re.escape(key)} -->\n", re.S)
    text = pattern.sub(lambda _: block, text) if pattern.search(text) else text.rstrip() + "\n\n" + block
    path.write_text(text)
    return path
