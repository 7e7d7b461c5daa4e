"""Limits the robot side and the operator both check, so a value one side accepts the other does too."""

MAX_TICK_RATE_HZ = 1000
"""The fastest tick rate an executor accepts, wherever a rate is given: `coral executor --rate`, a
compose file's `x-coral.rate`, a CoralSystem's `tree.tickRateHz`."""
