"""Writes the README's model table from the catalogue (`make readme`): the text between the markers
<!-- models:start --> and <!-- models:end --> is replaced by lamina.catalogue.markdown_table(). A test checks that the
README holds the current table."""

from __future__ import annotations

from pathlib import Path

from lamina.catalogue import markdown_table

README = Path(__file__).resolve().parents[1] / "README.md"
START, END = "<!-- models:start -->", "<!-- models:end -->"


def with_table(text: str) -> str:
    """`text` with the block between the markers replaced by the current table."""
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    return f"{head}{START}\n{markdown_table()}\n{END}{tail}"


if __name__ == "__main__":
    README.write_text(with_table(README.read_text()))
    print(f"wrote the model table into {README}")
