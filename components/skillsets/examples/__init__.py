"""A small example skillset used by tests, benchmarks and docs/skillsets.md.

`skillset.ExampleSkillset` (the ROS side) exports the behaviors in `behaviors` (the tree side).
Run it with `python -m coral_skillsets.examples --plugins DIR`.
"""
