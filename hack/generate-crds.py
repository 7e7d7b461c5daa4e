"""Writes the CRDs of coral.dev into crds/ and the Helm chart from the pydantic models, and the
executors' admission policy into the chart from `planning.rbac`.

Usage: python hack/generate-crds.py [--check]   (--check: exit 1 when a file is stale)
"""

from __future__ import annotations

import sys
from pathlib import Path

from coral_operator.api import crdgen
from coral_operator.planning import rbac

ROOT = Path(__file__).resolve().parent.parent
TARGETS = [ROOT / "crds", ROOT / "charts" / "coral-operator" / "crds"]
POLICY = ROOT / "charts" / "coral-operator" / "templates" / "executor-policy.yaml"


def main(argv: list[str]) -> int:
    check = "--check" in argv
    stale: list[Path] = []
    for name, manifest in crdgen.build_crds().items():
        text = crdgen.render(manifest)
        for folder in TARGETS:
            path = folder / name
            if path.exists() and path.read_text() == text:
                continue
            stale.append(path)
            if not check:
                folder.mkdir(parents=True, exist_ok=True)
                path.write_text(text)
    policy = rbac.render_admission_policy()
    if not (POLICY.exists() and POLICY.read_text() == policy):
        stale.append(POLICY)
        if not check:
            POLICY.write_text(policy)
    for path in stale:
        print(f"{'stale' if check else 'wrote'}: {path.relative_to(ROOT)}")
    return 1 if check and stale else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
