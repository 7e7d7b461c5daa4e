"""`python -m coral.sdk.run MODULE:CLASS --plugins DIR [--params FILE] [--name NAME]`."""

from coral.sdk.cli import skillset_command

if __name__ == "__main__":
    skillset_command(prog_name="python -m coral.sdk.run")
