"""Encoders, describers and segmenters behind the small interfaces of :mod:`.base`."""

from openreloc_bench.vision.base import (  # noqa: F401
    Describer,
    ImageTextEncoder,
    ObjectMask,
    Segmenter,
    create_describer,
    create_encoder,
    create_segmenter,
)
