"""Finds the system libLLVM for Mitsuba 3's llvm_ad_* variants (used by tests/conftest.py and the Makefile).

Dr.Jit needs LLVM >= 15, but measured here: Mitsuba 3.9.1's llvm_ad_rgb aborts the process (SIGABRT) in
roughconductor.eval with Debian 12's libLLVM 15, and works with Debian's libllvm19. So we take the highest installed
version >= 16. `python tests/libllvm.py` prints the path (empty when none).
"""

from __future__ import annotations

import glob
import re

MIN_VERSION = 16


def find() -> str | None:
    found = []
    for path in glob.glob("/usr/lib/*/libLLVM*.so*"):
        m = re.search(r"libLLVM(?:-|\.so\.)(\d+)", path)
        if m and int(m.group(1)) >= MIN_VERSION:
            found.append((int(m.group(1)), path))
    return max(found)[1] if found else None


if __name__ == "__main__":
    print(find() or "")
