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


def test_coral_operator_refuses_a_metrics_address_without_a_port_before_starting() -> None:
    for value in ("0.0.0.0", "localhost:http", ":8081", "0.0.0.0:70000"):
        result = CliRunner().invoke(operator_command, ["--metrics", value])
        assert result.exit_code == 2, (value, result.output)
        assert "--metrics" in result.output and "ADDRESS:PORT" in result.output
