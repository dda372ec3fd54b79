"""patchwork and kitchen_tool: shipped objects with no majority material (issue 18).

No material covers more than 45 % of the regions of interest (the labelled faces); every
intended material is there in touchable amounts; seams and flat bottoms are ignored.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.core.digit import GEL_HEIGHT_M, GEL_WIDTH_M
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.library import make_object
from neuralfeels_sem.objects.material_object import IGNORE, MaterialObject

CLASSES = tuple(DEFAULT_MATERIALS)
INTENDED = {
    "patchwork": {"plastic", "metal", "fabric", "wood"},
    "kitchen_tool": {"metal", "wood", "plastic"},
}


def _shares(obj: MaterialObject) -> dict[str, float]:
    """Share of the regions of interest (labelled area) per material."""
    areas = obj.area_by_material()
    roi = sum(a for name, a in areas.items() if name != "ignore")
    return {name: a / roi for name, a in areas.items() if name != "ignore"}


def _patches(obj: MaterialObject, label: int) -> list[np.ndarray]:
    """Face indices of each edge-connected patch of one material."""
    mesh, mask = obj.mesh, obj.face_labels == label
    adjacency = mesh.face_adjacency[mask[mesh.face_adjacency].all(axis=1)]
    return trimesh.graph.connected_components(adjacency, nodes=np.flatnonzero(mask), min_len=1)


@pytest.mark.parametrize("name", sorted(INTENDED))
def test_closed_sized_and_without_a_majority_material(name: str) -> None:
    obj = make_object(name, CLASSES)
    mesh = obj.mesh
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.is_volume
    assert len(mesh.split(only_watertight=False)) == 1
    assert 0.05 <= mesh.extents.max() <= 0.20
    shares = _shares(obj)
    present = {m for m, share in shares.items() if share > 0.0}
    assert present == INTENDED[name]
    # Each material is many fingertips big (>= 15 %), none is the majority (<= 45 %).
    assert min(shares[m] for m in INTENDED[name]) >= 0.15, shares
    assert max(shares.values()) <= 0.45, shares


@pytest.mark.parametrize("name", sorted(INTENDED))
def test_seams_and_the_flat_bottom_are_ignored(name: str) -> None:
    obj = make_object(name, CLASSES)
    mesh, labels = obj.mesh, obj.face_labels
    a, b = mesh.face_adjacency.T
    la, lb = labels[a], labels[b]
    changes = (la != IGNORE) & (lb != IGNORE) & (la != lb)
    assert not changes.any()  # an ignored band always separates two materials
    # The flat face it rests on (facing straight down, at the lowest height) is ignored...
    centres, normals = mesh.triangles_center, mesh.face_normals
    base = (normals[:, 2] < -0.99) & (centres[:, 2] < mesh.bounds[0, 2] + 0.001)
    assert mesh.area_faces[base].sum() > 2e-4  # a real base: over 2 cm^2
    assert (labels[base] == IGNORE).all()
    # ...and so is little else: the regions of interest are most of the surface.
    assert mesh.area_faces[labels == IGNORE].sum() / mesh.area < 0.25


def test_patchwork_has_patches_of_every_size_down_to_one_press() -> None:
    obj = make_object("patchwork", CLASSES)
    mesh = obj.mesh
    areas_cm2 = {
        m: sorted(mesh.area_faces[g].sum() * 1e4 for g in _patches(obj, i))
        for i, m in enumerate(CLASSES)
    }
    every = sorted(a for patches in areas_cm2.values() for a in patches)
    assert every[-1] > 30.0 and every[-1] / every[0] > 10.0  # patches of different sizes
    # At least one patch under 5 cm^2: the metal badge. Not a speck (>= 1.5 cm^2), and a
    # single DIGIT press covers it: its extent across the surface fits in the gel.
    small = [
        g for i in range(len(CLASSES)) for g in _patches(obj, i) if mesh.area_faces[g].sum() < 5e-4
    ]
    assert small
    badge = max(small, key=lambda g: mesh.area_faces[g].sum())
    assert mesh.area_faces[badge].sum() >= 1.5e-4
    assert CLASSES[obj.face_labels[badge[0]]] == "metal"
    points = np.asarray(mesh.vertices[np.unique(mesh.faces[badge])])
    points = points - points.mean(axis=0)
    _, _, axes = np.linalg.svd(points, full_matrices=False)
    extent = np.ptp(points @ axes.T, axis=0)  # longest, across, (depth: the surface's bow)
    assert extent[0] <= GEL_HEIGHT_M and extent[1] <= GEL_WIDTH_M, extent
    # The badge is metal, but metal is not only the badge: a large metal patch as well.
    assert max(areas_cm2["metal"]) > 15.0


def test_kitchen_tool_lies_along_y_head_grip_handle_in_order() -> None:
    obj = make_object("kitchen_tool", CLASSES)
    mesh, labels = obj.mesh, obj.face_labels
    x, y, z = mesh.extents
    assert 0.12 <= y <= 0.15  # the long axis is y
    assert y > 2.5 * x and y > 3.5 * z and x > z  # the head is wider than it is thick
    along = mesh.triangles_center[:, 1]
    index = {m: i for i, m in enumerate(CLASSES)}
    metal, plastic, wood = (along[labels == index[m]] for m in ("metal", "plastic", "wood"))
    # Metal head at +y; the plastic grip band lies between the two wooden parts of the
    # handle (its end and the neck up to the head).
    assert metal.min() > plastic.max() and metal.min() > wood.max()
    assert wood.min() < plastic.min() and plastic.max() < wood.max()
    assert len(_patches(obj, index["plastic"])) == 1 and len(_patches(obj, index["metal"])) == 1
    assert len(_patches(obj, index["wood"])) == 2
    # The head is at the +y end and carries most of the width: wider than the handle.
    head_width = np.ptp(mesh.triangles_center[labels == index["metal"], 0])
    handle_width = np.ptp(mesh.triangles_center[labels == index["wood"], 0])
    assert head_width > 1.3 * handle_width
