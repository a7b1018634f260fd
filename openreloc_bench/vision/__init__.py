"""Encoders, describers and segmenters behind the small interfaces of :mod:`.base`.

Importing this package registers every backend: encoders ``clip`` and ``offline``, describers
``offline`` and ``openai``, segmenters ``gt``, ``noisy-gt``, ``graph`` and ``learned``.
"""

from openreloc_bench.vision import clip, describe, learned_segment, offline, segment  # noqa: F401  (register backends)
from openreloc_bench.vision.base import (  # noqa: F401
    Describer,
    ImageTextEncoder,
    ObjectMask,
    Segmenter,
    create_describer,
    create_encoder,
    create_segmenter,
    segmenter_fingerprint,
)
