"""Thin kopf registrations; importing this package registers every handler with kopf."""

from coral_operator.handlers import indexing, instances, settings, systems, triggers

__all__ = ["indexing", "instances", "settings", "systems", "triggers"]
