"""`coral crds` prints or writes the CRDs; `coral operator` refuses nothing it should accept."""

from __future__ import annotations

from pathlib import Path

import yaml
from click.testing import CliRunner
from coral_operator.cli import operator_command
from coral_operator.crds_cli import crds_command


def test_coral_crds_prints_both_kinds() -> None:
    result = CliRunner().invoke(crds_command, [])
    assert result.exit_code == 0, result.output
    kinds = [d["spec"]["names"]["kind"] for d in yaml.safe_load_all(result.stdout) if d]
    assert sorted(kinds) == ["CoralInstance", "CoralSystem"]


def test_coral_crds_writes_the_files_kubectl_applies(tmp_path: Path) -> None:
    result = CliRunner().invoke(crds_command, ["-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    committed = Path(__file__).resolve().parents[3] / "crds"
    for path in tmp_path.iterdir():
        assert path.read_text() == (committed / path.name).read_text()


def test_coral_operator_documents_its_options() -> None:
    result = CliRunner().invoke(operator_command, ["--help"])
    assert result.exit_code == 0
    assert "--namespace" in result.output and "--liveness" in result.output
