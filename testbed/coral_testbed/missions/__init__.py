"""Missions on the cluster end to end (test and demo tooling): the operator by Helm and real robots
over a control plane, a mission applied with kubectl, its CoralInstances followed live.

`MissionStack` (stack.py) is what `coral demo` (demo.py) runs; the mission tests read and feed
their missions through `MissionView`.
"""

from coral_testbed.missions.stack import MissionStack, MissionView

__all__ = ["MissionStack", "MissionView"]
