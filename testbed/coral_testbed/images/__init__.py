"""Container images from the repository's Dockerfiles, built without a Docker engine or Docker Hub.

buildah builds every Dockerfile (daemonless, chroot isolation) on a Debian base made by mmdebstrap,
skips images whose inputs did not change, and pushes them to a local docker-registry that kubelets
pull from by name. Entry points: `build` (fixtures, the demo, `coral images build`), `registry`
(`start`/`stop` for a fixture's own registry, `up`/`down` for one kept running), and `catalog`.
"""

from coral_testbed.images import catalog, registry
from coral_testbed.images.building import Built, ImageBuildError, build, builder, registry_storage

__all__ = ["Built", "ImageBuildError", "build", "builder", "catalog", "registry", "registry_storage"]
