"""Pure planning: from a spec and the observed state to manifests and decisions (no API calls)."""
