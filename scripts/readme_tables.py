"""Writes the README's generated tables (`make readme`): the model table from the catalogue (between
<!-- models:start --> and <!-- models:end -->, lamina.catalogue.markdown_table()) and the cost/error table from the
chart's data (between <!-- chart:start --> and <!-- chart:end -->, `chart_table()` of docs/speed_accuracy.json).
Tests check that the README holds the current tables."""

from __future__ import annotations

import json
from pathlib import Path

from lamina.catalogue import markdown_table

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: (chart label, what the row is called in the README): each model's default form.
CHART_ROWS = (
    ("belcour", "`belcour`"),
    ("steinberg (lamina defaults)", "`steinberg`"),
    ("weidlich_wilkie (lamina defaults)", "`weidlich_wilkie`"),
    ("albedo_scaling reciprocal", "`albedo_scaling`"),
    ("tabulated (precomputed)", "`tabulated` (after its precomputation)"),
    ("Mitsuba principled", "Mitsuba `principled` (closest parameters)"),
)


def chart_table(chart: dict) -> str:
    """Cost and mean lobe error per band of each model's default form, from docs/speed_accuracy.json."""
    rows = {(r["label"], r["set"]): r for r in chart["rows"]}
    bands = chart["bands_deg"]
    head = " / ".join(b.replace("-", "–") + "°" for b in bands)
    out = [
        f"| model | CPU ns per evaluation | lobe error, population: {head} | lobe error, suite: {head} |",
        "|---|---:|---|---|",
    ]
    fmt = lambda r: " / ".join("—" if r["lobe_error"][b] is None else f"{r['lobe_error'][b]:.2f}" for b in bands)  # noqa: E731
    for label, name in CHART_ROWS:
        p, s = rows[(label, "population")], rows[(label, "suite")]
        out.append(f"| {name} | {s['ns_per_eval']:.0f} | {fmt(p)} | {fmt(s)} |")
    for r in (r for r in chart["rows"] if r["model"] == "reference"):
        out.append(f"| {r['label']} | {r['ns_per_eval']:.3g} | (suite only) | {fmt(r)} |")
    return "\n".join(out)


def replace(text: str, start: str, end: str, block: str) -> str:
    """`text` with the block between the markers replaced."""
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{start}\n{block}\n{end}{tail}"


def with_tables(text: str) -> str:
    text = replace(text, "<!-- models:start -->", "<!-- models:end -->", markdown_table())
    chart = json.loads((ROOT / "docs" / "speed_accuracy.json").read_text())
    return replace(text, "<!-- chart:start -->", "<!-- chart:end -->", chart_table(chart))


if __name__ == "__main__":
    README.write_text(with_tables(README.read_text()))
    print(f"wrote the model and chart tables into {README}")
