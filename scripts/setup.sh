#!/usr/bin/env bash
# Installs the system packages neural-cloth needs on a fresh Debian/Ubuntu machine:
# - Mesa's Vulkan drivers (lavapipe) and the Vulkan loader, so the 3D viewport, screenshots
#   and snapshot tests render on machines without a GPU;
# - the X11/Wayland client libraries that winit opens at run time for the app window;
# - the export tests' reference readers, outside the clone under $NEURAL_CLOTH_TOOLS (default
#   /var/tmp/neural-cloth-tools): the Khronos glTF validator and Pixar's usd-core (pinned).
# Safe to run repeatedly; does nothing when everything is present.
set -euo pipefail

packages=(mesa-vulkan-drivers libvulkan1 libx11-6 libxcursor1 libxrandr2 libxi6 libxkbcommon0 libxkbcommon-x11-0 libwayland-client0 libwayland-cursor0 libegl1)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "setup: installing ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The Khronos glTF validator (npm package gltf-validator), used by the export tests. Node.js
# comes from Debian when it is missing.
tools="${NEURAL_CLOTH_TOOLS:-/var/tmp/neural-cloth-tools}"
if [ ! -f "$tools/node_modules/gltf-validator/package.json" ]; then
  if ! command -v npm >/dev/null 2>&1; then
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends nodejs npm
  fi
  mkdir -p "$tools"
  (cd "$tools" && npm install --silent --no-audit --no-fund gltf-validator@2.0.0-dev.3.10 >/dev/null)
fi

# Pixar's USD library (PyPI usd-core, pinned) in a virtual environment next to the validator,
# used by the USD export tests (tests/usd/read_stage.py reads a bake back, usdchecker checks it).
# Python's venv module comes from Debian when it is missing.
usd_core_version="26.11"
usd_venv="$tools/usd-venv"
if ! "$usd_venv/bin/python" -c "import pxr, importlib.metadata as m, sys; sys.exit(m.version('usd-core') != '$usd_core_version')" >/dev/null 2>&1; then
  if ! python3 -c "import venv, ensurepip" >/dev/null 2>&1; then
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends python3 python3-venv
  fi
  mkdir -p "$tools"
  rm -rf "$usd_venv"
  python3 -m venv "$usd_venv"
  "$usd_venv/bin/python" -m pip install --quiet --disable-pip-version-check "usd-core==$usd_core_version"
fi
