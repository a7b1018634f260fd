"""Language descriptions of query objects: the paper's LLM step.

- ``offline``: retrieval from an open vocabulary (hundreds of nouns x colours x materials) with the
  encoder itself. Like the paper's prompt (full image + segmented object), the noun is chosen from
  the object crop *and* a wider context crop, so surroundings can disambiguate (a box on a desk vs a
  cabinet on the floor); the colour and material come from the object crop alone.
- ``openai``: any OpenAI-compatible chat-completions endpoint, given the query image and the
  segmented object as two images; cached on disk, retried with backoff, and falling back to the
  offline describer (with a warning) when the endpoint fails.
"""

from __future__ import annotations

import base64
import hashlib
import json
import logging
import os
import time
import urllib.error
import urllib.request
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from openreloc_bench.data import io, paths
from openreloc_bench.errors import ConfigError
from openreloc_bench.vision import vocabulary as voc
from openreloc_bench.vision.base import Describer, ImageTextEncoder, create_encoder, register_describer
from openreloc_bench.vision.preprocess import as_rgb_uint8, check_mask, mask_box, square_crop

log = logging.getLogger(__name__)


@register_describer("offline")
class OfflineDescriber(Describer):
    """'a {colour} [{material}] {noun}' chosen by retrieval in the encoder's joint space.

    Colour and material are chosen against noun-agnostic phrases ('a red object', 'a red wooden
    object', the usual zero-shot attribute prompts): their embeddings are computed once, whereas
    noun-specific ones ('a red sofa') would cost a text-encoder pass for every new noun at query time.
    """

    name = "offline"

    def __init__(
        self,
        encoder: ImageTextEncoder | None = None,
        nouns: list[str] | None = None,
        extra_nouns: list[str] | None = None,
        context_weight: float = 0.3,
        context_scale: float = 3.0,
        material_margin: float = 0.01,
    ):
        """``nouns``: the noun vocabulary (default :data:`~vocabulary.OBJECT_NOUNS`); ``extra_nouns``: nouns
        added to it, e.g. an asset pack's categories (``openreloc-bench assets`` prints them);
        ``context_weight``: share of the context-crop embedding in the noun query; ``context_scale``:
        context crop side / object box side; ``material_margin``: similarity gain needed to add a material."""
        self.encoder = encoder if encoder is not None else create_encoder("offline")
        self.nouns = list(dict.fromkeys([*(nouns or voc.OBJECT_NOUNS), *(extra_nouns or ())]))
        if not self.nouns:
            raise ConfigError("offline describer: the noun vocabulary is empty")
        self.context_weight, self.context_scale, self.material_margin = context_weight, context_scale, material_margin
        self._tables: dict[str, np.ndarray] = {}

    def _table(self, key: str, phrases: list[str]) -> np.ndarray:
        if key not in self._tables:
            self._tables[key] = self._stored_table(phrases)
        return self._tables[key]

    def _stored_table(self, phrases: list[str]) -> np.ndarray:
        """The encoder's embeddings of ``phrases``, kept in the user cache (``describer/``) under the
        encoder's config, the phrases and the library versions: a process that finds them there neither
        loads the text model nor runs it (seconds of every map load). The stored table is the one the
        encoder computed for this very list, so it is bit-identical to embedding it again."""
        key = json.dumps([self.encoder.config(), _library_versions(), phrases], sort_keys=True, default=str)
        path = paths.cache_root() / "describer" / f"table-{hashlib.sha256(key.encode()).hexdigest()[:24]}.npy"
        try:
            table = np.load(path, allow_pickle=False)
            if table.shape == (len(phrases), self.encoder.dim) and table.dtype == np.float32:
                return table
        except (OSError, ValueError):  # not stored yet, or a damaged file: embed again
            pass
        table = np.asarray(self.encoder.encode_texts(phrases), np.float32)
        try:
            io.atomic_write_npy(path, table)
        except OSError as e:  # a read-only cache costs time, not the answer
            log.warning("cannot store the describer's phrase table in %s (%s)", path.parent, e)
        return table

    def _nouns(self) -> np.ndarray:
        return self._table("nouns", [voc.with_article(voc.ZERO_SHOT_TEMPLATE.format(noun=n)) for n in self.nouns])

    def _colours(self) -> np.ndarray:
        return self._table("colours", [voc.with_article(f"a {c} object") for c in voc.COLOURS])

    def _materials(self, colour: str) -> np.ndarray:
        return self._table(f"materials/{colour}", [voc.with_article(f"a {colour} {mt} object") for mt in voc.MATERIALS])

    def prepare(self) -> None:
        self._nouns()
        self._colours()
        for colour in voc.COLOURS:
            self._materials(colour)

    def describe(self, rgb: np.ndarray, mask: np.ndarray) -> str:
        return self.describe_many(rgb, [mask])[0]

    def describe_many(self, rgb: np.ndarray, masks: list[np.ndarray]) -> list[str]:
        rgb = as_rgb_uint8(rgb)
        boxes = [mask_box(check_mask(m, rgb.shape[:2])) for m in masks]
        if not boxes:
            return []
        crops = [c for b in boxes for c in (square_crop(rgb, b, 1.2), square_crop(rgb, b, self.context_scale))]
        emb = self.encoder.encode_images(crops)  # one batch: object and context crops interleaved
        obj, ctx = emb[0::2], emb[1::2]
        q = obj + self.context_weight * ctx
        q /= np.linalg.norm(q, axis=1, keepdims=True).clip(1e-12)
        nouns, colours = self._nouns(), self._colours()
        out = []
        for o, noun_k in zip(obj, np.argmax(q @ nouns.T, axis=1)):
            noun = self.nouns[int(noun_k)]
            cs = colours @ o
            colour = voc.COLOURS[int(np.argmax(cs))]
            ms = self._materials(colour) @ o
            best = int(np.argmax(ms))
            words = f"{colour} {voc.MATERIALS[best]}" if ms[best] > cs.max() + self.material_margin else colour
            out.append(voc.with_article(f"a {words} {noun}"))
        return out


@lru_cache(maxsize=1)
def _library_versions() -> dict[str, str]:
    """Versions of the libraries a text embedding depends on (a new one may change its last bits)."""
    from openreloc_bench.vision.offline import MINILM_PACKAGE  # torch is loaded by then: an encoder ran

    found = {}
    for dist in ("torch", "transformers", "sentence-transformers", "open_clip_torch", MINILM_PACKAGE):
        try:
            found[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            found[dist] = ""
    return found


PROMPT = (
    "You are annotating objects for camera relocalization in indoor scenes. The first image is the full "
    "view of a room; the second image shows one object segmented from it. Using the room as context for "
    "what the object is, describe ONLY the segmented object as one short noun phrase with its colour, "
    "material if visible, and category, for example 'a red fabric armchair' or 'a white ceramic mug'. "
    "Answer with the phrase only."
)
"""Modelled on the paper's agent prompt (query image + segmented object; context helps, clutter hurts)."""


def _png_b64(img: np.ndarray) -> str:
    return base64.b64encode(io.encode_png(img)).decode("ascii")


@register_describer("openai")
class OpenAIDescriber(Describer):
    """Chat-completions vision model over HTTP (OpenAI, vLLM, Ollama, LM Studio... any compatible server)."""

    name = "openai"

    def __init__(
        self,
        model: str = "gpt-4o-mini",
        base_url: str | None = None,
        api_key: str | None = None,
        timeout_s: float = 30.0,
        max_retries: int = 3,
        backoff_s: float = 1.0,
        cache_dir: str | Path | None = None,
        max_tokens: int = 32,
        encoder: ImageTextEncoder | None = None,
        fallback: Describer | None = None,
    ):
        """``base_url`` / ``api_key`` default to $OPENAI_BASE_URL / $OPENAI_API_KEY; ``fallback`` (default: the
        offline describer on ``encoder``) answers when the endpoint fails."""
        self.model = model
        self.base_url = (base_url or os.environ.get("OPENAI_BASE_URL") or "https://api.openai.com/v1").rstrip("/")
        self.api_key = api_key if api_key is not None else os.environ.get("OPENAI_API_KEY", "")
        if timeout_s <= 0 or max_retries < 0 or backoff_s < 0:
            raise ConfigError("openai describer: need timeout_s > 0, max_retries >= 0, backoff_s >= 0")
        self.timeout_s, self.max_retries, self.backoff_s, self.max_tokens = (
            timeout_s,
            int(max_retries),
            backoff_s,
            max_tokens,
        )
        self.cache_dir = Path(cache_dir) if cache_dir else paths.cache_root() / "describer"
        self._encoder = encoder
        self._fallback = fallback
        self.calls = 0
        """HTTP requests sent (for tests and cost accounting)."""

    @property
    def fallback(self) -> Describer:
        if self._fallback is None:
            self._fallback = OfflineDescriber(self._encoder)
        return self._fallback

    def _request(self, payload: dict[str, Any]) -> str:
        req = urllib.request.Request(
            f"{self.base_url}/chat/completions",
            data=json.dumps(payload).encode("utf-8"),
            method="POST",
            headers={
                "Content-Type": "application/json",
                **({"Authorization": f"Bearer {self.api_key}"} if self.api_key else {}),
            },
        )
        self.calls += 1
        with urllib.request.urlopen(req, timeout=self.timeout_s) as resp:
            body = json.loads(resp.read().decode("utf-8"))
        text = body["choices"][0]["message"]["content"]
        if isinstance(text, list):  # content parts
            text = " ".join(p.get("text", "") for p in text if isinstance(p, dict))
        text = str(text).strip().strip("\"'.").strip()
        if not text:
            raise ValueError("empty answer")
        return text.splitlines()[0]

    def describe(self, rgb: np.ndarray, mask: np.ndarray) -> str:
        rgb = as_rgb_uint8(rgb)
        m = check_mask(mask, rgb.shape[:2])
        obj = np.where(m[..., None], rgb, 255).astype(np.uint8)
        obj = square_crop(obj, mask_box(m), 1.2, fill=255)
        images = [_png_b64(rgb), _png_b64(obj)]
        key = hashlib.sha256("\n".join([self.model, PROMPT, *images]).encode()).hexdigest()
        cache = self.cache_dir / f"{key}.json"
        if cache.is_file():
            try:
                return str(json.loads(cache.read_text())["description"])
            except (ValueError, KeyError):
                log.warning("ignoring corrupt describer cache entry %s", cache)
        payload = {
            "model": self.model,
            "max_tokens": self.max_tokens,
            "temperature": 0,
            "messages": [
                {
                    "role": "user",
                    "content": [
                        {"type": "text", "text": PROMPT},
                        *({"type": "image_url", "image_url": {"url": f"data:image/png;base64,{b}"}} for b in images),
                    ],
                }
            ],
        }
        error = ""
        for attempt in range(self.max_retries + 1):
            try:
                text = self._request(payload)
                io.write_json(cache, {"description": text, "model": self.model})
                return text
            except urllib.error.HTTPError as e:
                error = f"HTTP {e.code}"
                if e.code < 500 and e.code != 429:  # a client error does not heal by retrying
                    break
            except (urllib.error.URLError, TimeoutError, OSError, ValueError, KeyError, IndexError, TypeError) as e:
                error = f"{type(e).__name__}: {e}"
            if attempt < self.max_retries:
                time.sleep(self.backoff_s * 2**attempt)
        log.warning("describer endpoint %s failed (%s); falling back to the offline describer", self.base_url, error)
        return self.fallback.describe(rgb, m)
