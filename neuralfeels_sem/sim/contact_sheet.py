"""The tactile materials figure: one simulated DIGIT frame per material pressed into a sphere."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.digit_poses import pose_pressing
from neuralfeels_sem.sim.tactile_renderer import DigitRenderer


def contact_sheet(
    path: str | Path,
    materials: tuple[str, ...] = tuple(DEFAULT_MATERIALS),
    radius_m: float = 0.025,
    press_m: float = 1.0e-3,
    seed: int = 0,
    side_views: tuple[str, ...] = ("wood",),
) -> Path:
    """Write a PNG: the no-contact background, then each material pressed into a sphere.

    Each material is pressed at the pole (object z, wood's end grain); the materials in
    `side_views` are pressed on the equator too, where the wood runs along its grain.
    Draws docs/images/tactile_materials.png (shown in docs/simulation.md); also to eyeball realism.
    """
    import trimesh  # only this figure needs a primitive mesh

    mesh = trimesh.creation.icosphere(subdivisions=5, radius=radius_m)
    presses = {
        "": pose_pressing(np.array([0.0, 0.0, radius_m]), np.array([0.0, 0.0, 1.0]), press_m),
        " (side)": pose_pressing(
            np.array([radius_m, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), press_m
        ),
    }
    panels, names = [], ["background"]
    for i, name in enumerate(materials):
        obj = MaterialObject(name, mesh, np.full(len(mesh.faces), i), materials)
        renderer = DigitRenderer(obj, seed=seed)
        if not panels:
            panels.append(renderer.background_image)
        for suffix, world_T_sensor in presses.items():
            if suffix and name not in side_views:
                continue
            panels.append(renderer.render(np.eye(4), world_T_sensor).image)
            names.append(name + suffix)
        renderer.close()
    sheet = np.concatenate(
        [np.pad(p, ((0, 0), (2, 2), (0, 0)), constant_values=255) for p in panels], axis=1
    )
    sheet = np.pad(sheet, ((28, 0), (0, 0), (0, 0)), constant_values=255)
    for i, name in enumerate(names):
        cv2.putText(
            sheet, name, (i * 244 + 8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (0, 0, 0), 1, cv2.LINE_AA
        )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    return path
