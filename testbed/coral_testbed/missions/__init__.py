"""Missions on a cluster end to end (test and demo tooling): a mission applied with kubectl, its
CoralInstances followed live.

`coral demo` (demo.py) runs a mission on a kind cluster through
`coral_testbed.kind.missions.KindMissionStack`; the mission tests read and feed their missions
through `MissionView` (stack.py).
"""

from coral_testbed.missions.stack import MissionView

__all__ = ["MissionView"]
