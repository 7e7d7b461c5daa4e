"""kind clusters for Coral: the Docker engine, the node image, clusters of robots and their faults.

`provisioning` installs and caches what kind needs, `clusters` creates and deletes clusters with
one worker per robot, `faults` acts on a robot's node container; `coral dev-cluster` is the CLI
(docs/kind.md).
"""
