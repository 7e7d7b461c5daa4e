"""The robot runner: the kubelet of simulated robots, for tests and demos (docs/robot-runner.md).

`RobotRunner` runs the pods bound to chosen robot Nodes as local processes, each robot in its own
network namespace on a shared bridge, and reports pod and Node status to the API.
"""

from coral_testbed.runner.runner import RobotRunner, base_environment

__all__ = ["RobotRunner", "base_environment"]
