"""Real scanned YCB meshes (../shared/data/ycb) load through object=custom."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.custom import load_custom_object

CLASSES = tuple(DEFAULT_MATERIALS)
YCB = ("FoamBrick", "MasterChefCan", "MustardBottle", "PowerDrill", "TomatoSoupCan")


@pytest.mark.parametrize("name", YCB)
def test_ycb_mesh_loads_as_one_material(shared_data: Path, name: str) -> None:
    path = shared_data / "ycb" / name / "model.obj"
    if not path.is_file():
        pytest.skip(f"{path} is absent")
    obj = load_custom_object(str(path), CLASSES, material="metal", rescale_to=0.08, name=name)
    assert obj.name == name
    assert obj.mesh.is_watertight and obj.mesh.is_volume
    np.testing.assert_allclose(obj.mesh.extents.max(), 0.08)
    np.testing.assert_allclose(obj.mesh.bounds.mean(axis=0), 0.0, atol=1e-9)
    assert (obj.face_labels == CLASSES.index("metal")).all()
    assert obj.mass_kg > 0
