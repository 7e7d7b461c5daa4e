#!/usr/bin/env bash
# Builds what a kind cluster needs beyond the control-plane binaries of hack/build-control-plane.sh,
# from Go modules (and pause from its C source), cached outside the repository by version:
#   kind                       the CLI (sigs.k8s.io/kind)
#   kubeadm, kube-proxy        from the same pinned k8s.io/kubernetes module as the control plane
#   crictl                     sigs.k8s.io/cri-tools (`kind load` runs it inside the nodes)
#   etcd, coredns              the versions kubeadm 1.34 expects for its static pods and add-ons
#   pause                      gcc -static of build/pause/linux/pause.c shipped in the kubernetes module
# Only missing binaries are built. The node image (hack/build-kind-node-image.sh) copies them in.
#
# Usage: hack/build-kind-tools.sh     -> prints the bin directory when done
# Env:   CORAL_CACHE_DIR (default ~/.cache/coral-on-kubernetes)
set -euo pipefail

KIND_VERSION="${KIND_VERSION:-v0.33.0}"
KUBE_VERSION="${KUBE_VERSION:-v1.34.4}"
CRI_TOOLS_VERSION="${CRI_TOOLS_VERSION:-v1.34.0}"
ETCD_VERSION="${ETCD_VERSION:-v3.6.5}"
COREDNS_VERSION="${COREDNS_VERSION:-v1.12.1}"

cache_root="${CORAL_CACHE_DIR:-$HOME/.cache/coral-on-kubernetes}"
key="kind-${KIND_VERSION}_kube-${KUBE_VERSION}_crictl-${CRI_TOOLS_VERSION}_etcd-${ETCD_VERSION}_coredns-${COREDNS_VERSION}"
bin_dir="$cache_root/kind/tools/$key/bin"
work="$cache_root/kind/tools/$key/build"
wanted=(kind kubeadm kube-proxy crictl etcd coredns pause)

have_all() {
  for b in "${wanted[@]}"; do [[ -x "$bin_dir/$b" ]] || return 1; done
}
if have_all; then
  echo "$bin_dir"
  exit 0
fi

command -v go >/dev/null || { echo "error: the go tool is needed to build kind and the node binaries" >&2; exit 1; }
mkdir -p "$bin_dir" "$work"
export GOFLAGS="-mod=mod"
export CGO_ENABLED=0
log() { echo "[kind-tools] $*" >&2; }
staged() { [[ -x "$bin_dir/$1" ]]; }

# A throwaway module that requires one published module and builds commands from it: modules whose
# own go.mod points siblings at local folders (etcd) refuse `go install @version`, and the
# kubernetes module needs its staging modules pinned.
require_module() {
  local dir="$1" requirement="$2" imports="$3" replaces="${4:-}"
  [[ -f "$dir/.resolved" ]] && return 0
  mkdir -p "$dir"
  {
    printf 'module coral.dev/kindtools\n\ngo 1.24.0\n\nrequire %s\n' "$requirement"
    [[ -n "$replaces" ]] && printf '\nreplace (\n%s)\n' "$replaces"
  } > "$dir/go.mod"
  printf '//go:build tools\n\npackage tools\n\nimport (\n%s)\n' "$imports" > "$dir/tools.go"
  (cd "$dir" && go mod tidy -e 2>"$dir/tidy.log" || true)
  touch "$dir/.resolved"
}

if ! staged kind; then
  log "building kind ${KIND_VERSION}"
  GOBIN="$bin_dir" go install -trimpath -ldflags "-s -w" "sigs.k8s.io/kind@${KIND_VERSION}"
fi

if ! staged crictl; then
  log "building crictl ${CRI_TOOLS_VERSION}"
  GOBIN="$bin_dir" go install -trimpath -ldflags "-s -w -X sigs.k8s.io/cri-tools/pkg/version.Version=${CRI_TOOLS_VERSION}" \
    "sigs.k8s.io/cri-tools/cmd/crictl@${CRI_TOOLS_VERSION}"
fi

if ! staged coredns; then
  log "building coredns ${COREDNS_VERSION}"
  GOBIN="$bin_dir" go install -trimpath -ldflags "-s -w" "github.com/coredns/coredns@${COREDNS_VERSION}"
fi

if ! staged etcd; then
  log "building etcd ${ETCD_VERSION}"
  require_module "$work/etcd" "go.etcd.io/etcd/server/v3 ${ETCD_VERSION}" $'\t_ "go.etcd.io/etcd/server/v3"\n'
  (cd "$work/etcd" && go build -trimpath -ldflags "-s -w" -o "$bin_dir/etcd" go.etcd.io/etcd/server/v3)
fi

minor="${KUBE_VERSION#v1.}"; minor="${minor%%.*}"
patch="${KUBE_VERSION##*.}"
staging_version="v0.${minor}.${patch}"
kube_module() {
  local replaces="" s
  for s in api apiextensions-apiserver apimachinery apiserver cli-runtime client-go cloud-provider \
    cluster-bootstrap code-generator component-base component-helpers controller-manager cri-api \
    cri-client csi-translation-lib dynamic-resource-allocation endpointslice externaljwt kms \
    kube-aggregator kube-controller-manager kube-proxy kube-scheduler kubectl kubelet metrics \
    mount-utils pod-security-admission sample-apiserver sample-cli-plugin sample-controller; do
    replaces+=$'\t'"k8s.io/$s => k8s.io/$s ${staging_version}"$'\n'
  done
  require_module "$work/kube" "k8s.io/kubernetes ${KUBE_VERSION}" \
    $'\t_ "k8s.io/kubernetes/cmd/kubeadm"\n\t_ "k8s.io/kubernetes/cmd/kube-proxy"\n' "$replaces"
}
kube_ldflags() {
  local flags="-s -w" pkg
  for pkg in k8s.io/component-base/version k8s.io/client-go/pkg/version; do
    flags+=" -X $pkg.gitVersion=${KUBE_VERSION} -X $pkg.gitMajor=1 -X $pkg.gitMinor=${minor}"
    flags+=" -X $pkg.gitTreeState=clean -X $pkg.buildDate=1970-01-01T00:00:00Z"
  done
  echo "$flags"
}
if ! (staged kubeadm && staged kube-proxy); then
  kube_module
  log "building kubeadm, kube-proxy ${KUBE_VERSION} (first run: several minutes on 2 cores)"
  (cd "$work/kube" && go build -trimpath -ldflags "$(kube_ldflags)" -o "$bin_dir/" \
    k8s.io/kubernetes/cmd/kubeadm k8s.io/kubernetes/cmd/kube-proxy)
fi

if ! staged pause; then
  kube_module
  source_dir=$(cd "$work/kube" && go list -m -f '{{.Dir}}' k8s.io/kubernetes)
  log "building pause from ${source_dir##*/}/build/pause/linux/pause.c"
  command -v gcc >/dev/null || { echo "error: gcc is needed to build the pause binary" >&2; exit 1; }
  gcc -Os -Wall -Werror -static -DVERSION="v3.10.1-coral" -o "$bin_dir/pause" "$source_dir/build/pause/linux/pause.c"
fi

have_all || { echo "error: some kind tools are missing in $bin_dir" >&2; exit 1; }
log "kind tools ready in $bin_dir"
echo "$bin_dir"
