"""No two systems, or (system, robot) pairs, map to one instance, ServiceAccount, ConfigMap or
revision name.

Issue 47, item 9: instance names joined system and robot with `-`, so "a-b" + "c" and "a" + "b-c"
were one CoralInstance and the second system was silently never served; shortened names kept a
name verbatim when it fitted, so a system named exactly like another's shortened form shared its
executor ServiceAccount, and deleting one deleted the other's.
"""

from __future__ import annotations

import string

from coral_operator.planning import naming, revisions
from hypothesis import given, settings
from hypothesis import strategies as st

# Object names (DNS subdomains, as the API server admits a CoralSystem's) built from few letters
# and many dashes, so that the generated pairs often share joins and prefixes.
_LABEL = st.from_regex(r"[ab0]([ab0.-]{0,68}[ab0])?", fullmatch=True)
SYSTEMS = st.one_of(_LABEL, st.from_regex(r"[ab0][ab0-]{40,250}[ab0]", fullmatch=True))
# Robot names are label values: letters, digits, `-`, `_`, `.`, at most 63.
ROBOTS = st.from_regex(r"[aB1]([aB1_.-]{0,61}[aB1])?", fullmatch=True)


def test_the_common_names_stay_as_they_read() -> None:
    assert naming.instance_name("fleet", "robot-1") == "fleet-robot-1"
    assert naming.executor_account_name("fleet") == "coral-executor-fleet"
    assert naming.label_value("fleet") == "fleet"
    assert naming.dns_label("mission") == "mission"


def test_a_join_that_reads_two_ways_is_hashed_for_both() -> None:
    first, second = naming.instance_name("a-b", "c"), naming.instance_name("a", "b-c")
    assert first != second
    assert naming.instance_name("a", "b-c") == "a-b-c"  # the system has no dash: it reads back


def test_a_name_shaped_like_another_systems_shortened_name_is_shortened_too() -> None:
    victim = "v" * 80
    shortened = naming.label_value(victim)
    assert len(shortened) <= 63
    assert naming.label_value(shortened) != shortened
    assert naming.executor_account_name(shortened) != naming.executor_account_name(victim)
    assert naming.dns_label(naming.dns_label(victim)) != naming.dns_label(victim)
    assert naming.instance_name("x", shortened) != naming.instance_name("x", victim)


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(SYSTEMS, ROBOTS), min_size=2, max_size=12, unique=True))
def test_distinct_system_and_robot_pairs_never_share_an_instance_name(pairs: list[tuple[str, str]]) -> None:
    names = [naming.instance_name(system, robot) for system, robot in pairs]
    assert len(set(names)) == len(pairs), list(zip(pairs, names, strict=True))
    assert all(len(name) <= 63 for name in names)


@settings(max_examples=150, deadline=None)
@given(st.lists(SYSTEMS, min_size=2, max_size=12, unique=True))
def test_distinct_systems_never_share_an_account_config_map_or_revision(systems: list[str]) -> None:
    derived = {
        "account": [naming.executor_account_name(s) for s in systems],
        "label": [naming.label_value(s) for s in systems],
        "config map": [naming.config_map_name(s, "tree", "0123456789") for s in systems],
        "revision": [revisions.revision_name(s, "0123456789") for s in systems],
    }
    for kind, names in derived.items():
        assert len(set(names)) == len(systems), (kind, list(zip(systems, names, strict=True)))


@settings(max_examples=100, deadline=None)
@given(st.text(alphabet=string.ascii_lowercase + "-", min_size=1, max_size=300))
def test_a_shortened_name_is_valid_and_never_shortens_to_itself(text: str) -> None:
    label = naming.dns_label(text)
    assert len(label) <= 63 and label[0].isalnum() and label[-1].isalnum()
    assert (label == text) == (naming.dns_label(label) == label)
