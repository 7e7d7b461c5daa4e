"""`python -m coral.offline boot|watch ...`, the same as `coral offline-agent`."""

from coral.offline.cli import offline_agent_command

offline_agent_command(prog_name="python -m coral.offline")
