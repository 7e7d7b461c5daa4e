"""Where one robot's pull of a revision's images stands, read from its pre-pull pod (`planning.prepull`).

Apart from `planning.prepull` so that the rollout's checks can name a robot's pull without importing
the pre-pull's planning, which uses theirs. Pure.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

from coral_operator.planning.observed import ObservedPod

PULL_ROLE = "prepull"
"""`coral.dev/role` of a pre-pull pod; the instance pass leaves such pods to the system pass."""
PULL_COMMAND = ("true",)
"""What each pre-pull container runs: nothing. An image without `true` fails to start, which still
proves the image is on the robot."""


class PullState(StrEnum):
    """Where one robot's pull of the target revision's images stands."""

    ABSENT = "Absent"
    """No pre-pull pod for the revision yet."""
    PULLING = "Pulling"
    """The pod exists and not every container has started."""
    PULLED = "Pulled"
    """Every container has run, so every image is on the robot."""
    FAILED = "Failed"
    """The kubelet cannot pull an image, or the robot cannot run the pod; `message` says why."""


@dataclass(frozen=True)
class Pull:
    """One robot's pull, as its pre-pull pod shows it."""

    state: PullState = PullState.ABSENT
    message: str = ""


def read_pull(pods: Sequence[ObservedPod], revision: str) -> Pull:
    """Where the pull of `revision`'s images stands on a robot, from its instance's pods."""
    mine = [p for p in pods if p.role == PULL_ROLE and p.revision == revision and not p.deleting]
    if not mine:
        return Pull()
    pod = mine[0]
    problem = pod.image_problem or pod.unschedulable
    if problem:
        return Pull(PullState.FAILED, problem)
    # Containers run one after another's pull; the pod ends only once each image was there to start.
    if pod.phase in ("Succeeded", "Failed"):
        return Pull(PullState.PULLED)
    return Pull(PullState.PULLING)


def read_pulls(pods: Sequence[ObservedPod]) -> dict[str, Pull]:
    """Where the pull of each revision with a pre-pull pod stands on a robot."""
    return {p.revision: read_pull(pods, p.revision) for p in pods if p.role == PULL_ROLE and not p.deleting}
