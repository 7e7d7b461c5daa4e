"""`python -m coral_skillsets.examples --plugins DIR [--params FILE] [--name NAME]`."""

import sys

from coral.sdk.cli import skillset_command

if __name__ == "__main__":
    sys.argv.insert(1, "coral_skillsets.examples.skillset:ExampleSkillset")
    skillset_command(prog_name="python -m coral_skillsets.examples")
