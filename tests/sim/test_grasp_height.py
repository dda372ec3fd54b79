"""sensor.grasp_height=follow: a long object lying flat rests low between the fingers."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.sim.hand_model import PALM_FACE_X
from neuralfeels_sem.sim.rig import SimRig
from tests.sim.shapes import CLASSES

SECONDS = 6.0


@pytest.fixture(scope="module")
def runs():
    """A 4 x 18 x 4 cm bar along y, both ways, over the default two-axis motion."""
    mesh = trimesh.creation.box(extents=(0.04, 0.18, 0.04))
    mesh = mesh.subdivide().subdivide()
    bar = MaterialObject("bar", mesh, np.zeros(len(mesh.faces), int), CLASSES)
    out = {}
    for height in ("fixed", "follow"):
        rig = SimRig(bar, alternate_axis=(0.0, 1.0, 0.0), grasp_height=height, seed=0)
        states = [rig.state_at(i / 10) for i in range(int(SECONDS * 10))]
        out[height] = (rig, states)
    return bar, out


def lowest_clearance(bar: MaterialObject, rig: SimRig, t: float) -> float:
    """How far the bar's lowest point lies above the palm face at time t (metres)."""
    palm = rig.scene.world_T_palm
    up = palm[:3, 0]
    pose = rig.trajectory.pose(t)
    world = np.asarray(bar.mesh.vertices) @ pose[:3, :3].T + pose[:3, 3]
    return float((world @ up).min() - (palm[:3, 3] + PALM_FACE_X * up) @ up)


def test_the_bar_rests_lower_and_never_reaches_into_the_palm(runs) -> None:
    bar, out = runs
    fixed, follow = out["fixed"][0], out["follow"][0]
    assert follow.centre @ follow.scene.world_T_palm[:3, 0] < (
        fixed.centre @ fixed.scene.world_T_palm[:3, 0] - 0.02
    )
    clearances = [lowest_clearance(bar, follow, t) for t in np.arange(0.0, SECONDS, 0.1)]
    assert min(clearances) > 0.0
    # lying flat at the start it rests as low as the room allows, not above it
    assert clearances[0] < lowest_clearance(bar, fixed, 0.0) - 0.02


def test_more_fingers_touch_the_bar_when_it_rests_low(runs) -> None:
    _, out = runs
    touching = {
        height: np.mean([sum(s.touching.values()) for s in states])
        for height, (_, states) in out.items()
    }
    assert touching["follow"] > 1.3 * touching["fixed"], touching


def test_an_unknown_grasp_height_is_refused() -> None:
    mesh = trimesh.creation.box(extents=(0.04, 0.04, 0.04))
    cube = MaterialObject("cube", mesh, np.zeros(len(mesh.faces), int), CLASSES)
    with pytest.raises(ValueError, match="grasp_height='low'"):
        SimRig(cube, grasp_height="low")


def test_finger_contacts_bench_measures_either_grasp_height(tmp_path, capsys) -> None:
    from neuralfeels_sem.bench.finger_contacts import main

    out = tmp_path / "contacts.json"
    argv = ["--objects", "random:109", "--no-render", "--duration", "1", "--json", str(out)]
    main([*argv, "--grasp-height", "follow"])
    report = json.loads(out.read_text())[0]
    assert report["object"] == "random_109" and report["frames"] == 10
    with pytest.raises(SystemExit):
        main([*argv, "--grasp-height", "low"])
    assert "invalid choice: 'low'" in capsys.readouterr().err
