"""The rig's own touches as a labelled tactile set: what the classifier sees in `task=map`.

`task=collect_tactile` presses each DIGIT against chosen material points; the rig's
finger-gaiting policy instead touches wherever its fingers land, often with tilted pads
whose imprints are strips along the sensor edge. This runs the rig on shipped objects,
or generated development objects (`random_K`, K below 1000: `--generated 20-59`),
exactly as `sensor=sim` does by default (same motion and seeds, so the same DIGIT
backgrounds and frames) and writes every frame in contact (the classifier's contact
gate) whose ground-truth material is at least `min_purity` one class, in the ImageFolder layout
`<root>/<sensor>/<material>/<object>_<seed>_<frame>.png` that `task=eval_classifier`
reads, with `_backgrounds/<sensor>.png` and `touches.json` (every gated touch: object,
frame, finger, majority class, purity, contact pixels, edge share, whether it was written,
how many patch crops were).
`--keep-every E O` thins the set for training: an edge imprint (edge share above the
classifier's default max_edge_share) is written on every E-th frame, any other touch on
every O-th (the rig's frames follow each other closely, so neighbours are near copies).
`--mixed-patches P` also writes, on every P-th frame, what the classifier's patch reading
sees of an imprint that straddles materials (not an edge imprint; purity below
`min_purity`): a crop at each of its patch centres (perception/classifier/patches.py, the
classifier's default spacing), named `<object>_<seed>_<frame>_p<k>.png` and labelled with
the material within half the patch spacing of the centre where that is `min_purity` one
class. Pure touches alone teach the model nothing about where a border lies under a press.

    python -m neuralfeels_sem.bench.rig_touches data/tactile/rig_seed0 --seed 0
    python run.py task=eval_classifier dataset.root=data/tactile/rig_seed0

Not a training set for runs with the same seed: these are the very frames a map run sees.
"""

from __future__ import annotations

import argparse
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from neuralfeels_sem.configs.classifier import EfficientNetClassifierConfig
from neuralfeels_sem.configs.sensor_sim import SimSensorConfig
from neuralfeels_sem.core.hand import FINGERS
from neuralfeels_sem.core.materials import DEFAULT_MATERIALS
from neuralfeels_sem.objects.library import make_object
from neuralfeels_sem.objects.material_object import MaterialObject
from neuralfeels_sem.objects.procedural import RECIPES
from neuralfeels_sem.objects.random_object import development_seeds, make_random_object
from neuralfeels_sem.perception.classifier.patches import crop_around, patch_centres
from neuralfeels_sem.perception.contact import ContactGate, edge_share
from neuralfeels_sem.sim.backgrounds import finger_seed
from neuralfeels_sem.sim.rig import SimRig

CLASSES = tuple(DEFAULT_MATERIALS)
# The classifier's default edge band, and the share of it above which a touch is an edge imprint.
EDGE_PX = EfficientNetClassifierConfig.edge_px
MAX_EDGE_SHARE = EfficientNetClassifierConfig.max_edge_share
GENERATED = re.compile(r"random_(\d+)")  # object=random object.seed=K, named random_K
# Patch crops as the classifier reads them: its default spacing, and the shipped
# checkpoint's crop side (its meta "crop_px"; a test keeps the two equal).
PATCH_SPACING_PX = EfficientNetClassifierConfig.patch_spacing_px
MAX_PATCHES = EfficientNetClassifierConfig.max_patches
CROP_PX = 112
MIN_PATCH_CONTACT_PX = 200  # labelled contact pixels a patch's centre disc needs


@dataclass(frozen=True)
class WriteRule:
    """Which touches are written: pure ones (`min_purity`) on the frames `keep_every`
    (edge imprints, other touches) keeps; mixed ones as patch crops every `patch_every`-th
    frame (0: never)."""

    min_purity: float = 0.95
    keep_every: tuple[int, int] = (1, 1)
    patch_every: int = 0

    def __post_init__(self) -> None:
        if not 0.5 <= self.min_purity <= 1.0:
            raise ValueError(f"--min-purity {self.min_purity} must be in [0.5, 1]")
        if min(self.keep_every) < 1:
            raise ValueError(
                f"--keep-every {self.keep_every[0]} {self.keep_every[1]}: both must be >= 1"
            )
        if self.patch_every < 0:
            raise ValueError(f"--mixed-patches {self.patch_every} must be >= 0 (0: off)")


def build_object(name: str, classes: Sequence[str]) -> MaterialObject:
    """A shipped object by name, or generated development object K as `random_K`."""
    generated = GENERATED.fullmatch(name)
    if generated is None:
        if name not in RECIPES:
            raise ValueError(
                f"object {name!r} is neither a shipped object ({', '.join(sorted(RECIPES))}) "
                "nor a generated one (random_K)"
            )
        return make_object(name, tuple(classes))
    (seed,) = development_seeds(generated.group(1))
    return make_random_object(seed, tuple(classes))


def _write_rgb(path: Path, image: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))


def _majority(out, num_classes: int) -> tuple[int, float] | None:
    """The majority ground-truth class under the contact mask and its share (None: no labels)."""
    labels = out.material[out.contact_mask]
    labels = labels[labels >= 0]
    if labels.size == 0:
        return None
    counts = np.bincount(labels, minlength=num_classes)
    label = int(counts.argmax())
    return label, float(counts[label] / labels.size)


def _patch_crops(out, mask: np.ndarray, rule: WriteRule) -> list[tuple[int, np.ndarray]]:
    """(label, crop) at each patch centre of a mixed imprint whose centre disc (half the
    patch spacing) is `min_purity` one ground-truth material; other centres are skipped."""
    truth = np.where(out.contact_mask, out.material, -1)
    rows, cols = np.nonzero(truth >= 0)
    materials = truth[rows, cols]
    crops = []
    for centre in patch_centres(mask, PATCH_SPACING_PX, MAX_PATCHES):
        near = (rows - centre[0]) ** 2 + (cols - centre[1]) ** 2 <= (PATCH_SPACING_PX / 2) ** 2
        if near.sum() < MIN_PATCH_CONTACT_PX:
            continue
        counts = np.bincount(materials[near])
        if counts.max() >= rule.min_purity * near.sum():
            crops.append((int(counts.argmax()), crop_around(out.image, centre, CROP_PX)))
    return crops


def _frame_touches(
    root: Path,
    name: str,
    seed: int,
    i: int,
    state,
    renderers: dict,
    gate: ContactGate,
    classes: Sequence[str],
    rule: WriteRule,
) -> list[dict]:
    """Render frame i on every DIGIT; record each gated touch, write the pure ones on
    the frames the rule keeps and the mixed ones' patch crops where it asks for them."""
    records = []
    for finger, renderer in renderers.items():
        out = renderer.render(state.world_T_object, state.world_T_sensor[finger])
        mask = gate.mask(out.image, renderer.background_image)
        if mask.mean() < gate.min_area:
            continue
        majority = _majority(out, len(classes))
        if majority is None:
            continue
        label, purity = majority
        share = edge_share(mask, EDGE_PX)
        at_edge = share > MAX_EDGE_SHARE
        stride = rule.keep_every[0] if at_edge else rule.keep_every[1]
        write = purity >= rule.min_purity and i % stride == 0
        stem = f"{name}_{seed}_{i:04d}"
        mixed = not at_edge and purity < rule.min_purity
        patch_frame = rule.patch_every > 0 and i % rule.patch_every == 0
        patches = _patch_crops(out, mask, rule) if mixed and patch_frame else []
        for k, (patch_label, crop) in enumerate(patches):
            _write_rgb(root / finger / classes[patch_label] / f"{stem}_p{k}.png", crop)
        records.append(
            {
                "object": name,
                "frame": i,
                "finger": finger,
                "material": classes[label],
                "purity": round(purity, 4),
                "contact_px": int(out.contact_mask.sum()),
                "edge_share": round(share, 4),
                "written": write,
                "patches": len(patches),
            }
        )
        if write:
            _write_rgb(root / finger / classes[label] / f"{stem}.png", out.image)
    return records


def collect(
    root: str | Path,
    objects: Sequence[str],
    seed: int = 0,
    frames: int = 100,
    fps: float = 10.0,
    classes: Sequence[str] = CLASSES,
    rule: WriteRule = WriteRule(),
) -> list[dict]:
    """Write the rig's labelled touches under `root`; returns one record per gated touch."""
    from neuralfeels_sem.sim.tactile_renderer import DigitRenderer

    root = Path(root)
    built = [build_object(name, classes) for name in objects]  # bad names fail before any work
    gate = ContactGate()
    records: list[dict] = []
    progress = tqdm(total=len(objects) * frames, desc="rig touches", unit="frame")
    motion = SimSensorConfig().rig_motion()  # the default sensor=sim motion
    for name, obj in zip(objects, built, strict=True):
        rig = SimRig(obj, seed=seed, **motion)
        rig.open()
        renderers = {f: DigitRenderer(obj, seed=finger_seed(seed, f)) for f in FINGERS}
        try:
            for finger, renderer in renderers.items():
                _write_rgb(root / "_backgrounds" / f"{finger}.png", renderer.background_image)
            for i in range(frames):
                state = rig.state_at(i / fps)
                records += _frame_touches(
                    root, name, seed, i, state, renderers, gate, classes, rule
                )
                progress.update(1)
        finally:
            for renderer in renderers.values():
                renderer.close()
    progress.close()
    (root / "touches.json").write_text(json.dumps(records, indent=1))
    return records


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", help="output folder (ImageFolder layout)")
    parser.add_argument(
        "--objects",
        nargs="*",
        default=None,
        help="shipped objects, or generated development objects as random_K (K below 1000); "
        "default: every shipped object unless --generated is given",
    )
    parser.add_argument(
        "--generated", default=None, help="add generated development objects K, e.g. 20-59"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frames", type=int, default=100, help="frames per object (10 fps)")
    parser.add_argument("--min-purity", type=float, default=0.95)
    parser.add_argument(
        "--keep-every",
        nargs=2,
        type=int,
        default=(1, 1),
        metavar=("EDGE", "OTHER"),
        help="write edge imprints on every EDGE-th frame and other touches on every OTHER-th",
    )
    parser.add_argument(
        "--mixed-patches",
        type=int,
        default=0,
        metavar="P",
        help="write patch crops of imprints straddling materials on every P-th frame (0: off)",
    )
    args = parser.parse_args(argv)
    objects = list(args.objects or ([] if args.generated else sorted(RECIPES)))
    try:
        if args.generated is not None:
            objects += [f"random_{k}" for k in development_seeds(args.generated)]
        rule = WriteRule(args.min_purity, tuple(args.keep_every), args.mixed_patches)
        records = collect(args.root, objects, args.seed, args.frames, rule=rule)
    except ValueError as exc:
        parser.error(str(exc))
    shares = np.array([r["edge_share"] for r in records]) if records else np.zeros(1)
    written = sum(r["written"] for r in records)
    patches = sum(r["patches"] for r in records)
    print(
        f"{len(records)} touches in contact, {written} written to {args.root} "
        f"(and {patches} patch crops); "
        f"edge share median {np.median(shares):.2f}, > 0.35 in {(shares > 0.35).mean():.0%}"
    )


if __name__ == "__main__":
    main()
