#!/usr/bin/env bash
# Installs a Docker engine from Debian (`docker.io`: dockerd, containerd, runc) where `dockerd` is
# missing, for kind. Idempotent: with dockerd present, apt is not run at all. The package does not
# start dockerd (Debian's policy-rc.d forbids it in containers); the project starts its own dockerd
# per run (testbed/coral_testbed/kind/engine.py, docs/kind.md).
#
# Usage: hack/setup-docker.sh            -> installs what is missing (needs root)
#        hack/setup-docker.sh --check    -> exit 0 if dockerd is installed, else 1
set -euo pipefail

if command -v dockerd >/dev/null; then
  exit 0
fi
if [[ "${1:-}" == "--check" ]]; then
  echo "missing: dockerd (Debian package docker.io)" >&2
  exit 1
fi
if [[ $(id -u) -ne 0 ]]; then
  echo "error: kind needs a Docker engine; installing Debian's docker.io needs root." >&2
  echo "       run: sudo bash hack/setup-docker.sh" >&2
  exit 1
fi

export DEBIAN_FRONTEND=noninteractive
# A lock held by another apt run is waited for rather than failed on. The package lists are
# refreshed once, before the install, so a stale list never names a version the mirror dropped.
apt_get() { apt-get -o DPkg::Lock::Timeout=600 "$@"; }
apt_get update -q
apt_get install -y -q --no-install-recommends docker.io
