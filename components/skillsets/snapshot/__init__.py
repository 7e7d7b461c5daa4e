"""Snapshot skillset: the latest or time-synchronised messages of configured topics, saved on request."""
