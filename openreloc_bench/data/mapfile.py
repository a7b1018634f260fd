"""Versioned, checksummed file sets: every on-disk artefact a method loads (maps, weights).

A file set is a directory holding some payload files and ``manifest.json``, written last, with the
format name and version and the sha256 and size of every payload file. Reading checks all of it, so
a truncated, edited or foreign file, or a set written by another format version, fails with a
one-line :class:`~openreloc_bench.errors.DataError` naming the file instead of a traceback deep in a
decoder. Saving the same content twice gives the same bytes (sorted JSON, fixed zip timestamps).

    write_file_set(map_dir, "my-method-map", 1, {"arrays.npz": npz_bytes(arrays), "meta.json": ...})
    blobs = read_file_set(map_dir, "my-method-map", 1, {"arrays.npz", "meta.json"})
    arrays = load_npz(blobs["arrays.npz"], map_dir / "arrays.npz")
"""

from __future__ import annotations

import hashlib
import io as _io
import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from openreloc_bench.data import io
from openreloc_bench.errors import ConfigError, DataError

MANIFEST = "manifest.json"
SOURCE_KEY = "built_from"
ARRAYS = "arrays.npz"
META = "meta.json"


def write_file_set(directory: Path | str, format_name: str, version: int, payload: dict[str, bytes]) -> None:
    """Write ``payload`` (file name -> bytes) atomically into ``directory``, then its manifest."""
    directory = Path(directory)
    for name, data in payload.items():
        io.atomic_write_bytes(directory / name, data)
    io.write_json(directory / MANIFEST, _manifest(format_name, version, payload))


def _manifest(format_name: str, version: int, payload: dict[str, bytes]) -> dict[str, Any]:
    """The manifest of a file set: its format and each file's sha256 and size."""
    return {
        "format": format_name,
        "version": version,
        "files": {n: {"sha256": hashlib.sha256(d).hexdigest(), "bytes": len(d)} for n, d in payload.items()},
    }


def write_arrays(
    directory: Path | str, format_name: str, version: int, arrays: dict[str, np.ndarray], meta: dict[str, Any]
) -> None:
    """The usual map layout as a file set: ``arrays.npz`` and ``meta.json`` (which names the format too)."""
    meta = {**meta, "format": format_name, "version": version}
    write_file_set(directory, format_name, version, {ARRAYS: npz_bytes(arrays), META: json_bytes(meta)})


def read_arrays(directory: Path | str, format_name: str, version: int) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """``(arrays, meta)`` of a set written by :func:`write_arrays`, verified; DataError naming the file."""
    directory = Path(directory)
    blobs = read_file_set(directory, format_name, version, {ARRAYS, META})
    meta = load_json(blobs[META], directory / META)
    check_format(meta, directory / META, format_name, version)
    return load_npz(blobs[ARRAYS], directory / ARRAYS), meta


def read_file_set(
    directory: Path | str, format_name: str, version: int, expected: set[str] | None = None
) -> dict[str, bytes]:
    """The verified payload of a file set (file name -> bytes); DataError on any inconsistency.

    ``expected``: the exact set of payload file names this reader needs (None: whatever is listed).
    """
    directory = Path(directory)
    manifest_path = directory / MANIFEST
    if not directory.is_dir():
        raise DataError(directory, f"not found (expected a {format_name} directory)")
    if not manifest_path.is_file():
        raise DataError(manifest_path, f"missing: no {format_name} here (build it first)")
    manifest = io.read_json(manifest_path)
    check_format(manifest, manifest_path, format_name, version)
    files = manifest.get("files")
    if not isinstance(files, dict) or (expected is not None and set(files) != expected):
        raise DataError(manifest_path, f"manifest must list exactly {', '.join(sorted(expected or ()))}")
    foreign = [n for n in files if n in ("", ".", "..") or Path(n).name != n]
    if foreign:  # a set's files lie in its directory: never read one from elsewhere
        raise DataError(manifest_path, f"lists '{foreign[0]}', which is not a file name in {directory}")
    return {name: _verified_bytes(directory / name, entry) for name, entry in files.items()}


def is_intact(directory: Path | str) -> bool:
    """Whether ``directory`` holds a file set (of any format) whose every listed file matches its
    manifest: a cache checks a stored map before reusing it."""
    directory = Path(directory)
    try:
        files = io.read_json(directory / MANIFEST).get("files")
        for name, entry in files.items():
            if Path(name).name != name or name in ("", ".", ".."):
                return False
            _verified_bytes(directory / name, entry)
    except (DataError, AttributeError, TypeError):
        return False
    return True


def replaceable_files(directory: Path | str) -> list[str]:
    """The files of the file set ``directory`` holds (its manifest first), which a new set may replace;
    none for a missing or empty directory. Dead writers' temp files are removed.

    Anything else in it is refused with a ConfigError: the directory is not a file set (``map --out``
    naming a folder of the user's), or the user's files are mixed into one, or an interrupted build left
    payload files without a manifest; writing there would overwrite files of the same names or count
    foreign bytes as the map's size.
    """
    directory = Path(directory)
    if not directory.is_dir():
        return []
    io.remove_stray_temps(directory)
    entries = {p.name for p in directory.iterdir()}
    manifest = directory / MANIFEST
    listed: set[str] = set()
    if manifest.is_file():
        try:
            doc = io.read_json(manifest)
        except DataError:
            doc = None
        files = doc.get("files") if isinstance(doc, dict) else None
        listed = {n for n in files if isinstance(n, str)} & entries if isinstance(files, dict) else set()
    others = sorted(entries - listed - {MANIFEST})
    if entries and (not manifest.is_file() or others):
        what = f"'{others[0]}'" if others else "files"
        raise ConfigError(
            f"{directory} holds {what} that no {MANIFEST} there lists (not a map, or a damaged one): "
            "remove it or choose a new or empty directory"
        )
    return [MANIFEST, *sorted(listed)] if entries else []


def clear_file_set(directory: Path | str) -> None:
    """Remove the file set ``directory`` holds (:func:`replaceable_files`; refused if it holds anything
    else), the manifest first: a half-cleared set is no longer a set."""
    for name in replaceable_files(directory):
        (Path(directory) / name).unlink(missing_ok=True)


FOREIGN_FORMAT = ("plugin-map", 1)
"""The manifest's format of a map a method wrote in its own format (:func:`record_source`)."""


def record_source(directory: Path | str, source: dict[str, str]) -> None:
    """Note in a written file set's manifest what it was made from (``built_from``: e.g. a map's scene
    and its spec hash), so that a reader can refuse to pair it with something else. A map a method wrote
    without a manifest (a plugin's own format) gets one, listing its files (:data:`FOREIGN_FORMAT`), so
    that it is checked and replaced like any map; one with sub-folders is left as it is."""
    path = Path(directory) / MANIFEST
    if path.is_file():
        doc = io.read_json(path)
        if not isinstance(doc, dict):
            raise DataError(path, "not a file-set manifest")
    else:
        files = sorted(Path(directory).iterdir()) if Path(directory).is_dir() else []
        if not files or not all(p.is_file() and not p.is_symlink() for p in files):
            return
        doc = _manifest(*FOREIGN_FORMAT, {p.name: p.read_bytes() for p in files})  # the files stay as written
    io.write_json(path, {**doc, SOURCE_KEY: source})


def recorded_source(directory: Path | str) -> dict[str, str] | None:
    """What :func:`record_source` noted for this file set (None when nothing was, or there is no manifest)."""
    path = Path(directory) / MANIFEST
    doc = io.read_json(path) if path.is_file() else None
    source = doc.get(SOURCE_KEY) if isinstance(doc, dict) else None
    return source if isinstance(source, dict) else None


def check_format(doc: Any, path: Path, format_name: str, version: int) -> None:
    """DataError unless ``doc`` (a manifest or metadata mapping) names this format and version."""
    if not isinstance(doc, dict) or doc.get("format") != format_name:
        raise DataError(
            path, f"not a {format_name} file (format {doc.get('format') if isinstance(doc, dict) else None!r})"
        )
    if doc.get("version") != version:
        raise DataError(
            path,
            f"{format_name} format version {doc.get('version')!r}, but this openreloc-bench reads version "
            f"{version}: build it again",
        )


def _verified_bytes(path: Path, entry: Any) -> bytes:
    if not path.is_file():
        raise DataError(path, f"file not found (listed in {MANIFEST})")
    data = path.read_bytes()
    if not isinstance(entry, dict) or "sha256" not in entry:
        raise DataError(path.parent / MANIFEST, f"no checksum for {path.name}")
    if len(data) != entry.get("bytes") or hashlib.sha256(data).hexdigest() != entry["sha256"]:
        raise DataError(path, "checksum mismatch: the file is truncated or was modified; build it again")
    return data


def json_bytes(obj: Any) -> bytes:
    """Deterministic JSON bytes (sorted keys, fixed indent)."""
    return (json.dumps(obj, indent=1, sort_keys=True) + "\n").encode()


def load_json(blob: bytes, path: Path) -> Any:
    """Parse verified JSON bytes; DataError naming ``path`` if they are not JSON."""
    try:
        return json.loads(blob.decode("utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DataError(path, f"not valid JSON ({e})") from None


def npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """An ``.npz`` (readable by ``np.load``) with fixed timestamps, so equal arrays give equal bytes."""
    buf = _io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in sorted(arrays):
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            arr = _io.BytesIO()
            np.lib.format.write_array(arr, np.ascontiguousarray(arrays[name]), allow_pickle=False)
            zf.writestr(info, arr.getvalue())
    return buf.getvalue()


def load_npz(blob: bytes, path: Path) -> dict[str, np.ndarray]:
    """Every array of verified ``.npz`` bytes (no pickles); DataError naming ``path`` if malformed."""
    try:
        with np.load(_io.BytesIO(blob), allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (ValueError, OSError, zipfile.BadZipFile) as e:
        raise DataError(path, f"malformed arrays ({type(e).__name__}: {e})") from None
