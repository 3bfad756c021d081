#!/usr/bin/env bash
# Installs what Relief needs from Debian 12 packages, skipping what is present
# (pybind11, python3-dev, numpy and pytest build and test the Python bindings; python3-distributed
# runs the sharded build on Dask).
# Idempotent; uses sudo when not root. Set RELIEF_WITH_BENCH=1 to add the peer
# codecs the benchmarks compare against (draco), RELIEF_WITH_FUZZ=1 to add clang
# and its libFuzzer runtime for -DRELIEF_FUZZ=ON (tests/fuzz/README.md; CI
# does not need them: the corpus replays build with g++).
set -euo pipefail

packages=(
  cmake g++ make pkg-config
  libeigen3-dev libopenjp2-7-dev libturbojpeg0-dev liblzma-dev libsqlite3-dev
  catch2 libjbig-dev libnanoflann-dev libpng-dev liblzf-dev libexpat1-dev
  libgeotiff-dev libproj-dev
  pybind11-dev python3-dev python3-numpy python3-pytest python3-distributed
)
if [[ "${RELIEF_WITH_BENCH:-0}" == "1" ]]; then
  packages+=(draco)
fi
if [[ "${RELIEF_WITH_FUZZ:-0}" == "1" ]]; then
  packages+=(clang-14 libclang-rt-14-dev)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

sudo_cmd=()
if [[ $(id -u) -ne 0 ]]; then
  if ! command -v sudo >/dev/null 2>&1; then
    # No sudo (a minimal container or a fresh Debian without it): say exactly
    # what to run as root instead of failing with "sudo: command not found".
    echo "install-deps: missing packages: ${missing[*]}" >&2
    echo "install-deps: not root and sudo is not installed; as root, run:" >&2
    echo "  apt-get update && apt-get install -y --no-install-recommends ${missing[*]}" >&2
    echo "install-deps: then run this script again" >&2
    exit 1
  fi
  sudo_cmd=(sudo)
fi
echo "install-deps: installing ${missing[*]}"
"${sudo_cmd[@]}" apt-get update -qq
DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
