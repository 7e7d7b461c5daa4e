"""A local Kubernetes control plane with kwok robots, for tests, demos and development.

Entry points: `Cluster` (a handle used by tests and tooling), `controlplane.start/stop/status`
(processes in a state folder, behind `coral dev-cluster local up|down|status`), and `wait_for`
re-exported from `coral_testbed.waiting`.
"""

from coral_testbed.cluster.binaries import BinariesMissing, find_bin_dir
from coral_testbed.cluster.client import Cluster, KubectlError
from coral_testbed.cluster.controlplane import AlreadyRunning, ControlPlaneError, State, start, status, stop
from coral_testbed.cluster.robots import NOT_READY_ANNOTATION, ROBOT_LABEL
from coral_testbed.waiting import WaitTimeout, wait_for

__all__ = [
    "NOT_READY_ANNOTATION",
    "ROBOT_LABEL",
    "AlreadyRunning",
    "BinariesMissing",
    "Cluster",
    "ControlPlaneError",
    "KubectlError",
    "State",
    "WaitTimeout",
    "find_bin_dir",
    "start",
    "status",
    "stop",
    "wait_for",
]
