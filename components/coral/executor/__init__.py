"""The Coral executor: runs one behavior tree with behaviors loaded at runtime from plugins.

Entry points: `python -m coral.executor` / `coral executor` (`cli`), `running.run_executor`.
"""

# The fastest tick rate an executor accepts, wherever a rate is given: `coral executor --rate`, a
# compose file's `x-coral.rate`, a CoralSystem's `tree.tickRateHz`.
MAX_TICK_RATE_HZ = 1000

# How long one node may fail the same way, again and again, before the executor reports that its
# tree makes no progress (`coral executor --no-progress`, a CoralSystem's `tree.noProgressSeconds`).
DEFAULT_NO_PROGRESS_S = 60
