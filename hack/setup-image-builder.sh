#!/usr/bin/env bash
# Installs what building the project's images needs, from Debian packages: buildah (daemonless
# OCI builder), mmdebstrap (the Debian base's root filesystem), docker-registry (the local
# registry kubelets pull from).
# Idempotent: does nothing when all are installed. Installing needs root.
#
# Usage: sudo bash hack/setup-image-builder.sh
set -euo pipefail

packages=(buildah mmdebstrap docker-registry)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [[ ${#missing[@]} -eq 0 ]]; then
  exit 0
fi
if [[ $(id -u) -ne 0 ]]; then
  echo "error: image builder packages missing (${missing[*]}); installing them needs root:" >&2
  echo "  sudo bash hack/setup-image-builder.sh" >&2
  exit 1
fi
command -v apt-get >/dev/null || { echo "error: apt-get not found; install ${missing[*]} by hand" >&2; exit 1; }
echo "==> Installing ${missing[*]} (Debian packages, about 1 min)" >&2
export DEBIAN_FRONTEND=noninteractive
# dpkg's lock may be held by another installer for a while; apt waits for it.
apt_get=(apt-get -o DPkg::Lock::Timeout=600)
if ! "${apt_get[@]}" install -y --no-install-recommends "${missing[@]}" >/dev/null; then
  "${apt_get[@]}" update -qq
  "${apt_get[@]}" install -y --no-install-recommends "${missing[@]}" >/dev/null
fi
