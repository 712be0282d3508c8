"""Writes one generated section of a Markdown file in docs/, leaving the other sections as they are."""

from __future__ import annotations

import json
import re
import sys
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


def read_section(path: Path, key: str) -> list[str] | None:
    """The lines between <!-- begin KEY --> and <!-- end KEY --> in the Markdown file at `path`, or None."""
    found = re.search(rf"<!-- begin {re.escape(key)} -->\n(.*?)\n<!-- end {re.escape(key)} -->", path.read_text(), re.S)
    return found.group(1).split("\n") if found else None


def import_device_check(folder: Path) -> Path:
    """Takes what scripts/device_check.sh brought back from a hardware GPU (its folder: adapter.json, parity.log,
    benchmarks.md) into docs/benchmarks.md: the benchmarks' "gpu-hardware" and "render-hardware" sections as they
    were written there, and a "device-check" section with the adapter and the parity tests' outcome."""
    adapter = json.loads((folder / "adapter.json").read_text())
    log = (folder / "parity.log").read_text().strip().split("\n")
    failed = [line.removeprefix("FAILED ").split(" - ")[0] for line in log if line.startswith("FAILED ")]
    lines = [
        "## The device check (scripts/device_check.sh on a hardware GPU)",
        "",
        "Written by `python benchmarks/docs_section.py import-device-check FOLDER` from the folder the check brought "
        "back; do not edit by hand. "
        f"Adapter: **{adapter['name']}** ({adapter['device_type']}, {adapter['backend']}, {adapter['driver']}). "
        f"GPU parity tests (tests/test_gpu.py): {log[-1]}.",
    ]
    if failed:
        lines += ["", "Failed there:", "", *(f"- `{name}`" for name in failed)]
    path = write_section("benchmarks.md", "Benchmarks", "device-check", lines)
    for key in ("gpu-hardware", "render-hardware"):
        section = read_section(folder / "benchmarks.md", key)
        if section is None:
            raise SystemExit(f"{folder / 'benchmarks.md'} has no {key!r} section: did the benchmarks run on a GPU?")
        write_section("benchmarks.md", "Benchmarks", key, section)
    return path


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] != "import-device-check":
        raise SystemExit("usage: python benchmarks/docs_section.py import-device-check FOLDER")
    print(f"wrote {import_device_check(Path(sys.argv[2]))}")
