# The two commands a user needs are `make demo` and `make test`; everything else supports them.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo demo-local demo-cluster test test-images venv control-plane node-runtime images verdict-tools lint crds bench bench-bt bench-calls bench-slam bench-fleet bench-writes kind test-kind-setup

$(STAMP): pyproject.toml setup.py constraints.txt
	@echo "==> Creating $(VENV) and installing the project with its robot and test extras (first run: about 1-2 min)"
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PY) -m pip install --disable-pip-version-check -q --upgrade pip
	@$(PY) -m pip install --disable-pip-version-check --progress-bar off -q -c constraints.txt -e '.[robot,test]'
	@touch $(STAMP)

venv: $(STAMP)

# Builds etcd, kube-apiserver, kube-controller-manager, kube-scheduler, kubectl, kwok, helm and the
# kubelet from Go modules on first use; cached under ~/.cache/coral-on-kubernetes by version.
control-plane:
	@bash hack/build-control-plane.sh >/dev/null

# containerd, runc and busybox-static for the kind node image and tests, and buildah, mmdebstrap
# and docker-registry for the images, from Debian (needs root; without root it only reports what is
# missing, and the tests that need kind or images are skipped).
node-runtime:
	@if [ "$$(id -u)" -eq 0 ]; then bash hack/setup-node-runtime.sh; \
	else bash hack/setup-node-runtime.sh --check || echo "==> not root: kind and image tests will be skipped"; fi

# What kind clusters need, installed where missing and cached (docs/kind.md): a Docker engine from
# Debian, kind and the node binaries from Go modules, and the node image (built locally where
# kindest/node cannot be pulled; first build about 8 min). Needs root.
kind: venv node-runtime control-plane
	@$(VENV)/bin/coral dev-cluster setup

# Every image from the repository's Dockerfiles, pushed to the local registry (docs/images.md).
images: venv node-runtime
	@$(VENV)/bin/coral images build

# The images the tests run, built before pytest (with progress) so a first build of about five
# minutes counts against no test's timeout; the tests' fixtures then find them unchanged and only
# push them to their session's registry. Skipped where images cannot be built (the tests say why).
test-images: venv node-runtime
	@if [ "$$(id -u)" -eq 0 ] && command -v buildah >/dev/null && command -v mmdebstrap >/dev/null; then \
		echo "==> images (unchanged ones are not rebuilt)"; \
		$(VENV)/bin/coral images build --no-push || echo "==> the image build failed; the tests that need images will say why"; fi

# coral-verdicts: kstatus, Argo CD's Lua runtime and Flux's CEL for the verdict tests (docs/verdicts.md);
# the tests build it on first use too. Cached under ~/.cache/coral-on-kubernetes by version.
verdict-tools:
	@bash hack/build-verdict-tools.sh >/dev/null

# The SLAM mission on a kind cluster (docs/kind.md): images, a robot worker, the operator by Helm,
# kubectl apply; the cluster and the project's dockerd are gone afterwards.
demo: venv control-plane node-runtime kind
	@$(VENV)/bin/coral demo

# The same mission on one machine, no cluster: `coral run` with a live tree view.
demo-local: venv
	@$(VENV)/bin/coral slam-demo

# The control-plane tour: robots as kwok Nodes, a pod pinned to one of them.
demo-cluster: venv control-plane
	@$(VENV)/bin/coral dev-cluster local demo

# What the kind test (tests/integration/kind) needs, made before pytest so that the node image's
# first build (about 8 min) counts against no test's timeout; where it cannot be made, that test
# says why. Leaves nothing running.
test-kind-setup: venv node-runtime control-plane
	@if [ "$$(id -u)" -eq 0 ]; then \
		$(VENV)/bin/coral dev-cluster setup || echo "==> kind setup failed; the kind test will say why"; fi

test: venv control-plane node-runtime verdict-tools test-images test-kind-setup
	@echo "==> ruff"
	@$(VENV)/bin/ruff check .
	@echo "==> pytest, in two lanes: the kind folder beside the rest (tests/conftest.py)"
	@$(PY) -m pytest -n 2 -m "not quiet" --durations=25
	@echo "==> pytest: the tests that measure speed, on a machine left to them"
	@$(PY) -m pytest -m quiet

lint: venv
	@$(VENV)/bin/ruff check .

# Regenerates crds/ and the chart's CRDs from the pydantic models, then the single-file manifest.
crds: venv
	@$(PY) hack/generate-crds.py
	@$(PY) hack/render-manifest.py

bench: bench-bt bench-calls bench-slam bench-fleet bench-writes

# `make bench PLOT=figures` also writes the fleet and SLAM figures as PNGs into figures/;
# `make bench-fleet SIZES=100` runs the fleet benchmark at 100 robots only (default 100 500 1000);
# `LAYOUT=PodPerRobot` measures that layout alone against its reference; the fleet runs on a kind
# cluster named `KIND_NAME` (default fleet-bench), or with `CLUSTER=local` on the testbed's own
# control plane (no root or Docker engine needed); `BASELINE=DIR` also measures the operator of
# the checkout DIR (with its own .venv) against this one (docs/performance.md);
# `PAIRS=1` one pair of runs at the largest size instead of three.
bench-fleet bench-writes: control-plane
bench-fleet: $(if $(filter local,$(CLUSTER)),,node-runtime)
bench-bt bench-calls bench-slam bench-fleet bench-writes: venv
	@f=benchmarks/bench_$(subst bench-,,$@).py; if [ -f $$f ]; then $(PY) $$f $(if $(and $(PLOT),$(filter bench-fleet bench-slam,$@)),--plot $(PLOT)) $(if $(filter bench-fleet,$@),$(SIZES) $(if $(LAYOUT),--layout $(LAYOUT)) $(if $(CLUSTER),--cluster $(CLUSTER)) $(if $(KIND_NAME),--kind-name $(KIND_NAME)) $(if $(BASELINE),--baseline $(BASELINE)) $(if $(PAIRS),--pairs $(PAIRS))); else echo "$$f: not written yet"; fi
