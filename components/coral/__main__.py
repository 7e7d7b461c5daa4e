"""Allows `python -m coral`, the same as the `coral` console script."""

from coral_core.command import main

main()
