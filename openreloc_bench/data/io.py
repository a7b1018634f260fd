"""Low-level file I/O: atomic writes and strict image/pose readers with one-line errors.

Every writer goes through :func:`atomic_write_bytes` (temp file in the same directory + rename), so
an interrupted run never leaves a half-written file that a resumed run would trust.
"""

from __future__ import annotations

import io as stdio
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from openreloc_bench.errors import DataError

DEPTH_SCALE_MM = 1000.0  # depth PNG stores uint16 millimetres (ScanNet convention)
NO_DEPTH = 65535
"""The uint16 maximum in a depth PNG: no reading, like 0 (7-Scenes marks invalid pixels with it), never a
distance."""


_TEMP_SUFFIX = ".tmp"
_UMASK: int | None = None


def _file_mode() -> int:
    """Permissions of a new file under the process umask (``mkstemp`` alone gives 0600)."""
    global _UMASK
    if _UMASK is None:
        _UMASK = os.umask(0)
        os.umask(_UMASK)
    return 0o666 & ~_UMASK


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` is running (one of another user's counts as running). A zombie (ended,
    not yet reaped by its parent, as a killed eval is until its shell waits on it) is not."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:  # no procfs (not Linux): the signal's answer stands
        return True
    return stat.rpartition(")")[2].split()[:1] != ["Z"]  # the state follows the command name in parentheses


def _writer_alive(temp: Path) -> bool:
    """Whether the process that created an atomic-write temp file (pid in its name) is still running."""
    pid = temp.name[: -len(_TEMP_SUFFIX)].rpartition(".")[2].partition("-")[0]
    return pid.isdigit() and process_alive(int(pid))


def remove_stray_temps(root: Path | str) -> None:
    """Delete the temp files of atomic writes whose writer died before renaming them (SIGKILL skips
    the clean-up in :func:`atomic_write_bytes`); they are never results, so a resumed run starts from a
    clean tree. Temps of a live process (another run writing here) are left alone."""
    for p in Path(root).rglob(f".*{_TEMP_SUFFIX}"):
        if p.is_file() and not _writer_alive(p):
            p.unlink(missing_ok=True)


def atomic_write_bytes(path: Path | str, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: readers see the old file or the new one, never a part.

    The temp file sits next to ``path`` (same file system, so the rename is atomic) and carries the
    writer's pid, so clean-up never removes another live process's file in flight.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{os.getpid()}-", suffix=_TEMP_SUFFIX)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, _file_mode())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: Path | str, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_npy(path: Path | str, array: np.ndarray) -> None:
    """One array as a ``.npy`` file (no pickles), written atomically (:func:`atomic_write_bytes`)."""
    buf = stdio.BytesIO()
    np.save(buf, array, allow_pickle=False)
    atomic_write_bytes(path, buf.getvalue())


def write_json(path: Path | str, obj: Any) -> None:
    """Deterministic JSON (sorted keys, fixed indent) so identical content gives identical bytes."""
    atomic_write_text(path, json.dumps(obj, indent=1, sort_keys=True) + "\n")


def read_json(path: Path | str) -> Any:
    path = Path(path)
    if not path.is_file():
        raise DataError(path, "file not found")
    try:
        return json.loads(read_text(path))
    except json.JSONDecodeError as e:
        raise DataError(path, f"not valid JSON ({e})") from None


def encode_png(image: np.ndarray) -> bytes:
    """PNG bytes of an RGB uint8 (H,W,3), or a single-channel uint8/uint16 image.

    Compression level 1: PNG encoding is the generator's bottleneck, and level 1 trades slightly
    larger files for markedly less CPU.
    """
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:
        raise ValueError("PNG encoding failed")
    return buf.tobytes()


def write_png(path: Path | str, image: np.ndarray) -> None:
    atomic_write_bytes(path, encode_png(image))


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"


def is_complete_png(path: Path | str) -> bool:
    """True when ``path`` is a PNG file that starts with the signature and ends with its IEND chunk
    (cheap: reads 16 bytes; catches missing, truncated and foreign files without decoding)."""
    path = Path(path)
    try:
        with path.open("rb") as f:
            head = f.read(8)
            f.seek(-8, os.SEEK_END)
            return head == _PNG_SIGNATURE and f.read(8) == _PNG_END
    except OSError:
        return False


def _read_raw(path: Path) -> np.ndarray:
    if not path.is_file():
        raise DataError(path, "file not found")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise DataError(path, "unreadable image (corrupt or not an image)")
    return img


def read_rgb(path: Path | str, expect_hw: tuple[int, int] | None = None) -> np.ndarray:
    """RGB uint8 (H,W,3); grey images are expanded, alpha dropped, 16-bit scaled down."""
    path = Path(path)
    img = _read_raw(path)
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2RGB)
    elif img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2RGB)
    else:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    _check_size(path, img, expect_hw)
    return img


def read_depth(path: Path | str, scale: float = DEPTH_SCALE_MM, expect_hw: tuple[int, int] | None = None) -> np.ndarray:
    """Metric depth float32 (H,W) from a uint16 PNG; 0 and :data:`NO_DEPTH` (invalid) become 0.0."""
    path = Path(path)
    img = _read_raw(path)
    if img.ndim != 2 or img.dtype != np.uint16:
        raise DataError(path, f"depth must be a single-channel uint16 PNG, got {img.dtype} with shape {img.shape}")
    _check_size(path, img, expect_hw)
    depth = img.astype(np.float32) / scale
    depth[img == NO_DEPTH] = 0.0
    return depth


def read_instance(path: Path | str, expect_hw: tuple[int, int] | None = None) -> np.ndarray:
    """Instance ids int32 (H,W) from a uint8/uint16 PNG (0 = no instance)."""
    path = Path(path)
    img = _read_raw(path)
    if img.ndim != 2:
        raise DataError(path, f"instance image must be single-channel, got shape {img.shape}")
    _check_size(path, img, expect_hw)
    return img.astype(np.int32)


def depth_to_png(depth_m: np.ndarray, scale: float = DEPTH_SCALE_MM) -> np.ndarray:
    """Metric depth -> uint16 millimetres; NaN, inf, <= 0 and what rounds to :data:`NO_DEPTH` or beyond
    become 0 (invalid)."""
    d = np.nan_to_num(np.asarray(depth_m, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0) * scale
    d = np.where((d > 0) & (d < NO_DEPTH - 0.5), np.round(d), 0)
    return d.astype(np.uint16)


def _check_size(path: Path, img: np.ndarray, expect_hw: tuple[int, int] | None) -> None:
    if expect_hw is not None and img.shape[:2] != tuple(expect_hw):
        raise DataError(path, f"image is {img.shape[1]}x{img.shape[0]}, expected {expect_hw[1]}x{expect_hw[0]}")


def read_text(path: Path | str) -> str:
    """A text file a user gave, as str; DataError if it is missing, binary or not UTF-8.

    A leading UTF-8 byte-order mark (editors on Windows write one) is dropped, so it never becomes
    part of the first name or key; UTF-16 text is named as such rather than called binary.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(path, "file not found")
    data = path.read_bytes()
    if b"\x00" in data:
        binary = "UTF-16 text: save it as UTF-8" if data.startswith((b"\xff\xfe", b"\xfe\xff")) else "binary content"
        raise DataError(path, f"not a text file ({binary})")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise DataError(path, f"not UTF-8 text (byte {e.start}: {e.reason})") from None


def data_lines(path: Path | str) -> Iterator[tuple[int, list[str]]]:
    """(line number, whitespace-split fields) of every non-blank, non-``#`` line of a text file."""
    for lineno, raw in enumerate(read_text(path).splitlines(), 1):
        line = raw.strip()
        if line and not line.startswith("#"):
            yield lineno, line.split()


def read_matrix(path: Path | str, shape: tuple[int, int] = (4, 4)) -> np.ndarray:
    """A whitespace-separated matrix file (ScanNet pose / intrinsic) as float64."""
    path = Path(path)
    text = read_text(path)
    try:
        rows = [line.split() for line in text.splitlines() if line.strip()]
        M = np.array(rows, dtype=np.float64)
    except ValueError:
        raise DataError(path, f"malformed matrix: expected {shape[0]} rows of {shape[1]} numbers") from None
    if M.shape != shape:
        raise DataError(path, f"malformed matrix: expected shape {shape}, got {M.shape}")
    return M


def format_matrix(M: np.ndarray) -> str:
    return "\n".join(" ".join(f"{v:.9g}" for v in row) for row in np.asarray(M)) + "\n"
