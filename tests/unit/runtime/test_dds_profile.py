"""Every Coral process points FastDDS at Coral's profile unless the user chose one of their own."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest
from coral.sdk import dds

NS = {"dds": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}


def test_a_process_without_a_profile_gets_corals(tmp_path: Path) -> None:
    environ: dict[str, str] = {}
    assert dds.use_coral_profile(environ, cwd=tmp_path)
    assert environ == {
        "FASTRTPS_DEFAULT_PROFILES_FILE": str(dds.PROFILE),
        "RMW_FASTRTPS_PUBLICATION_MODE": "SYNCHRONOUS",
    }
    assert dds.PROFILE.is_file()


def test_a_users_publication_mode_wins(tmp_path: Path) -> None:
    environ = {"RMW_FASTRTPS_PUBLICATION_MODE": "ASYNCHRONOUS"}
    assert dds.use_coral_profile(environ, cwd=tmp_path)
    assert environ["RMW_FASTRTPS_PUBLICATION_MODE"] == "ASYNCHRONOUS"


@pytest.mark.parametrize("variable", ["FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE"])
def test_a_users_profile_variable_wins(tmp_path: Path, variable: str) -> None:
    environ = {variable: "/etc/robot/dds.xml"}
    assert not dds.use_coral_profile(environ, cwd=tmp_path)
    assert environ == {variable: "/etc/robot/dds.xml"}


def test_fastdds_default_file_in_the_working_directory_wins(tmp_path: Path) -> None:
    (tmp_path / "DEFAULT_FASTRTPS_PROFILES.xml").write_text("<dds/>")
    environ: dict[str, str] = {}
    assert not dds.use_coral_profile(environ, cwd=tmp_path)
    assert environ == {}


def test_writers_announce_unacknowledged_samples_well_within_a_second() -> None:
    root = ElementTree.parse(dds.PROFILE).getroot()
    writers = root.findall("dds:profiles/dds:data_writer[@is_default_profile='true']", NS)
    assert len(writers) == 1
    period = writers[0].find("dds:times/dds:heartbeatPeriod", NS)
    assert period is not None
    seconds = int(period.findtext("dds:sec", "0", NS)) + int(period.findtext("dds:nanosec", "0", NS)) / 1e9
    assert 0 < seconds <= 0.2
