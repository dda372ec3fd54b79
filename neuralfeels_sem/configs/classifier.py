"""Schemas for conf/classifier/ and the classifier tasks (train_classifier, eval_classifier)."""

from __future__ import annotations

from dataclasses import dataclass, field

from neuralfeels_sem.configs.root import TaskConfig
from neuralfeels_sem.perception.classifier.edge_streak import (
    LONG_STREAK,
    SHORT_STREAK,
    check_alone,
    check_streak,
)
from neuralfeels_sem.perception.classifier.gates import (
    check_edge_extent,
    check_label_gates,
    check_patch_reading,
)
from neuralfeels_sem.perception.onnx_cpu import check_cpu_runtime


@dataclass
class EfficientNetClassifierConfig:
    """MaterialClassifier arguments (perception/classifier/infer.py)."""

    _target_: str = "neuralfeels_sem.perception.classifier.MaterialClassifier"
    class_names: list[str] = field(default_factory=list)
    checkpoint: str | None = None  # null = the shipped assets/classifier/classifier.pt
    device: str = "auto"
    min_confidence: float = 0.8
    # No label when more than this share of the contact lies within edge_px of the border.
    max_edge_share: float = 0.5  # 1.0 = off
    # Above 0: an imprint past max_edge_share read confidently keeps its label, trusted
    # this much by the map (TouchLabel.weight; reach as edge_extent) instead of none.
    edge_label_weight: float = 0.0
    # Above 0: an imprint past max_edge_share keeps its label (at full trust) where the same
    # finger named that material at >= edge_streak_confidence on this many frames just
    # before (perception/classifier/edge_streak.py; development objects 91.1 % mean-class
    # against 90.2 % without, three seeds). 0: off.
    edge_streak_frames: int = 2
    edge_streak_confidence: float = 0.99
    # Above 0: a longer streak at a lower bar backs an edge imprint too: this many frames
    # just before, each naming the material at >= edge_long_streak_confidence. A finger
    # sliding over a small part often reads it only at the gel's edge, frame after frame,
    # short of 0.99 (edge_streak.py; development set 91.1 % mean-class against 90.2 %
    # without, 19 of 20 objects >= 80 against 17; docs/classifier.md). 0: off.
    edge_long_streak_frames: int = 4
    edge_long_streak_confidence: float = 0.8
    # Not null: an imprint past max_edge_share read at >= this keeps its label (full trust)
    # on its own. The shipped model is adapted to the rig's edge imprints and reads them
    # right at this confidence nearly always (docs/classifier.md). null: off.
    edge_min_confidence: float | None = 0.99
    # Where a trusted edge imprint's label reaches: the whole imprint | patches (read patch
    # by patch as other touches; a patch naming another material abstains) | centre (only
    # the centroid crop's reach, which that label read). The streaks back the material,
    # not the imprint: development set 91.7 % mean-class with patches or centre against
    # 91.1 % whole, two mapping seeds (docs/classifier.md). patch_spacing_px=0: whole.
    edge_extent: str = "patches"
    edge_px: int = 16
    contact_threshold: float = 30.0
    contact_min_area: float = 0.01
    contact_blur_px: float = 3.0
    background_dir: str | None = None
    first_frame_background: bool = True
    weights: str | None = (
        None  # local ImageNet B0 state dict for training (efficientnet-pytorch layout)
    )
    input_size: int = 224  # training input side in pixels
    # Training only: crop this many native pixels around the contact before resizing
    # (null = the paper's whole-frame resize). A checkpoint records its own crop.
    crop_px: int | None = None
    # Read each touch patch by patch (perception/classifier/patch_reader.py): crops at most this
    # many pixels apart across the imprint, at most max_patches; each contact point takes
    # the nearest confident patch's material. 0: one label for the whole touch. 56 px
    # (half a crop) resolves a border under the imprint to about 4 mm.
    patch_spacing_px: int = 56
    max_patches: int = 8
    # Patches read first, after the centre: the imprint's far ends (farthest-point order).
    # A touch whose centre and these name one material confidently is taken as one
    # material throughout and its other patches are not read (43 % fewer crops on the
    # default run, maps as good: docs/classifier.md). 0: read every patch.
    patch_probe: int = 2
    # A patch past the centroid is centred only where its crop holds at least this share
    # of imprint pixels: a crop on the imprint's rim is half empty gel, unlike the training
    # crops (centred on the contact). 0: centres anywhere on the contact.
    patch_min_contact: float = 0.0
    # A patch naming another material than the touch's own (centre) label needs at least
    # this confidence, else it abstains (at or below min_confidence: off).
    patch_disagree_confidence: float = 0.0
    # On a GPU: replay the forward from CUDA graphs, one launch per batch instead of a few
    # hundred (perception/graphed.py); false runs it eagerly.
    cuda_graphs: bool = True
    # On the CPU: onnxruntime (perception/onnx_cpu.py: about half the time a crop, outputs
    # within float rounding) | torch (the traced model, to the bit of the eager one).
    cpu_runtime: str = "onnxruntime"

    def __post_init__(self) -> None:
        check_cpu_runtime("classifier.cpu_runtime", self.cpu_runtime)
        check_patch_reading(
            self.patch_spacing_px,
            self.max_patches,
            self.patch_probe,
            self.patch_min_contact,
            self.patch_disagree_confidence,
        )
        check_label_gates(
            self.min_confidence, self.max_edge_share, self.edge_px, self.edge_label_weight
        )
        check_streak(SHORT_STREAK, self.edge_streak_frames, self.edge_streak_confidence)
        check_streak(
            LONG_STREAK,
            self.edge_long_streak_frames,
            self.edge_long_streak_confidence,
        )
        check_alone(self.edge_min_confidence)
        check_edge_extent(self.edge_extent)
        if self.contact_threshold <= 0:
            raise ValueError(f"classifier.contact_threshold={self.contact_threshold} must be > 0")
        if not 0.0 < self.contact_min_area < 1.0:
            raise ValueError(
                f"classifier.contact_min_area={self.contact_min_area} must be in (0, 1)"
            )
        if self.contact_blur_px < 0:
            raise ValueError(f"classifier.contact_blur_px={self.contact_blur_px} must be >= 0")
        if self.input_size < 32:
            raise ValueError(f"classifier.input_size={self.input_size} must be >= 32")
        if self.crop_px is not None and not 32 <= self.crop_px <= 240:
            raise ValueError(f"classifier.crop_px={self.crop_px} must be null or in 32..240")


@dataclass
class OracleClassifierConfig:
    """OracleClassifier arguments (perception/classifier/oracle.py): sim ground truth only."""

    _target_: str = "neuralfeels_sem.perception.classifier.OracleClassifier"
    class_names: list[str] = field(default_factory=list)
    min_confidence: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.min_confidence <= 1.0:
            raise ValueError(f"classifier.min_confidence={self.min_confidence} must be in [0, 1]")


@dataclass
class TrainClassifierTaskConfig(TaskConfig):
    """The paper's recipe: 224 px (classifier.input_size), batch 32, AdamW 3e-4, wd 1e-5, patience 10."""

    batch_size: int = 32
    lr: float = 3e-4
    weight_decay: float = 1e-5
    max_epochs: int = 100
    patience: int = 10
    split: list[float] = field(default_factory=lambda: [0.7, 0.15, 0.15])  # train, val, test
    rotation_deg: float = 30.0
    brightness: float = 0.2
    contrast: float = 0.2
    color_gain: float = 0.1
    resume: str = "auto"  # auto (continue when the run dir has last.pt) | never | PATH to a run dir or last.pt
    export_fp16: bool = False  # store classifier.pt in half precision (the shipped asset)
    lr_schedule: str = "constant"  # constant (the paper) | cosine: decay to min_lr_ratio * lr
    min_lr_ratio: float = 0.01
    # Fine-tuning: null trains a new model; `shipped` (assets/classifier/) or a classifier.pt
    # (or its run directory) is trained further, at its own input size and crop.
    init_from: str | None = None
    # Share of dataset.root images in each training epoch when dataset.sim_root is mixed in.
    real_ratio: float = 0.5

    def __post_init__(self) -> None:
        if not 0.0 < self.real_ratio <= 1.0:
            raise ValueError(f"task.real_ratio={self.real_ratio} must be in (0, 1]")
        if self.lr_schedule not in ("constant", "cosine"):
            raise ValueError(f"task.lr_schedule={self.lr_schedule!r} must be constant or cosine")
        if not 0.0 <= self.min_lr_ratio <= 1.0:
            raise ValueError(f"task.min_lr_ratio={self.min_lr_ratio} must be in [0, 1]")
        for name in ("batch_size", "max_epochs", "patience"):
            if getattr(self, name) < 1:
                raise ValueError(f"task.{name}={getattr(self, name)} must be >= 1")
        if self.batch_size < 2:
            raise ValueError(f"task.batch_size={self.batch_size} must be >= 2 (BatchNorm)")
        if self.lr <= 0 or self.weight_decay < 0:
            raise ValueError(
                f"task.lr={self.lr} must be > 0 and task.weight_decay={self.weight_decay} >= 0"
            )
        if len(self.split) != 3 or min(self.split) < 0 or abs(sum(self.split) - 1) > 1e-6:
            raise ValueError(f"task.split={self.split} must be three fractions summing to 1")
        if self.split[0] <= 0 or self.split[1] <= 0:
            raise ValueError(f"task.split={self.split} needs train and validation fractions > 0")
        if self.rotation_deg < 0 or min(self.brightness, self.contrast, self.color_gain) < 0:
            raise ValueError(
                "task augmentation strengths (rotation_deg, brightness, contrast, color_gain) must be >= 0"
            )


@dataclass
class EvalClassifierTaskConfig(TaskConfig):
    batch_size: int = 64

    def __post_init__(self) -> None:
        if self.batch_size < 1:
            raise ValueError(f"task.batch_size={self.batch_size} must be >= 1")


def register(cs) -> None:
    cs.store(group="schema/classifier", name="efficientnet_b0", node=EfficientNetClassifierConfig)
    cs.store(group="schema/classifier", name="oracle", node=OracleClassifierConfig)
    cs.store(group="schema/task", name="train_classifier", node=TrainClassifierTaskConfig)
    cs.store(group="schema/task", name="eval_classifier", node=EvalClassifierTaskConfig)
