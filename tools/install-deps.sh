#!/usr/bin/env bash
# Installs the Debian 12 packages photonfarm needs, if any are missing. Idempotent and quick
# when everything is present. Uses sudo only when not already root.
#   tools/install-deps.sh           what building, running and testing need
#   tools/install-deps.sh --bench   also what the benchmark reports need (plots: matplotlib)
#   tools/install-deps.sh --slurm   also Slurm and munge (deploy/slurm/slurm_array_test.sh)
#   tools/install-deps.sh --container  also mmdebstrap and podman (deploy/container/)
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libembree-dev libopenexr-dev libspdlog-dev libfmt-dev libtbb-dev libtinyobjloader-dev
  libtinygltf-dev  # glTF 2.0 scenes (header-only tiny_gltf.h; uses nlohmann-json and stb)
  libgtest-dev libgmock-dev libcli11-dev nlohmann-json3-dev libpng-dev
  libnanoflann-dev
  libstb-dev  # image files: .hdr, .png, .jpg (common/image/image_file.cpp)
  # The farm: gRPC, Protobuf, SQLite, and the Python client.
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc libsqlite3-dev sqlite3
  libssl-dev  # SHA-256 of scene bundles (OpenSSL EVP)
  openssl     # deploy/make-credentials.sh and the TLS e2e tests make certificates with the openssl CLI
  python3 python3-grpcio python3-protobuf
  # The deployment recipes' test (tests/deploy): compose.yaml read with PyYAML, units checked by
  # systemd-analyze (nothing is started by systemd).
  python3-yaml systemd
  iproute2  # the multi-host test (tests/deploy/multihost_test.py): `ip netns`, veth, a bridge
  # Fuzzing the MGF parser (libFuzzer lives in clang's runtime).
  clang libclang-rt-14-dev
  # Formatting check of the test command (tools/check-format.sh): Debian 12 ships version 14.
  clang-format
  # The coordinator's web status page (cpp-httplib) and its test in headless Chromium.
  libcpp-httplib-dev chromium
)
for option in "$@"; do
  case "$option" in
    --bench) PACKAGES+=(python3-matplotlib) ;;
    # deploy/slurm/slurm_array_test.sh: a one-node Slurm cluster with munge on this machine.
    --slurm) PACKAGES+=(slurm-wlm munge) ;;
    # deploy/container/build-image.sh: a Debian root filesystem imported into podman.
    --container) PACKAGES+=(mmdebstrap podman uidmap) ;;
    *) echo "install-deps: unknown option $option (--bench, --slurm, --container)" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
