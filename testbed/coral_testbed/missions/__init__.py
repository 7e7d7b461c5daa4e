"""Missions on the cluster end to end (test and demo tooling): the operator and the robot runner
over a control plane, a mission applied with kubectl, its CoralInstances followed live.

`MissionStack` (stack.py) is what `coral demo` (demo.py) and tests/integration/missions use.
"""

from coral_testbed.missions.stack import MissionStack

__all__ = ["MissionStack"]
