"""The executor's Kubernetes status sink (robot side; imports no kopf)."""
