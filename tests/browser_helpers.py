"""A real ``quasitune serve`` (simulated leg on its virtual CAN bus) and Debian's Chromium driven by Playwright,
shared by the browser tests and ``quasitune bench-ui``-style checks. Screenshots go to ``artifacts/browser/``."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

CHROMIUM = os.environ.get("QUASITUNE_CHROMIUM", "/usr/bin/chromium")
ARTIFACTS = Path(os.environ.get("QUASITUNE_ARTIFACTS", Path(__file__).resolve().parents[1] / "artifacts")) / "browser"


def chromium_path() -> str:
    """Debian's Chromium (installed by scripts/test.sh); a clear failure if it is missing, never a skip."""
    path = shutil.which(CHROMIUM) or (CHROMIUM if Path(CHROMIUM).exists() else None)
    if path is None:
        raise RuntimeError(f"Chromium not found at {CHROMIUM}: run 'bash scripts/test.sh', which installs Debian's "
                           "chromium package (never 'playwright install')")
    return path


def shot(page, name: str) -> Path:
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    page.screenshot(path=str(path), full_page=True)
    return path


def canvas_ink(page, selector: str) -> list[int]:
    """Number of non-transparent pixels in each canvas matching ``selector`` (0 = nothing drawn)."""
    return page.evaluate("""(sel) => [...document.querySelectorAll(sel)].map((c) => {
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let n = 0; for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++; return n; })""", selector)
