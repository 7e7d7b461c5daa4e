"""Takes what a component built while starting out of the garbage collector's sight.

A started component holds tens of thousands of long-lived objects: rclpy, the message modules,
rosbags' type store, its own node, and for an executor the whole tree. CPython's collector walks
all of them again on every full pass, and a component that streams data (a bag player handing
out a scan per millisecond, a snapshot skillset matching messages) allocates enough to trigger
those passes while a registration needs both cores. Frozen, they are never walked again: on the
SLAM mission this took the bag player from about 0.29 to 0.22 CPU seconds in the timed window,
a third of it having been the collector (docs/architecture.md, "Where the SLAM mission's CPU
goes"). The cost is that a reference cycle among start-up objects that later becomes garbage is
never freed; start-up objects live as long as the process anyway.
"""

from __future__ import annotations

import gc


def freeze_startup_heap() -> None:
    """Collects what start-up left behind, then moves every remaining object to the permanent
    generation; called once, when a component is about to settle into its steady work."""
    gc.collect()
    gc.freeze()
