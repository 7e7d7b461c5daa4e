"""Fixtures shared by every test folder; each lives in its own module under tests/fixtures/."""

pytest_plugins = [
    "fixtures.ros",
    "fixtures.processes",
    "fixtures.operator",
    "fixtures.cluster",
    "fixtures.images",
    "fixtures.robots",
    "fixtures.prometheus",
]
