#!/usr/bin/env bash
# Builds the pinned control-plane binaries (etcd, kube-apiserver, kube-controller-manager,
# kube-scheduler, kubectl, kwok, helm) and the kubelet the kind node image carries with the go
# tool from Go modules, and caches them outside the repository, keyed by version, so a
# machine pays for the build once. Only missing binaries are built.
#
# Usage: hack/build-control-plane.sh            -> prints the bin directory when done
# Env:   CORAL_CACHE_DIR (default ~/.cache/coral-on-kubernetes)
set -euo pipefail

KUBE_VERSION="${KUBE_VERSION:-v1.34.4}"
ETCD_VERSION="${ETCD_VERSION:-v3.6.4}"
KWOK_VERSION="${KWOK_VERSION:-v0.7.0}"
HELM_VERSION="${HELM_VERSION:-v3.19.0}"

cache_root="${CORAL_CACHE_DIR:-$HOME/.cache/coral-on-kubernetes}"
key="kube-${KUBE_VERSION}_etcd-${ETCD_VERSION}_kwok-${KWOK_VERSION}_helm-${HELM_VERSION}"
bin_dir="$cache_root/control-plane/$key/bin"
wanted=(etcd kube-apiserver kube-controller-manager kube-scheduler kubectl kwok helm kubelet)

have_all() {
  for b in "${wanted[@]}"; do [[ -x "$bin_dir/$b" ]] || return 1; done
}

if have_all; then
  echo "$bin_dir"
  exit 0
fi

command -v go >/dev/null || { echo "error: the go tool is needed to build the control plane" >&2; exit 1; }

mkdir -p "$bin_dir"
work="$cache_root/control-plane/$key/build"
mkdir -p "$work"
export GOFLAGS="-mod=mod"
export CGO_ENABLED=0
log() { echo "[control-plane] $*" >&2; }
staged() { [[ -x "$bin_dir/$1" ]]; }

# The minor version drives the v0.X.Y versions of the published staging modules.
minor="${KUBE_VERSION#v1.}"; minor="${minor%%.*}"
patch="${KUBE_VERSION##*.}"
staging_version="v0.${minor}.${patch}"

kube_module() {
  # One module for every k8s.io/kubernetes command, resolved once and shared by their builds.
  mod="$work/kube"
  [[ -f "$mod/.resolved-with-kubelet" ]] && return 0
  mkdir -p "$mod"
  log "resolving k8s.io/kubernetes ${KUBE_VERSION} (staging modules at ${staging_version})"
  staging=(api apiextensions-apiserver apimachinery apiserver cli-runtime client-go cloud-provider
    cluster-bootstrap code-generator component-base component-helpers controller-manager cri-api
    cri-client csi-translation-lib dynamic-resource-allocation endpointslice externaljwt kms
    kube-aggregator kube-controller-manager kube-proxy kube-scheduler kubectl kubelet metrics
    mount-utils pod-security-admission sample-apiserver sample-cli-plugin sample-controller)
  {
    echo "module coral.dev/controlplane"
    echo
    echo "go 1.24.0"
    echo
    echo "require k8s.io/kubernetes ${KUBE_VERSION}"
    echo
    echo "replace ("
    for s in "${staging[@]}"; do echo "	k8s.io/$s => k8s.io/$s ${staging_version}"; done
    echo ")"
  } > "$mod/go.mod"
  cat > "$mod/tools.go" <<'GO'
//go:build tools

package tools

import (
	_ "k8s.io/kubernetes/cmd/kube-apiserver"
	_ "k8s.io/kubernetes/cmd/kube-controller-manager"
	_ "k8s.io/kubernetes/cmd/kube-scheduler"
	_ "k8s.io/kubernetes/cmd/kubectl"
	_ "k8s.io/kubernetes/cmd/kubelet"
)
GO
  (cd "$mod" && go mod tidy -e >&2 2>"$mod/tidy.log" || true)
  touch "$mod/.resolved-with-kubelet"
}

kube_ldflags() {
  local flags="-s -w"
  for pkg in k8s.io/component-base/version k8s.io/client-go/pkg/version; do
    flags+=" -X $pkg.gitVersion=${KUBE_VERSION} -X $pkg.gitMajor=1 -X $pkg.gitMinor=${minor}"
    flags+=" -X $pkg.gitTreeState=clean -X $pkg.buildDate=1970-01-01T00:00:00Z"
  done
  echo "$flags"
}

if ! (staged kube-apiserver && staged kube-controller-manager && staged kube-scheduler && staged kubectl); then
  kube_module
  log "building kube-apiserver, kube-controller-manager, kube-scheduler, kubectl ${KUBE_VERSION} (first run: 15-30 min on 2 cores)"
  (cd "$work/kube" && go build -trimpath -ldflags "$(kube_ldflags)" -o "$bin_dir/" \
    k8s.io/kubernetes/cmd/kube-apiserver k8s.io/kubernetes/cmd/kube-controller-manager \
    k8s.io/kubernetes/cmd/kube-scheduler k8s.io/kubernetes/cmd/kubectl)
fi

if ! staged kubelet; then
  kube_module
  log "building kubelet ${KUBE_VERSION} (first run: about 4 min on 2 cores)"
  (cd "$work/kube" && go build -trimpath -ldflags "$(kube_ldflags)" -o "$bin_dir/kubelet" k8s.io/kubernetes/cmd/kubelet)
fi

if ! staged etcd; then
  mod="$work/etcd"
  mkdir -p "$mod"
  log "building etcd ${ETCD_VERSION}"
  # etcd's own go.mod points its sibling modules at local folders, so `go install @version`
  # refuses it; requiring it from a module of ours resolves the published siblings instead.
  printf 'module coral.dev/etcd\n\ngo 1.24.0\n\nrequire go.etcd.io/etcd/server/v3 %s\n' "$ETCD_VERSION" > "$mod/go.mod"
  printf '//go:build tools\n\npackage tools\n\nimport _ "go.etcd.io/etcd/server/v3"\n' > "$mod/tools.go"
  (cd "$mod" && go mod tidy -e 2>"$mod/tidy.log" || true)
  (cd "$mod" && go build -trimpath -ldflags "-s -w" -o "$bin_dir/etcd" go.etcd.io/etcd/server/v3)
fi

if ! staged kwok; then
  log "building kwok ${KWOK_VERSION}"
  GOBIN="$bin_dir" go install -trimpath -ldflags "-s -w" "sigs.k8s.io/kwok/cmd/kwok@${KWOK_VERSION}"
fi

if ! staged helm; then
  log "building helm ${HELM_VERSION}"
  GOBIN="$bin_dir" go install -trimpath -ldflags "-s -w -X helm.sh/helm/v3/internal/version.version=${HELM_VERSION}" "helm.sh/helm/v3/cmd/helm@${HELM_VERSION}"
fi

have_all || { echo "error: some control-plane binaries are missing in $bin_dir" >&2; exit 1; }
log "control-plane binaries ready in $bin_dir"
echo "$bin_dir"
