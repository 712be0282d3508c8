"""Every notebook in notebooks/ runs top to bottom on a real kernel (nbclient on an ipykernel of this Python), every
cell has an id, and every cell that shows a figure produces one (an image/png output)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from run_notebooks import NOTEBOOKS, execute  # noqa: E402


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs_on_a_kernel(path):
    nb = execute(path)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert all(c.execution_count for c in code)
    assert all(c.get("id") for c in nbformat_cells(path))  # committed with ids
    for c in code:
        if "plt.show()" in c.source:
            assert any("image/png" in o.get("data", {}) for o in c.outputs), f"no figure from: {c.source[:80]!r}"


def nbformat_cells(path: Path) -> list:
    import nbformat

    return nbformat.read(path, as_version=4).cells
