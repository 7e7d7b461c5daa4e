"""`python -m coral.executor --tree FILE --plugins DIR [...]`, the same as `coral executor`."""

from coral.executor.cli import executor_command

executor_command(prog_name="python -m coral.executor")
