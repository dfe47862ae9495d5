#!/usr/bin/env bash
# Installs the Debian 12 packages rayfarm builds against, only those missing.
# Idempotent and quiet when everything is present; needs root (or sudo) otherwise.
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libembree-dev libopenimageio-dev libpng-dev libtbb-dev
  libzmq3-dev cppzmq-dev nlohmann-json3-dev
  libcli11-dev doctest-dev python3-matplotlib
  libcpp-httplib-dev zlib1g-dev
  # only for the status page's browser test (tests/browser/)
  chromium chromium-driver python3-selenium
  # only for the fuzz targets (fuzz/: libFuzzer needs clang); the build itself uses gcc
  clang libclang-rt-14-dev
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "rayfarm: installing missing packages: ${missing[*]}"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
