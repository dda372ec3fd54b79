"""The rig's fingers reach every material of the objects without a majority material.

patchwork and kitchen_tool place their materials where the fingers reach as the default
sensor=sim motion turns the object (5 s about z, then 5 s about y): in the motion's first
10 s (100 frames, seed 0) each material is under a touching finger's contact point in
several frames. The rig alone, no rendering: about 3 s per object.
"""

from __future__ import annotations

import pytest

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.library import make_object
from tests.sim.touch_counts import touched_materials

CLASSES = tuple(DEFAULT_MATERIALS)
MATERIALS = {
    "patchwork": {"plastic", "metal", "fabric", "wood"},
    "kitchen_tool": {"metal", "wood", "plastic"},
}


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_default_run_touches_every_material(name: str) -> None:
    touched, rig = touched_materials(make_object(name, CLASSES), CLASSES)
    # Measured (seed 0): patchwork 42-84 finger-frames per material, kitchen_tool 53-88.
    assert all(touched[m] >= 15 for m in MATERIALS[name]), touched
    assert touched.keys() <= MATERIALS[name] | {"ignore"}
    rig.scene.step(200)  # and the scene with this object steps cleanly
    assert rig.scene.warning_count == 0
