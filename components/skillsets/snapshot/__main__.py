"""`python -m coral_skillsets.snapshot --plugins DIR [--params FILE] [--name NAME]`."""

import sys

from coral.sdk.cli import skillset_command

if __name__ == "__main__":
    sys.argv.insert(1, "coral_skillsets.snapshot.skillset:SnapshotSkillset")
    skillset_command(prog_name="python -m coral_skillsets.snapshot")
