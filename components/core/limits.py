"""Limits the robot side and the operator both check, so a value one side accepts the other does too."""

MAX_TICK_RATE_HZ = 1000
"""The fastest tick rate an executor accepts, wherever a rate is given: `coral executor --rate`, a
compose file's `x-coral.rate`, a CoralSystem's `tree.tickRateHz`."""

DEFAULT_NO_PROGRESS_S = 60
"""How long one node may fail the same way, again and again, before the executor reports that its
tree makes no progress (`coral executor --no-progress`, a CoralSystem's `tree.noProgressSeconds`)."""
