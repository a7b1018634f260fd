#!/usr/bin/env bash
# One-command set-up on a bare Debian machine (run as root, or with sudo available).
# Installs the Debian packages for offscreen OpenGL (EGL, OSMesa fallback), open3d and headless Chromium, then a
# virtual environment at .venv/ with torch 2.13.0 (CPU) and this project. Idempotent: a second run
# only checks and returns in seconds.
set -euo pipefail
cd "$(dirname "$0")/.."
EXTRAS="${OPENRELOC_EXTRAS:-dev}"

# chromium + its driver: the boards' screenshots and the test that sorts a board's column in a real browser
debs=(libegl1 libgl1 libgl1-mesa-dri libegl-mesa0 libosmesa6 libusb-1.0-0 libgomp1 chromium chromium-driver)
missing=()
for p in "${debs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "[setup] installing Debian packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

PY="${PYTHON:-python3}"
[ -x .venv/bin/python ] || "$PY" -m venv .venv
stamp=".venv/.openreloc-setup-$(cat pyproject.toml scripts/setup.sh | sha256sum | cut -c1-16)-$EXTRAS"
if [ ! -f "$stamp" ]; then
  .venv/bin/pip install -q --upgrade pip
  # torch first and exactly: a looser spec resolves to the newest CUDA build (gigabytes).
  .venv/bin/pip install -q torch==2.13.0
  # open3d-cpu replaces the full open3d on Linux x86-64 and installs the same package: remove the full
  # build first (afterwards, uninstalling it would delete the files the CPU build shares with it)
  if [ "$(uname -sm)" = "Linux x86_64" ] && .venv/bin/pip show -q open3d >/dev/null 2>&1; then
    .venv/bin/pip uninstall -q -y open3d
  fi
  # (setuptools warns on every editable install that a folder named like a package may shadow it)
  PYTHONWARNINGS="ignore:Editable installation" .venv/bin/pip install -q -e ".[${EXTRAS}]"
  rm -f .venv/.openreloc-setup-*
  touch "$stamp"
fi
echo "[setup] ready: $(.venv/bin/openreloc-bench --version 2>/dev/null || echo 'openreloc-bench installed')"
