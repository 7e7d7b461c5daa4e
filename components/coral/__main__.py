"""Allows `python -m coral`, the same as the `coral` console script."""

from coral.cli import main

main()
