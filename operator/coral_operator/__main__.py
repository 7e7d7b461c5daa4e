"""`python -m coral_operator`: the same as `coral operator`."""

from coral_operator.cli import operator_command

operator_command(prog_name="python -m coral_operator")
