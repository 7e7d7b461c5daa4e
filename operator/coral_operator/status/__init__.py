"""Pure status helpers: condition types and reasons, transitions, readiness chains."""
