"""Container images from the repository's Dockerfiles, built without a Docker engine or Docker Hub.

buildah builds every Dockerfile (daemonless, chroot isolation) on a Debian base made by mmdebstrap,
skips images whose inputs did not change, and pushes them to a local docker-registry that kubelets
pull from by name. Entry points: `build` (fixtures), `publish` (build into a registry kept
running: `coral images build`, dev-cluster and the demo), `registry` (`start`/`stop` for a
fixture's own registry, `up`/`down` for one kept running), and `catalog`.
"""

from coral_testbed.images import catalog, registry
from coral_testbed.images.building import (
    Built,
    ImageBuildError,
    build,
    builder,
    publish,
    registry_state_dir,
    registry_storage,
)

__all__ = [
    "Built",
    "ImageBuildError",
    "build",
    "builder",
    "catalog",
    "publish",
    "registry",
    "registry_state_dir",
    "registry_storage",
]
