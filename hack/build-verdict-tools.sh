#!/usr/bin/env bash
# Builds coral-verdicts (hack/verdicts/main.go): the real kstatus library from
# sigs.k8s.io/cli-utils, gopher-lua (the Lua runtime Argo CD runs health scripts in) and cel-go
# (which Flux evaluates healthCheckExprs with), for the verdict tests. Built with the go tool and
# cached outside the repository, keyed by the pinned versions and the source's hash.
#
# Usage: hack/build-verdict-tools.sh   -> prints the path of the binary when done
# Env:   CORAL_CACHE_DIR (default ~/.cache/coral-on-kubernetes)
set -euo pipefail

CLI_UTILS_VERSION="${CLI_UTILS_VERSION:-v0.37.2}"
GOPHER_LUA_VERSION="${GOPHER_LUA_VERSION:-v1.1.2}"
CEL_GO_VERSION="${CEL_GO_VERSION:-v0.26.0}"
APIMACHINERY_VERSION="${APIMACHINERY_VERSION:-v0.34.4}"

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
source_hash="$(sha256sum "$here/verdicts/main.go" | cut -c1-12)"
key="cli-utils-${CLI_UTILS_VERSION}_gopher-lua-${GOPHER_LUA_VERSION}_cel-go-${CEL_GO_VERSION}_${source_hash}"
dir="${CORAL_CACHE_DIR:-$HOME/.cache/coral-on-kubernetes}/verdict-tools/$key"
binary="$dir/coral-verdicts"
if [[ -x "$binary" ]]; then
  echo "$binary"
  exit 0
fi
command -v go >/dev/null || { echo "error: the go tool is needed to build coral-verdicts" >&2; exit 1; }
work="$dir/build"
mkdir -p "$work"
cp "$here/verdicts/main.go" "$work/main.go"
cat > "$work/go.mod" <<MOD
module coral.dev/verdicts

go 1.24.0

require (
	github.com/google/cel-go ${CEL_GO_VERSION}
	github.com/yuin/gopher-lua ${GOPHER_LUA_VERSION}
	k8s.io/apimachinery ${APIMACHINERY_VERSION}
	sigs.k8s.io/cli-utils ${CLI_UTILS_VERSION}
)
MOD
echo "[verdict-tools] building coral-verdicts (cli-utils ${CLI_UTILS_VERSION}, gopher-lua ${GOPHER_LUA_VERSION}, cel-go ${CEL_GO_VERSION})" >&2
(cd "$work" && GOFLAGS=-mod=mod go mod tidy >&2 && CGO_ENABLED=0 GOFLAGS=-mod=mod go build -trimpath -ldflags "-s -w" -o "$binary.tmp" . >&2)
mv "$binary.tmp" "$binary"
echo "$binary"
