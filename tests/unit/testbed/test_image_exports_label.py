"""`coral images build` writes the `dev.coral.exports` label preflight reads on every component image
whose component exports a manifest, and does not reuse an image built before it did."""

from __future__ import annotations

import pytest
from coral.local import checking
from coral_core.image_exports import EXPORTS_LABEL
from coral_testbed.images import building, catalog, fingerprints

SPECS = catalog.by_name()


def test_a_component_image_without_its_declaration_is_built_again() -> None:
    skillset = SPECS["slam-skillset"]
    assert not building.is_current(skillset, {fingerprints.LABEL: "f1"}, "f1")
    assert building.is_current(skillset, {fingerprints.LABEL: "f1", EXPORTS_LABEL: "{}"}, "f1")
    assert not building.is_current(skillset, {fingerprints.LABEL: "f0", EXPORTS_LABEL: "{}"}, "f1")


def test_images_that_run_no_exporting_component_need_no_declaration() -> None:
    for name in ("runtime", "executor", "operator"):
        assert building.is_current(SPECS[name], {fingerprints.LABEL: "f1"}, "f1"), name


@pytest.mark.parametrize("name", catalog.COMPONENTS)
def test_the_images_labelled_are_those_whose_component_exports_a_manifest(name: str) -> None:
    """What `coral verify REPOSITORY --print-label` reads in the image: the executor is no plugin."""
    verification = checking.verify_component(SPECS[name].repository)
    assert (verification.manifest is not None) == (name in catalog.EXPORTING), verification.problems
