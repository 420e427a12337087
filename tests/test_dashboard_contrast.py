"""The dashboard's verdict colours against the plots' white: WCAG 2.x asks 3:1 of graphics
(success criterion 1.4.11, non-text contrast), which the verdict's bars and decision lines
are. axe-core checks text only, not what Plotly draws: the amber, #c98a00, was 2.95:1."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

IDENTIFY_JS = Path(__file__).resolve().parents[1] / "frontend" / "js" / "pages" / "identify.js"


def _status_colours() -> dict[str, str]:
    """``STATUS_COLOR`` as identify.js ships it: each status and its ``#rrggbb``."""
    source = IDENTIFY_JS.read_text(encoding="utf-8")
    found = re.search(r"const STATUS_COLOR = \{([^}]*)\}", source)
    assert found, f"no STATUS_COLOR in {IDENTIFY_JS}"
    pairs = re.findall(r'"?([\w-]+)"?\s*:\s*"(#[0-9a-fA-F]{6})"', found.group(1))
    assert pairs, found.group(0)
    return dict(pairs)


def _luminance(colour: str) -> float:
    """WCAG 2.x relative luminance of ``#rrggbb`` (sRGB, its 0.04045 threshold)."""
    channels = [int(colour[i : i + 2], 16) / 255 for i in (1, 3, 5)]
    r, g, b = (c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in channels)
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def contrast_ratio(a: str, b: str) -> float:
    light, dark = sorted((_luminance(a), _luminance(b)), reverse=True)
    return (light + 0.05) / (dark + 0.05)


def test_the_contrast_ratio_is_wcags() -> None:
    assert contrast_ratio("#000000", "#ffffff") == pytest.approx(21.0)
    assert contrast_ratio("#ffffff", "#ffffff") == pytest.approx(1.0)
    assert contrast_ratio("#c98a00", "#ffffff") == pytest.approx(2.95, abs=0.005)


def test_every_verdict_colour_the_plots_draw_is_3_to_1_on_white() -> None:
    colours = _status_colours()
    assert set(colours) >= {"identified", "ambiguous", "matches-none"}, colours
    low = {
        status: round(contrast_ratio(colour, "#ffffff"), 2)
        for status, colour in colours.items()
        if contrast_ratio(colour, "#ffffff") < 3
    }
    assert low == {}, f"under 3:1 on white: {low}"
