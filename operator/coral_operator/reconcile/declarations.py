"""What component images declare they export, read from their registries for the system passes.

The reconciler reads, `planning.preflight` decides. Only images of the registries the operator is
told to read (`CORAL_PREFLIGHT_REGISTRIES`) are read; the others are left to the robot, as before
preflight. Labels are kept by digest (`coral_core.image_labels`), and what a tag resolved to is
kept for `TAG_SECONDS`, so a pass over a hundred robots on five images asks the registry nothing
most of the time; a registry that failed is not asked again for `FAILED_SECONDS`, so it costs a
pass at most its timeout once in a while. Thread safe: the queue's workers share one.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from coral_core import image_exports, image_labels

from coral_operator.planning.preflight import ImageTable

TAG_SECONDS = 60.0
"""How long what an image reference resolved to is used before its registry is asked again."""
FAILED_SECONDS = 30.0
READ_BUDGET_SECONDS = 5.0
"""The longest one pass spends reading declarations; what is left unread is checked on the robot."""
ANY_REGISTRY = "*"


@dataclass
class ImageDeclarations:
    registries: frozenset[str] = frozenset()
    """Registry hosts (`host[:port]`) read from; `*` for every one; empty reads none."""
    labels: image_labels.ImageLabels = field(default_factory=image_labels.ImageLabels)
    clock: Callable[[], float] = time.monotonic
    _lock: threading.Lock = field(default_factory=threading.Lock, init=False, repr=False)
    _known: dict[str, tuple[float, image_exports.ImageExports | None | str]] = field(
        default_factory=dict, init=False, repr=False
    )

    def wanted(self, image: str) -> bool:
        if not self.registries:
            return False
        return (
            ANY_REGISTRY in self.registries or image_labels.parse_reference(image).registry in self.registries
        )

    def read(self, images: Iterable[str]) -> ImageTable:
        """The declarations of `images` (those of the registries read), each at most so old."""
        exports: dict[str, image_exports.ImageExports | None] = {}
        unread: dict[str, str] = {}
        started = self.clock()
        for image in images:
            if not self.wanted(image):
                continue
            hit, found = self._recent(image)
            if not hit:
                if self.clock() - started > READ_BUDGET_SECONDS:
                    unread[image] = "no time left in this pass"
                    continue
                found = self._read(image)
            if isinstance(found, str):
                unread[image] = found
            else:
                exports[image] = found
        return ImageTable(exports=exports, unread=unread)

    def _recent(self, image: str) -> tuple[bool, image_exports.ImageExports | None | str]:
        """(whether `image` was read recently enough, what was read)."""
        with self._lock:
            known = self._known.get(image)
        if known is None:
            return False, None
        at, value = known
        fresh = FAILED_SECONDS if isinstance(value, str) else TAG_SECONDS
        return self.clock() - at < fresh, value

    def _read(self, image: str) -> image_exports.ImageExports | None | str:
        value: image_exports.ImageExports | None | str
        try:
            _, labels = self.labels.labels(image)
            value = image_exports.from_labels(labels, image)
        except (image_labels.LabelsError, image_exports.ExportsError) as error:
            value = str(error)
        with self._lock:
            self._known[image] = (self.clock(), value)
        return value
