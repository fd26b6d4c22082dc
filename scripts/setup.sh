#!/usr/bin/env bash
# Installs the Debian packages PCR-ORB needs (idempotent). Run as root or with sudo available.
set -euo pipefail
PKGS=(build-essential cmake ninja-build pkg-config
      libopencv-dev libtbb-dev libeigen3-dev libceres-dev libspdlog-dev libfmt-dev
      libgtest-dev libgmock-dev libbenchmark-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev
      libjemalloc-dev
      libdnnl-dev  # oneDNN: the CPU inference executor (--inference onednn)
      python3-onnx python3-numpy)  # tools/yolo_resize.py and its test (ctest yolo_resize)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PKGS[@]} packages present"
  exit 0
fi
echo "setup: installing ${missing[*]}"
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
