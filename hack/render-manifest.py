"""Renders deploy/coral-operator.yaml, the single-file install (`kubectl apply -f`), from the Helm chart.

Usage: python hack/render-manifest.py [--check] [--helm PATH]
The manifest is `helm template --include-crds` of charts/coral-operator into namespace coral-system,
preceded by that Namespace. --check exits 1 when the committed file differs.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CHART = ROOT / "charts" / "coral-operator"
OUTPUT = ROOT / "deploy" / "coral-operator.yaml"
NAMESPACE = "coral-system"
MANAGED_BY_HELM = "app.kubernetes.io/managed-by: Helm"

HEADER = f"""# Coral operator, single-file install: kubectl apply --server-side -f deploy/coral-operator.yaml
# Rendered from charts/coral-operator by hack/render-manifest.py; do not edit.
apiVersion: v1
kind: Namespace
metadata:
  name: {NAMESPACE}
  labels:
    # The operator's own pod meets Pod Security's restricted level; nothing else runs here.
    pod-security.kubernetes.io/enforce: restricted
    pod-security.kubernetes.io/enforce-version: latest
    pod-security.kubernetes.io/warn: restricted
"""


def find_helm(given: str | None) -> str:
    if given:
        return given
    on_path = shutil.which("helm")
    if on_path:
        return on_path
    from coral_testbed.cluster import binaries

    return str(binaries.find_bin_dir(("helm",)) / "helm")


def render(helm: str) -> str:
    result = subprocess.run(
        [helm, "template", "coral-operator", str(CHART), "--namespace", NAMESPACE, "--include-crds"],
        check=True,
        capture_output=True,
        text=True,
    )
    # `helm template` stamps every object `managed-by: Helm`, but this file is applied with kubectl:
    # Helm would refuse to adopt those objects later, and tools reading the label would be misled.
    lines = [line for line in result.stdout.splitlines(keepends=True) if line.strip() != MANAGED_BY_HELM]
    return HEADER + "".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--check", action="store_true")
    parser.add_argument("--helm")
    args = parser.parse_args()
    text = render(find_helm(args.helm))
    if args.check:
        if not OUTPUT.exists() or OUTPUT.read_text() != text:
            print(f"stale: {OUTPUT.relative_to(ROOT)}; run python hack/render-manifest.py")
            return 1
        return 0
    OUTPUT.write_text(text)
    print(f"wrote {OUTPUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
