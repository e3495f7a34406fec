"""Helpers for the browser tests: screenshots (under ``artifacts/browser/``, or ``$QUASITUNE_ARTIFACTS/browser``)
and a check that a canvas has something drawn on it."""

from __future__ import annotations

import os
from pathlib import Path

ARTIFACTS = Path(os.environ.get("QUASITUNE_ARTIFACTS", Path(__file__).resolve().parents[1] / "artifacts")) / "browser"


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
