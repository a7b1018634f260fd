from __future__ import annotations

import base64
import json
import re
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import cv2
import numpy as np
import pytest

from openreloc_bench.data.paths import cache_root
from openreloc_bench.vision import create_describer
from openreloc_bench.vision import vocabulary as voc
from openreloc_bench.vision.preprocess import InputError


def _image() -> tuple[np.ndarray, np.ndarray]:
    img = np.full((48, 64, 3), 100, np.uint8)
    img[20:40, 10:30] = (200, 20, 20)
    mask = np.zeros((48, 64), bool)
    mask[20:40, 10:30] = True
    return img, mask


PHRASE = re.compile(r"^an? .+$")


def test_offline_describer_phrase_and_determinism(clip_encoder) -> None:
    d = create_describer("offline", encoder=clip_encoder)
    img, mask = _image()
    text = d.describe(img, mask)
    assert PHRASE.match(text), text
    assert any(text.endswith(" " + n) for n in voc.OBJECT_NOUNS)
    assert any(f" {c} " in f" {text} " for c in voc.COLOURS)
    assert d.describe(img, mask) == text
    assert d.describe(img.astype(np.float32) / 255.0, mask) == text  # float input coerced


class _Spy:
    """Wraps an encoder and records the crops it is given."""

    def __init__(self, enc) -> None:
        self.enc, self.crops, self.dim = enc, [], enc.dim

    def config(self):
        return self.enc.config()

    def encode_images(self, crops):
        self.crops.append(list(crops))
        return self.enc.encode_images(crops)

    def encode_texts(self, texts):
        return self.enc.encode_texts(texts)


class _TextCounter(_Spy):
    """Also counts the text phrases it is asked to encode."""

    def __init__(self, enc) -> None:
        super().__init__(enc)
        self.texts = 0

    def encode_texts(self, texts):
        self.texts += len(texts)
        return self.enc.encode_texts(texts)


def test_extra_nouns_join_the_vocabulary(clip_encoder) -> None:
    """An asset pack's categories reach the describer: a red patch is described as the only noun."""
    d = create_describer("offline", encoder=clip_encoder, extra_nouns=["storage crate", "chair"])
    assert d.nouns[-1] == "storage crate" and d.nouns.count("chair") == 1
    img, mask = _image()
    only = create_describer("offline", encoder=clip_encoder, nouns=["tomato"], extra_nouns=["storage crate"])
    assert only.describe(img, mask).endswith((" tomato", " storage crate"))


def test_prepared_offline_describer_encodes_no_text_per_query(clip_encoder) -> None:
    """The vocabulary tables are built when a map loads (``prepare``), not in the first queries."""
    img, mask = _image()
    counter = _TextCounter(clip_encoder)
    d = create_describer("offline", encoder=counter)
    d.prepare()
    prepared = counter.texts
    assert prepared >= len(voc.OBJECT_NOUNS) + len(voc.COLOURS) * (1 + len(voc.MATERIALS))
    other = img.copy()
    other[20:40, 10:30] = (20, 20, 200)
    d.describe_many(img, [mask])
    d.describe_many(other, [mask, ~mask])
    assert counter.texts == prepared


def test_offline_describer_stores_its_tables_in_the_user_cache(clip_encoder) -> None:
    """A second process (here: a second describer) reads the phrase tables bit for bit, encoding nothing;
    a damaged table file is embedded again."""
    first = _TextCounter(clip_encoder)
    d = create_describer("offline", encoder=first)
    d.prepare()
    stored = sorted((cache_root() / "describer").glob("table-*.npy"))
    assert first.texts > 0 and len(stored) == 2 + len(voc.COLOURS)
    second = _TextCounter(clip_encoder)
    again = create_describer("offline", encoder=second)
    again.prepare()
    assert second.texts == 0
    assert all(again._tables[k].tobytes() == d._tables[k].tobytes() for k in d._tables)
    stored[0].write_bytes(b"not an array")
    third = _TextCounter(clip_encoder)
    create_describer("offline", encoder=third).prepare()
    assert 0 < third.texts < first.texts


def test_offline_describer_sees_object_and_context(clip_encoder) -> None:
    """Like the paper's prompt: the object crop plus a wider context crop; colour comes from the object."""
    img, mask = _image()
    spy = _Spy(clip_encoder)
    create_describer("offline", encoder=spy, context_scale=3.0).describe(img, mask)
    obj, ctx = spy.crops[0]
    assert obj.shape[0] == 24 and ctx.shape[0] == 60  # 20-px object: 1.2x and 3x squares
    assert (ctx == 100).all(axis=2).mean() > 0.3  # the context crop shows the surroundings
    # with no context weight, changing the image outside the object crop cannot change the description
    d0 = create_describer("offline", encoder=clip_encoder, context_weight=0.0)
    other = np.full_like(img, 30)
    other[18:42, 8:32] = img[18:42, 8:32]
    assert d0.describe(other, mask) == d0.describe(img, mask)


def test_offline_describer_batches_all_objects_of_an_image(clip_encoder) -> None:
    img, mask = _image()
    other = np.zeros_like(mask)
    other[5:15, 40:60] = True
    img[5:15, 40:60] = (20, 20, 200)
    spy = _Spy(clip_encoder)
    d = create_describer("offline", encoder=spy)
    phrases = d.describe_many(img, [mask, other])
    assert len(spy.crops) == 1 and len(spy.crops[0]) == 4  # one encoder call: object + context crop each
    assert phrases == [d.describe(img, mask), d.describe(img, other)]
    assert d.describe_many(img, []) == []


def test_offline_describer_bad_masks(clip_encoder) -> None:
    d = create_describer("offline", encoder=clip_encoder)
    img, mask = _image()
    with pytest.raises(InputError, match="zero-area"):
        d.describe(img, np.zeros_like(mask))
    with pytest.raises(InputError, match="does not match"):
        d.describe(img, mask[:10])
    assert PHRASE.match(d.describe(np.zeros((48, 64), np.uint8), mask))  # grey/black image


class _Server:
    """Loopback OpenAI-compatible endpoint; ``mode`` picks the behaviour of the next requests."""

    def __init__(self) -> None:
        self.mode = "ok"
        self.requests: list[dict] = []
        self.headers: list[dict] = []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args: object) -> None:
                pass

            def do_POST(self) -> None:  # noqa: N802
                body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
                outer.requests.append(body)
                outer.headers.append(dict(self.headers))
                if outer.mode == "error":
                    self.send_response(500)
                    self.end_headers()
                    return
                if outer.mode == "slow":
                    time.sleep(3.0)
                reply = json.dumps(
                    {"choices": [{"message": {"role": "assistant", "content": " A red leather armchair.\n"}}]}
                ).encode()
                try:
                    self.send_response(200)
                    self.send_header("Content-Type", "application/json")
                    self.send_header("Content-Length", str(len(reply)))
                    self.end_headers()
                    self.wfile.write(reply)
                except (BrokenPipeError, ConnectionResetError):  # the client timed out and left
                    pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture
def server() -> Iterator[_Server]:
    s = _Server()
    yield s
    s.close()


def _openai(server_url: str, tmp_path: Path, clip_encoder, **kw):
    return create_describer(
        "openai",
        base_url=server_url,
        api_key="sk-test",
        model="vlm-test",
        cache_dir=tmp_path / "cache",
        encoder=clip_encoder,
        backoff_s=0.01,
        **kw,
    )


def test_openai_success_request_format_and_cache(server: _Server, tmp_path: Path, clip_encoder) -> None:
    d = _openai(server.url, tmp_path, clip_encoder)
    img, mask = _image()
    assert d.describe(img, mask) == "A red leather armchair"
    req = server.requests[0]
    assert req["model"] == "vlm-test"
    parts = req["messages"][0]["content"]
    assert parts[0]["type"] == "text" and "segmented" in parts[0]["text"]
    urls = [p["image_url"]["url"] for p in parts if p["type"] == "image_url"]
    assert len(urls) == 2 and all(u.startswith("data:image/png;base64,") for u in urls)
    full = cv2.imdecode(np.frombuffer(base64.b64decode(urls[0].split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)
    assert full.shape == img.shape
    assert server.headers[0]["Authorization"] == "Bearer sk-test"
    # cache hit: a second describer (same cache dir) does not call the server again
    d2 = _openai(server.url, tmp_path, clip_encoder)
    assert d2.describe(img, mask) == "A red leather armchair"
    assert len(server.requests) == 1 and d2.calls == 0
    # another object is a cache miss
    mask2 = np.zeros_like(mask)
    mask2[5:10, 40:60] = True
    d2.describe(img, mask2)
    assert len(server.requests) == 2


def test_openai_500_retries_then_falls_back(
    server: _Server, tmp_path: Path, clip_encoder, caplog: pytest.LogCaptureFixture
) -> None:
    server.mode = "error"
    d = _openai(server.url, tmp_path, clip_encoder, max_retries=2)
    img, mask = _image()
    offline = create_describer("offline", encoder=clip_encoder).describe(img, mask)
    with caplog.at_level("WARNING"):
        assert d.describe(img, mask) == offline
    assert len(server.requests) == 3
    assert "falling back" in caplog.text and "HTTP 500" in caplog.text
    assert not list((tmp_path / "cache").glob("*.json"))  # failures are not cached


def test_openai_timeout_falls_back(server: _Server, tmp_path: Path, clip_encoder) -> None:
    server.mode = "slow"
    d = _openai(server.url, tmp_path, clip_encoder, max_retries=0, timeout_s=0.3)
    img, mask = _image()
    expected = d.fallback.describe(img, mask)  # warm the fallback so the timing below is the request's
    t0 = time.time()
    assert d.describe(img, mask) == expected
    assert time.time() - t0 < 2.5 and d.calls == 1


def test_openai_unreachable_endpoint_falls_back(tmp_path: Path, clip_encoder) -> None:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # closed again on exit: nothing listens there
    d = _openai(f"http://127.0.0.1:{port}/v1", tmp_path, clip_encoder, max_retries=1)
    img, mask = _image()
    assert PHRASE.match(d.describe(img, mask))
    assert d.calls == 2


def test_openai_env_defaults(monkeypatch: pytest.MonkeyPatch, clip_encoder) -> None:
    monkeypatch.setenv("OPENAI_BASE_URL", "http://127.0.0.1:9/v9/")
    monkeypatch.setenv("OPENAI_API_KEY", "sk-env")
    d = create_describer("openai", encoder=clip_encoder)
    assert d.base_url == "http://127.0.0.1:9/v9" and d.api_key == "sk-env"
