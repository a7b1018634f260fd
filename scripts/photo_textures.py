"""Build ``generators/asset_library/photos.npz``: the photographic material textures the generator mixes
with its procedural ones, from robosuite's MIT-licensed texture images.

The generator tints every texture with its part's colour (the colour a description names), so only each
photograph's luminance is kept: a centred square, 256 pixels across, 8-bit. Run it on an unpacked
robosuite wheel (``pip download robosuite==1.5.1 --no-deps``, then unzip) to rebuild the file:

    python scripts/photo_textures.py UNPACKED_WHEEL_DIR generators/asset_library/photos.npz
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

SIDE = 256
SOURCE = "robosuite/models/assets/textures"
PHOTOS = {
    "wood": ("dark-wood", "light-wood", "gray-woodgrain", "red-wood", "blue-wood", "wood-varnished-panels"),
    "plaster": ("cream-plaster", "gray-plaster", "light-gray-plaster", "white-plaster"),
    "ceramic": ("ceramic", "light-gray-floor-tile"),
    "metal": ("brass-ambra", "metal", "steel-brushed", "steel-scratched"),
    "fabric": ("gray-felt",),
    "stone": ("white-bricks", "clay"),
}
"""The generator's material -> the robosuite textures photographed of it (food and packaging left out)."""


def luminance_square(path: Path) -> np.ndarray:
    """The image's centred square as 8-bit luminance, ``SIDE`` pixels across (area-averaged)."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        sys.exit(f"error: cannot read {path}")
    h, w = image.shape[:2]
    side = min(h, w)
    top, left = (h - side) // 2, (w - side) // 2
    grey = cv2.cvtColor(image[top : top + side, left : left + side], cv2.COLOR_BGR2GRAY)
    return cv2.resize(grey, (SIDE, SIDE), interpolation=cv2.INTER_AREA)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("wheel_dir", type=Path, help="an unpacked robosuite wheel")
    parser.add_argument("out", type=Path, help="the .npz to write")
    args = parser.parse_args()
    source = args.wheel_dir / SOURCE
    if not source.is_dir():
        sys.exit(f"error: {source} is not a directory: unpack a robosuite wheel there")
    names = [name for group in PHOTOS.values() for name in group]
    np.savez_compressed(
        args.out,
        images=np.stack([luminance_square(source / f"{name}.png") for name in names]),
        names=np.array(names),
        materials=np.array([material for material, group in PHOTOS.items() for _ in group]),
    )
    print(f"{len(names)} photographs -> {args.out}")


if __name__ == "__main__":
    main()
