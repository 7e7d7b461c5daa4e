"""The global map holds every keyframe scan thinned at the map's resolution, whichever way it is
thinned: at the default resolution (half KISS-ICP's voxel) the skillset reuses the scan KISS-ICP
has just thinned for its own local map instead of thinning it a second time."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from coral_skillsets.slam.core import SlamConfig, SlamCore, sanitise
from kiss_icp.kiss_icp import KissICP
from kiss_icp.voxelization import voxel_down_sample
from test_slam_sanitising import _scans


def _expected_map(scans: list[tuple[np.ndarray, np.ndarray | None, int]], config: SlamConfig) -> np.ndarray:
    """The map built the plain way: KISS-ICP's deskewed scan at each keyframe, thinned here."""
    reference, core = KissICP(config=config.kiss_config()), SlamCore(config)
    chunks = []
    for points, times, _stamp in scans:
        clean = sanitise(points, times, deskew=config.deskew)
        frame, _ = reference.register_frame(clean.points, clean.times)
        pose = np.array(reference.last_pose)
        if core._is_keyframe(pose):
            core._keyframe = pose
            thinned = np.asarray(voxel_down_sample(np.asarray(frame), config.map_voxel_size))
            chunks.append(thinned @ pose[:3, :3].T + pose[:3, 3])
    return np.asarray(voxel_down_sample(np.concatenate(chunks), config.map_voxel_size))


def _sorted(points: np.ndarray) -> np.ndarray:
    return points[np.lexsort(points.T[::-1])]


@pytest.mark.parametrize("map_voxel_size", [0.2, 0.5], ids=["kiss-icp-resolution", "own-resolution"])
def test_the_global_map_is_every_keyframe_thinned_at_the_map_resolution(
    short_dataset: Path, map_voxel_size: float
) -> None:
    scans = _scans(short_dataset)
    config = SlamConfig(map_voxel_size=map_voxel_size)
    core = SlamCore(config)
    for points, times, stamp in scans:
        core.process(points, times, stamp)
    built, expected = core.global_map(), _expected_map(scans, config)
    assert len(core._map_chunks) > 1, "the bag should give more than one keyframe"
    assert built.shape == expected.shape
    np.testing.assert_allclose(_sorted(built), _sorted(expected), atol=1e-9)
