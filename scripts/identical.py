"""Check that a refactoring changed no output: scenes, maps, pose files, tables and boards.

``record`` evaluates methods on a suite with the code importable from the working folder (generating
missing scenes), draws the boards and writes a manifest: one content hash per output file, after
removing what differs between two runs of the same code (wall-clock timings, dates, the commit id,
and the map sizes those timings change by a few bytes). ``compare`` prints the files whose hashes
differ and exits 1 if any do. Run ``record`` before and after a change, on the same data folder or on
fresh ones (the scenes are hashed too), then ``compare``.

    python scripts/identical.py record --suite scenes/smoke.yaml --data D --work W --out before.json
    python scripts/identical.py record --scenes val1,val6 --data data/validation --work W2 --out val.json
    python scripts/identical.py compare before.json after.json
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

DEFAULT_METHODS = "openreloc,openreloc-paper,goreloc,sift-pnp,nearest-frame"
TRACKS = ("predicted", "oracle-mask")
# Keys and columns whose values change between two runs of the same code.
VOLATILE = {"finished", "started", "git_commit", "map_bytes", "bytes_on_disk"}
SKIPPED_FILES = {".openreloc-bench.lock"}
CONFIG_KEYS = {"config", "method_config"}


def is_volatile(key: str) -> bool:
    """Timings (every ``*_s`` field), dates, the commit and map sizes."""
    return key in VOLATILE or key.endswith("_s") or key == "map_mb"


def scrub_json(value, in_config: bool = False):
    """The value with every volatile field outside method configs set to 0."""
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            if not in_config and is_volatile(k):
                out[k] = 0
            elif k == "files" and isinstance(v, dict):  # a map manifest: meta.json holds timings
                out[k] = {f: ({} if f.endswith(".json") else e) for f, e in v.items()}
            else:
                out[k] = scrub_json(v, in_config or k in CONFIG_KEYS)
        return out
    if isinstance(value, list):
        return [scrub_json(v, in_config) for v in value]
    return value


def scrub_csv(text: str) -> str:
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        return text
    volatile = [i for i, name in enumerate(rows[0]) if is_volatile(name)]
    for row in rows[1:]:
        for i in volatile:
            if i < len(row) and row[i] != "":
                row[i] = "0"
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()


def scrub_header(text: str) -> str:
    """A pose file without the commit its ``#`` header names."""
    return re.sub(r"^(#.*\bcommit )\S+", r"\g<1>0", text, flags=re.MULTILINE)


def scrub_tree(root: Path) -> None:
    """Rewrite a copied results tree in place without its volatile fields."""
    for path in sorted(root.rglob("*")):
        if path.name in SKIPPED_FILES:
            path.unlink()
        elif path.suffix == ".json":
            path.write_text(json.dumps(scrub_json(json.loads(path.read_text())), indent=1, sort_keys=True))
        elif path.suffix == ".csv":
            path.write_text(scrub_csv(path.read_text()))
        elif path.suffix == ".txt":
            path.write_text(scrub_header(path.read_text()))


def content_hash(path: Path) -> str:
    if path.suffix == ".npz":  # hash the arrays, not the zip container
        h = hashlib.sha256()
        with np.load(path, allow_pickle=False) as z:
            for name in sorted(z.files):
                a = z[name]
                h.update(f"{name}{a.dtype.str}{a.shape}".encode())
                h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()
    return hashlib.sha256(path.read_bytes()).hexdigest()


def hash_tree(root: Path, prefix: str) -> dict[str, str]:
    return {
        f"{prefix}/{p.relative_to(root).as_posix()}": content_hash(p)
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name not in SKIPPED_FILES
    }


def cli(*args: str) -> None:
    """Run ``openreloc-bench`` from the code importable here (PYTHONPATH first), failing loudly."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path.cwd()), os.environ.get("PYTHONPATH", "")]))
    cmd = [sys.executable, "-m", "openreloc_bench.cli", *args]
    done = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if done.returncode != 0:
        sys.exit(f"failed ({done.returncode}): {' '.join(cmd)}\n{done.stdout[-3000:]}")


def record(args: argparse.Namespace) -> None:
    work = Path(args.work)
    if work.exists():
        sys.exit(f"--work {work} exists; give a new folder")
    results, scrubbed = work / "results", work / "scrubbed"
    which = ["--scenes", args.scenes] if args.scenes else ["--suite", args.suite]
    for track in TRACKS:
        cli("eval", *which, "--methods", args.methods, "--data", args.data,
            "--out", str(results), "--track", track, "--resume")  # fmt: skip
    shutil.copytree(results, scrubbed)
    scrub_tree(scrubbed)
    cli("leaderboard", str(scrubbed), "--out", str(work / "board"), "--data", args.data)
    manifest = {
        **hash_tree(Path(args.data), "data"),
        **hash_tree(scrubbed, "results"),
        **hash_tree(work / "board", "board"),
    }
    Path(args.out).write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n")
    print(f"{len(manifest)} files hashed -> {args.out}")


def compare(args: argparse.Namespace) -> None:
    a, b = (json.loads(Path(p).read_text()) for p in (args.a, args.b))
    only_a, only_b = sorted(a.keys() - b.keys()), sorted(b.keys() - a.keys())
    changed = sorted(k for k in a.keys() & b.keys() if a[k] != b[k])
    for label, names in (("only in the first", only_a), ("only in the second", only_b), ("changed", changed)):
        for name in names:
            print(f"{label}: {name}")
    same = len(a.keys() & b.keys()) - len(changed)
    print(f"{same} identical, {len(changed)} changed, {len(only_a)} + {len(only_b)} only on one side")
    sys.exit(1 if changed or only_a or only_b else 0)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("record", help="evaluate, draw the boards, write the manifest")
    r.add_argument("--suite", help="suite YAML")
    r.add_argument("--scenes", help="comma-separated scenes under --data instead of a suite (e.g. val1,val6)")
    r.add_argument("--data", required=True, help="dataset folder (missing scenes are generated)")
    r.add_argument("--work", required=True, help="new folder for results and boards")
    r.add_argument("--out", required=True, help="manifest JSON to write")
    r.add_argument("--methods", default=DEFAULT_METHODS, help=f"methods (default: {DEFAULT_METHODS})")
    c = sub.add_parser("compare", help="compare two manifests")
    c.add_argument("a")
    c.add_argument("b")
    args = p.parse_args()
    if args.command == "record" and not (args.suite or args.scenes):
        p.error("record needs --suite or --scenes")
    record(args) if args.command == "record" else compare(args)


if __name__ == "__main__":
    main()
