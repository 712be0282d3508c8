"""Writes python/lamina/data/cie1931_2deg_d65.csv: the CIE 1931 2° colour-matching functions and the CIE
standard illuminant D65 on a 1 nm grid, 360-830 nm, read from colour-science's copies of the CIE tables.

This is standard reference data (CIE 015:2018 / ISO 11664-1, ISO 11664-2), not derived data; the script exists so
that the shipped file can be regenerated and checked. Run: .venv/bin/python scripts/make_cie_table.py
"""

from pathlib import Path

import colour
import numpy as np

shape = colour.SpectralShape(360, 830, 1)
cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(shape)
d65 = colour.SDS_ILLUMINANTS["D65"].copy().align(shape)
out = Path(__file__).resolve().parents[1] / "python" / "lamina" / "data" / "cie1931_2deg_d65.csv"
rows = np.column_stack([shape.wavelengths, cmfs.values, d65.values])
header = (
    "CIE 1931 2-degree standard observer colour-matching functions and CIE standard illuminant D65 (relative SPD),\n"
    "1 nm steps. Source: CIE 015:2018, ISO 11664-1:2019, ISO 11664-2:2022, as tabulated in colour-science "
    f"{colour.__version__}\n(MSDS_CMFS['CIE 1931 2 Degree Standard Observer'], SDS_ILLUMINANTS['D65']). "
    "Regenerate with scripts/make_cie_table.py.\nwavelength_nm,xbar,ybar,zbar,d65"
)
np.savetxt(out, rows, delimiter=",", fmt=["%.0f", "%.9g", "%.9g", "%.9g", "%.9g"], header=header)
print(f"wrote {out} ({len(rows)} rows)")
