#!/usr/bin/env bash
# Installs, with apt, the Debian packages that the kind node image and the image pipeline need on
# this machine. Idempotent: packages already installed are left alone and apt is not run at all.
# Needs root (apt-get install); says so and exits 1 when it is not root and something is missing.
#
# Usage: hack/setup-node-runtime.sh            -> installs what is missing
#        hack/setup-node-runtime.sh --check    -> exit 0 if everything is installed, else 1 (no root needed)
set -euo pipefail

# One list per purpose, so each purpose's packages can change without touching the others.

# The kind node image and tests: a throwaway containerd (with runc and ctr) preloads the node
# image's images, iptables-save shows the kind tests left the host's rules alone, busybox-static is
# the busybox test image the kind tests load into their nodes.
node_packages=(containerd runc iptables busybox-static)

# Images, built from the repository's Dockerfiles without a Docker engine: buildah (daemonless OCI
# builder), mmdebstrap (the Debian base's root filesystem), docker-registry (the local registry the
# kubelets pull from).
image_packages=(buildah mmdebstrap docker-registry)

# Metrics: Debian's prometheus package brings `prometheus` and `promtool`, which the tests run on
# the shipped alert rules and dashboard queries (docs/metrics.md). Only the binaries are used; on a
# host run by systemd the package also enables its own server on port 9090, which
# `systemctl disable --now prometheus` turns off.
metrics_packages=(prometheus)

wanted=("${node_packages[@]}" "${image_packages[@]}" "${metrics_packages[@]}")

missing=()
for package in "${wanted[@]}"; do
  status=$(dpkg-query -W -f='${db:Status-Status}' "$package" 2>/dev/null || true)
  [[ "$status" == "installed" ]] || missing+=("$package")
done

if [[ ${#missing[@]} -eq 0 ]]; then
  exit 0
fi
if [[ "${1:-}" == "--check" ]]; then
  echo "missing Debian packages: ${missing[*]}" >&2
  exit 1
fi
if [[ $(id -u) -ne 0 ]]; then
  echo "error: the Debian packages ${missing[*]} are missing; installing them needs root." >&2
  echo "       run: sudo bash hack/setup-node-runtime.sh" >&2
  exit 1
fi

echo "[node-runtime] installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
# A lock held by another apt run is waited for rather than failed on.
apt_get() { apt-get -o DPkg::Lock::Timeout=600 "$@"; }
# The package lists are refreshed first: a stale list names versions the mirror no longer has.
apt_get update -q >&2
apt_get install -y -q --no-install-recommends "${missing[@]}" >&2
