"""What the reconcilers must remember between passes: only what they cannot observe (yet).

One `Memory` is made per operator process and handed to both reconcilers; nothing else in the
operator keeps state between passes. It is a set of named parts, one job each, and the one place
that says what is forgotten when the watch reports an object deleted:

- `statuses`, `moved`, `rollouts`: this process's writes the watch has not delivered yet
  (`reconcile.unseen_writes`);
- `creates`, `moves`: creates, deletes and rollout moves the indexes do not show yet
  (`reconcile.expectations`);
- `desired_pods`, `vetted`, `histories`: values too costly to derive on every pass
  (`reconcile.caches`);
- `pacing`: what the pacing of status writes counts from (`reconcile.pacing`);
- `seen`: summaries of the last watch event per object, so that an event that changes nothing a
  pass reads costs no pass (`reconcile.event_filter`);
- `specs`, `verdicts`: tables that keep one copy of what many objects hold (the part of
  CoralInstance specs every robot of a revision shares) or what many passes compute (validation
  results by content hash), each bounded (docs/architecture.md, "The operator's memory").

Each part is thread safe: the queue's workers and kopf's event loop use them at once. Beside it,
the system reconciler keeps what component images declare, by digest (`reconcile.declarations`):
content of registries, not of the cluster, and never forgotten with an object.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from coral_operator.kube.observing import SpecTable
from coral_operator.planning.validation import Verdicts
from coral_operator.reconcile.caches import DesiredPods, RevisionHistories, VettedSpecs
from coral_operator.reconcile.event_filter import EventFilter
from coral_operator.reconcile.expectations import MoveExpectations, WriteExpectations
from coral_operator.reconcile.pacing import WritePacing
from coral_operator.reconcile.unseen_writes import MovedInstances, RolloutWrites, StatusWrites


class Memory:
    """The operator's only state between passes (see the module docstring)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        # The parts that time their entries share the memory's clock, so that tests can move it.
        self.statuses = StatusWrites(clock=clock)
        self.moved = MovedInstances(clock=clock)
        self.rollouts = RolloutWrites()
        self.creates = WriteExpectations(clock=clock)
        """Under an owner's uid: an instance's pods, a system's instances."""
        self.moves = MoveExpectations(clock=clock)
        self.pacing = WritePacing(clock=clock)
        self.desired_pods = DesiredPods()
        self.vetted = VettedSpecs()
        self.histories = RevisionHistories()
        self.seen = EventFilter()
        self.specs = SpecTable()
        self.verdicts = Verdicts()

    def forget_instance(self, uid: str, namespace: str, name: str) -> None:
        """The watch reported the CoralInstance deleted."""
        self.statuses.forget(uid)
        self.pacing.forget(uid)
        self.desired_pods.forget(uid)
        self.creates.forget(uid)
        self.vetted.forget(uid)
        self.moved.forget((namespace, name))

    def forget_system(self, uid: str, namespace: str, name: str) -> None:
        """The watch reported the CoralSystem deleted."""
        self.statuses.forget(uid)
        self.histories.forget((namespace, name, uid))
        self.moves.forget(uid, namespace)
        self.rollouts.forget(uid)
        self.creates.forget(uid)
