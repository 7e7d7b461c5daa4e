"""Control-plane side of Coral on Kubernetes: API models, planning, status and kopf handlers."""
