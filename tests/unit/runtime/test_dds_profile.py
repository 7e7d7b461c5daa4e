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


def test_a_process_that_publishes_large_messages_gets_the_large_data_profile(tmp_path: Path) -> None:
    environ: dict[str, str] = {}
    assert dds.use_coral_profile(environ, cwd=tmp_path, large_messages=True)
    assert environ["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(dds.LARGE_DATA_PROFILE)
    assert environ["RMW_FASTRTPS_PUBLICATION_MODE"] == "SYNCHRONOUS"


def test_a_users_builtin_transports_keep_the_default_segment(tmp_path: Path) -> None:
    environ = {"FASTDDS_BUILTIN_TRANSPORTS": "LARGE_DATA"}
    assert dds.use_coral_profile(environ, cwd=tmp_path, large_messages=True)
    assert environ["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(dds.PROFILE)
    assert environ["FASTDDS_BUILTIN_TRANSPORTS"] == "LARGE_DATA"


def test_the_bag_player_asks_for_the_large_segment_and_other_components_only_when_they_say_so() -> None:
    from coral.sdk import Driver, Skillset
    from coral_drivers.bag_player.driver import BagPlayer

    assert BagPlayer.LARGE_MESSAGES
    assert not Driver.LARGE_MESSAGES and not Skillset.LARGE_MESSAGES


def test_the_large_data_profile_keeps_udp_for_other_hosts_beside_its_larger_segment() -> None:
    root = ElementTree.parse(dds.LARGE_DATA_PROFILE).getroot()
    kinds = {
        descriptor.findtext("dds:transport_id", "", NS): descriptor
        for descriptor in root.findall("dds:profiles/dds:transport_descriptors/dds:transport_descriptor", NS)
    }
    participant = root.find("dds:profiles/dds:participant[@is_default_profile='true']/dds:rtps", NS)
    assert participant is not None
    used = [kinds[name.text or ""] for name in participant.findall("dds:userTransports/dds:transport_id", NS)]
    assert sorted(descriptor.findtext("dds:type", "", NS) for descriptor in used) == ["SHM", "UDPv4"]
    shm = next(descriptor for descriptor in used if descriptor.findtext("dds:type", "", NS) == "SHM")
    assert int(shm.findtext("dds:segment_size", "0", NS)) >= 8 * 1024 * 1024
    assert participant.findtext("dds:useBuiltinTransports", "", NS) == "false"


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


@pytest.mark.parametrize("profile", [dds.PROFILE, dds.LARGE_DATA_PROFILE], ids=["default", "large-data"])
def test_writers_announce_unacknowledged_samples_well_within_a_second(profile: Path) -> None:
    root = ElementTree.parse(profile).getroot()
    writers = root.findall("dds:profiles/dds:data_writer[@is_default_profile='true']", NS)
    assert len(writers) == 1
    period = writers[0].find("dds:times/dds:heartbeatPeriod", NS)
    assert period is not None
    seconds = int(period.findtext("dds:sec", "0", NS)) + int(period.findtext("dds:nanosec", "0", NS)) / 1e9
    assert 0 < seconds <= 0.2


def test_the_large_data_profile_carries_the_default_profiles_writer_settings_unchanged() -> None:
    """FastDDS reads one profile file, so the large-data profile repeats the default's writer
    settings; this keeps the copy from drifting."""

    def settings(element: ElementTree.Element) -> tuple[object, ...]:
        # Comments and indentation aside: tags, attributes, values, in order.
        children = tuple(settings(child) for child in element)
        return element.tag, sorted(element.attrib.items()), (element.text or "").strip(), children

    def writers(profile: Path) -> list[tuple[object, ...]]:
        return [
            settings(writer)
            for writer in ElementTree.parse(profile).getroot().iter(f"{{{NS['dds']}}}data_writer")
        ]

    assert writers(dds.PROFILE)
    assert writers(dds.LARGE_DATA_PROFILE) == writers(dds.PROFILE)
