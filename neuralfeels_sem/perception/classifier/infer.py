"""The material classifier the mapper calls: tactile readings in, TouchLabels out.

    clf = MaterialClassifier(class_names=["plastic", "metal", "fabric", "wood"])
    labels = clf.classify([frame.tactile[f] for f in frame.tactile])  # one TouchLabel each

The checkpoint loads on first use (the constructor does no I/O). Each frame is first
gated for contact against its sensor's no-contact background; only contact frames are
classified. A prediction whose top probability is below `min_confidence` is returned
as `label=-1, low_confidence=True` instead of being forced to a class.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import torch

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.core.frame import TactileReading
from neuralfeels_sem.perception.classifier.checkpoint import ClassifierCheckpoint, load_checkpoint
from neuralfeels_sem.perception.classifier.edge_streak import LONG_STREAK, EdgeStreak
from neuralfeels_sem.perception.classifier.gates import check_edge_extent, check_label_gates
from neuralfeels_sem.perception.classifier.inference import inference_model
from neuralfeels_sem.perception.classifier.model import build_model
from neuralfeels_sem.perception.classifier.patch_reader import PatchReader
from neuralfeels_sem.perception.classifier.predict import predict_probs
from neuralfeels_sem.perception.classifier.transforms import preprocess, resize_batch
from neuralfeels_sem.perception.contact import ContactGate, edge_share
from neuralfeels_sem.perception.onnx_cpu import check_cpu_runtime
from neuralfeels_sem.perception.touch import NO_LABEL, TouchLabel
from neuralfeels_sem.utils.device import resolve_device
from neuralfeels_sem.utils.paths import ASSETS_DIR

log = logging.getLogger(__name__)

SHIPPED_CHECKPOINT = ASSETS_DIR / "classifier" / "classifier.pt"


class MaterialClassifier:
    """EfficientNet-B0 material classifier with a background-difference contact gate.

    class_names: the config's `materials`; must equal the checkpoint's class list.
    checkpoint: a `classifier.pt`; None means the shipped one (assets/classifier/).
    min_confidence: below this top probability a touch gets no label.
    max_edge_share, edge_px: a touch with more than this share of its contact pixels within
        `edge_px` of the sensor's border (an imprint cut off by the edge, typical of a tilted
        pad) gets no label either (1.0 = never), unless edge_label_weight, the edge streak
        (edge_streak_frames, edge_streak_confidence), the longer streak at a lower bar
        (edge_long_streak_frames, edge_long_streak_confidence) or edge_min_confidence trusts
        it (perception/classifier/edge_streak.py); the defaults are chosen on the rig's touches.
    edge_extent: where a trusted edge imprint's label reaches: `whole` imprint, read
        `patches` as other touches (a patch naming another material abstains), or only the
        `centre` crop's reach.
    edge_label_weight: above 0, such an imprint read confidently keeps its label with this
        `TouchLabel.weight` (the map trusts it less; its reach as edge_extent says), instead
        of none.
    contact_*: ContactGate parameters (see perception/contact.py).
    background_dir: folder of `<finger>.png` no-contact frames (e.g. `<data>/_backgrounds`).
    first_frame_background: without any background, take a finger's first frame as its
        background (a real DIGIT is usually started free of contact).
    weights, input_size, crop_px: how `task=train_classifier` builds a new model
        (`new_model()`) and its inputs; a loaded checkpoint carries its own input size and crop.
    patch_spacing_px, max_patches, patch_probe: patch readings across the imprint
        (perception/classifier/patch_reader.py); spacing 0 = off.
    patch_min_contact: a patch past the centroid is centred only where its crop holds at
        least this share of imprint pixels (0: anywhere on the contact).
    patch_disagree_confidence: a patch naming another material than the touch's (centre)
        label needs at least this confidence, else it abstains (below min_confidence: off).
    cuda_graphs: on a GPU, replay the forward from CUDA graphs (perception/graphed.py).
    cpu_runtime: on the CPU, `onnxruntime` (perception/onnx_cpu.py) or `torch` (traced).
    """

    def __init__(
        self,
        class_names: Sequence[str],
        checkpoint: str | None = None,
        device: str = "auto",
        min_confidence: float = 0.8,
        max_edge_share: float = 0.5,
        edge_px: int = 16,
        edge_label_weight: float = 0.0,
        edge_streak_frames: int = 0,
        edge_streak_confidence: float = 0.99,
        edge_long_streak_frames: int = 0,
        edge_long_streak_confidence: float = 0.8,
        edge_min_confidence: float | None = None,
        edge_extent: str = "whole",
        contact_threshold: float = 30.0,
        contact_min_area: float = 0.01,
        contact_blur_px: float = 3.0,
        background_dir: str | None = None,
        first_frame_background: bool = True,
        weights: str | None = None,
        input_size: int = 224,
        crop_px: int | None = None,
        patch_spacing_px: int = 0,
        max_patches: int = 8,
        patch_probe: int = 0,
        patch_min_contact: float = 0.0,
        patch_disagree_confidence: float = 0.0,
        cuda_graphs: bool = True,
        cpu_runtime: str = "onnxruntime",
    ) -> None:
        check_label_gates(min_confidence, max_edge_share, edge_px, edge_label_weight)
        self.class_names, self.checkpoint = list(class_names), checkpoint
        self.device_name = device
        self.min_confidence = float(min_confidence)
        self.max_edge_share, self.edge_px = float(max_edge_share), int(edge_px)
        self.edge_label_weight = float(edge_label_weight)
        self.edge_streaks = (
            EdgeStreak(edge_streak_frames, edge_streak_confidence, edge_min_confidence),
            EdgeStreak(edge_long_streak_frames, edge_long_streak_confidence, None, LONG_STREAK),
        )
        check_edge_extent(edge_extent)
        self.edge_extent = edge_extent
        self.gate = ContactGate(contact_threshold, contact_min_area, contact_blur_px)
        self.background_dir = background_dir
        self.first_frame_background = first_frame_background
        self.weights = weights
        self.input_size = int(input_size)
        self.crop_px = crop_px
        self.patches = PatchReader(
            patch_spacing_px, max_patches, patch_probe, patch_min_contact, patch_disagree_confidence
        )
        self.cuda_graphs = bool(cuda_graphs)
        check_cpu_runtime("classifier.cpu_runtime", cpu_runtime)
        self.cpu_runtime = cpu_runtime
        self._backgrounds: dict[str, np.ndarray] = {}
        self._model: torch.nn.Module | None = None
        self._ckpt: ClassifierCheckpoint | None = None
        self._device: torch.device | None = None

    # ---- training side -------------------------------------------------------------
    def new_model(self) -> torch.nn.Module:
        """A fresh EfficientNet-B0 for these classes (backbone from `weights` if set)."""
        from neuralfeels_sem.perception.classifier.dataset import resolve_path

        return build_model(
            len(self.class_names), resolve_path(self.weights) if self.weights else None
        )

    # ---- loading -------------------------------------------------------------------
    @property
    def checkpoint_path(self) -> Path:
        if self.checkpoint is None:
            return SHIPPED_CHECKPOINT
        from neuralfeels_sem.perception.classifier.dataset import resolve_path

        return resolve_path(self.checkpoint)

    def open(self) -> MaterialClassifier:
        """Load the checkpoint and backgrounds (done automatically on first use)."""
        if self._model is not None:
            return self
        path = self.checkpoint_path
        if self.checkpoint is None and not path.is_file():
            raise ConfigError(
                f"no shipped classifier at {path}; train one with task=train_classifier and set classifier.checkpoint"
            )
        ckpt = load_checkpoint(path)
        if ckpt.class_names != self.class_names:
            raise ConfigError(
                f"classifier checkpoint {path} was trained for {ckpt.class_names} but materials={self.class_names}; "
                "set materials to match or train a classifier for these classes"
            )
        self._device = resolve_device(self.device_name)
        self._model = inference_model(lambda: ckpt.build(self._device), ckpt.input_size,
                                      self._device, self.cuda_graphs, path, self.cpu_runtime)  # fmt: skip
        self._ckpt = ckpt
        if self.background_dir is not None:
            self._load_backgrounds()
        return self

    def _load_backgrounds(self) -> None:
        from neuralfeels_sem.perception.classifier.dataset import resolve_path

        folder = resolve_path(self.background_dir)
        files = (
            sorted(folder.glob("*.png")) + sorted(folder.glob("*.jpg")) if folder.is_dir() else []
        )
        if not files:
            raise DataError(
                f"classifier.background_dir={folder} has no <finger>.png background frames"
            )
        for f in files:
            bgr = cv2.imread(str(f), cv2.IMREAD_COLOR)
            if bgr is None:
                raise DataError(f"background frame {f} is unreadable; recapture it")
            self._backgrounds[f.stem] = np.ascontiguousarray(bgr[..., ::-1])

    @property
    def loaded(self) -> ClassifierCheckpoint:
        """The loaded checkpoint (class names, input size, normalisation, provenance)."""
        self.open()
        return self._ckpt

    def set_background(self, finger: str, image: np.ndarray) -> None:
        """Use `image` as the no-contact reference of `finger` from now on."""
        self._backgrounds[finger] = np.asarray(image)

    # ---- inference -----------------------------------------------------------------
    def predict_images(
        self, images: np.ndarray, backgrounds: Sequence[np.ndarray | None] | None = None
    ) -> np.ndarray:
        """(B, H, W, 3) uint8 tactile images -> (B, C) probabilities.

        Raw frames (larger than the checkpoint's crop) are cropped around their contact
        (against `backgrounds`, one per image) when the model was trained on crops;
        images already at the input size are used as they are.
        """
        self.open()
        images = np.asarray(images)
        if images.ndim != 4 or images.shape[-1] != 3 or images.dtype != np.uint8:
            raise ValueError(
                f"expected (B, H, W, 3) uint8 images, got {images.shape} {images.dtype}"
            )
        if len(images) == 0:
            return np.zeros((0, len(self.class_names)), dtype=np.float32)
        ckpt = self._ckpt
        crop_px = ckpt.meta.get("crop_px")
        if crop_px and min(images.shape[1:3]) > crop_px:
            backgrounds = backgrounds if backgrounds is not None else [None] * len(images)
            batch = np.stack(
                [
                    preprocess(im, ckpt.input_size, crop_px, bg)
                    for im, bg in zip(images, backgrounds)
                ]
            )
        else:
            batch = resize_batch(images, ckpt.input_size)
        return predict_probs(self._model, batch, ckpt.mean, ckpt.std, self._device)

    def background_for(self, reading: TactileReading) -> np.ndarray | None:
        if reading.background is not None:
            return reading.background
        if reading.finger not in self._backgrounds and self.first_frame_background:
            log.warning(
                "no background for %s; using its first frame as the no-contact reference",
                reading.finger,
            )
            self._backgrounds[reading.finger] = reading.image.copy()
        return self._backgrounds.get(reading.finger)

    def contact_mask(self, reading: TactileReading) -> np.ndarray:
        background = self.background_for(reading)
        if background is None:
            raise ConfigError(
                f"no background frame for finger {reading.finger}; set classifier.background_dir "
                "or classifier.first_frame_background=true"
            )
        return self.gate.mask(reading.image, background)

    def in_contact(self, reading: TactileReading) -> bool:
        return float(self.contact_mask(reading).mean()) >= self.gate.min_area

    def classify(self, readings: Sequence[TactileReading]) -> list[TouchLabel]:
        """One TouchLabel per reading; frames without contact get no label."""
        self.open()
        masks = [self.contact_mask(r) for r in readings]
        contact = [float(m.mean()) >= self.gate.min_area for m in masks]
        # An imprint mostly along the sensor's border (a tilted pad's edge) gets no label
        # unless the finger's streak of confident readings backs it (_label).
        at_edge = [
            self.max_edge_share < 1.0 and edge_share(m, self.edge_px) > self.max_edge_share
            for m in masks
        ]
        labels = [TouchLabel(finger=r.finger, contact=c) for r, c in zip(readings, contact)]
        touched = [i for i, c in enumerate(contact) if c]
        if touched:
            probs = self.predict_images(
                np.stack([readings[i].image for i in touched]),
                [self.background_for(readings[i]) for i in touched],
            )
            for i, p in zip(touched, probs):
                self._label(labels[i], p, at_edge[i])
            if self.patches.spacing_px > 0:
                self._read_patches(readings, masks, labels, touched)
        for r, label in zip(readings, labels):
            top = int(label.probs.argmax()) if label.probs is not None else None
            for streak in self.edge_streaks:
                streak.update(r.finger, top, label.confidence)
        return labels

    def _label(self, label: TouchLabel, probs: np.ndarray, at_edge: bool) -> None:
        """Set a touch's label from its class probabilities: none below min_confidence,
        none for an imprint along the border unless edge_label_weight trusts it some or the
        finger's streak of confident frames naming this material backs it (EdgeStreak)."""
        top = int(probs.argmax())
        label.probs = probs
        label.confidence = float(probs[top])
        label.at_edge = at_edge
        unbacked_edge = at_edge and not any(
            streak.trusted(label.finger, top, label.confidence) for streak in self.edge_streaks
        )
        if probs[top] < self.min_confidence or (unbacked_edge and not self.edge_label_weight):
            label.low_confidence = True
            label.label = NO_LABEL
            return
        label.label = top
        if unbacked_edge:
            label.weight = self.edge_label_weight

    def _read_patches(
        self,
        readings: Sequence[TactileReading],
        masks: list[np.ndarray],
        labels: list[TouchLabel],
        touched: list[int],
    ) -> None:
        """Patch readings of the touched frames; a labelled edge imprint's as `edge_extent` says."""
        crop_px = self.loaded.meta.get("crop_px")
        if not crop_px:
            return  # a whole-frame model has no patches to read
        edge = [i for i in touched if labels[i].at_edge and labels[i].label != NO_LABEL]
        read = [i for i in touched if not labels[i].at_edge]
        read += edge if self.edge_extent == "patches" else []
        self.patches.read([readings[i] for i in read], [masks[i] for i in read],
                          [labels[i] for i in read], self.predict_images, crop_px,
                          self.min_confidence)  # fmt: skip
        for i in edge if self.edge_extent == "centre" else []:
            self.patches.centre_only(readings[i], masks[i], labels[i], crop_px)
