"""`make notebooks`: executes every notebook in notebooks/ top to bottom on an ipykernel (nbclient) and writes it
back with its outputs, so that a reader sees the figures; every cell gets a stable id. tests/test_notebooks.py runs
the same execution in `make test` without writing."""

from __future__ import annotations

import sys
from pathlib import Path

import nbformat
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


def execute(path: Path, timeout: int = 900):
    """The executed notebook (nbformat node), run in its own folder; every cell given an id if it has none."""
    nb = nbformat.read(path, as_version=4)
    nb.nbformat_minor = max(nb.nbformat_minor, 5)
    for i, cell in enumerate(nb.cells):
        if not cell.get("id"):
            cell["id"] = f"{path.stem.split('_', 1)[-1]}-{i:02d}"
    NotebookClient(
        nb, timeout=timeout, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}
    ).execute()
    return nb


def main() -> None:
    for path in NOTEBOOKS if len(sys.argv) < 2 else [Path(p).resolve() for p in sys.argv[1:]]:
        nb = execute(path)
        nbformat.write(nb, path)
        print(f"executed {path.relative_to(ROOT)}", file=sys.stderr)


if __name__ == "__main__":
    main()
