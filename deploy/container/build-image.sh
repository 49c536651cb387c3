#!/usr/bin/env bash
# Builds localhost/photonfarm:latest from Debian packages alone (no registry): a minimal Debian 12
# root filesystem with exactly the runtime packages the built binaries link (ldd -> dpkg -S),
# made by mmdebstrap from the configured apt sources, imported into podman as the base, then the
# Containerfile copies the binaries on top.
#
#   deploy/container/build-image.sh [BUILD_DIR]     (default: build; needs root or rootless podman)
#
# Needs: tools/install-deps.sh --container (mmdebstrap, podman, uidmap).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=$(cd "${1:-$here/../../build}" && pwd)
bins=("$build/client/pf" "$build/server/pf-coordinator" "$build/worker/pf-worker")
for b in "${bins[@]}"; do [ -x "$b" ] || { echo "build-image: $b not built" >&2; exit 1; }; done

# The Debian packages owning every shared library the binaries load (usrmerge: try both paths).
packages=$(for lib in $(ldd "${bins[@]}" | awk '/=> \//{print $3}' | sort -u); do
  real=$(readlink -f "$lib")
  dpkg -S "$real" 2> /dev/null || dpkg -S "${real#/usr}" 2> /dev/null || dpkg -S "/usr$real" 2> /dev/null
done | cut -d: -f1 | sort -u | tr '\n' ',')
packages=${packages%,}
echo "build-image: runtime packages: $packages"

ctx=$(mktemp -d)
trap 'rm -rf "$ctx"' EXIT
mmdebstrap --variant=essential --include="$packages,ca-certificates" \
  --customize-hook='mkdir -p "$1/data" "$1/cache" && chown 65534:65534 "$1/data" "$1/cache"' \
  bookworm "$ctx/rootfs.tar"
podman import "$ctx/rootfs.tar" localhost/photonfarm-base:bookworm
cp "${bins[@]}" "$here/Containerfile" "$ctx/"
podman build -t localhost/photonfarm:latest -f "$ctx/Containerfile" "$ctx"
# Smoke test where containers can run (this needs a working OCI runtime and cgroups).
if podman run --rm localhost/photonfarm:latest pf --version; then
  echo "build-image: localhost/photonfarm:latest runs"
else
  echo "build-image: image built, but no container could be started here (OCI runtime/cgroups)" >&2
fi
