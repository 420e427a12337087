"""Refresh the README's dashboard images from the browser tests' screenshots.

``pytest tests/browser`` saves every page type at 1366 px wide as
``artifacts/screenshots/page-NAME.png``; this writes ``docs/img/dashboard-NAME.png``
from each: 900 px wide, at most 2,400 px tall (the top of a long page), in a 128-colour
palette, so the README's images stay small. Needs Pillow::

    python scripts/readme_images.py [--from artifacts/screenshots] [--to docs/img]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from PIL import Image

WIDTH = 900
MAX_HEIGHT = 2400


def shrink(source: Path, target: Path) -> int:
    with Image.open(source) as image:
        rgb = image.convert("RGB")
        height = round(rgb.height * WIDTH / rgb.width)
        small = rgb.resize((WIDTH, height), Image.Resampling.LANCZOS)
        if height > MAX_HEIGHT:
            small = small.crop((0, 0, WIDTH, MAX_HEIGHT))
        small.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(target, optimize=True)
    return target.stat().st_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--from", dest="source", default="artifacts/screenshots", type=Path)
    parser.add_argument("--to", dest="target", default="docs/img", type=Path)
    args = parser.parse_args()
    args.target.mkdir(parents=True, exist_ok=True)
    for shot in sorted(args.source.glob("page-*.png")):
        out = args.target / f"dashboard-{shot.stem.removeprefix('page-')}.png"
        print(f"{out}: {shrink(shot, out) / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
