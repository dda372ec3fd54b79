"""RunScorer on an analytic field: majority baseline, shape-aware matching, failed extraction."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from neuralfeels_sem.core.errors import NoDataError
from neuralfeels_sem.eval import run_scorer
from neuralfeels_sem.eval.run_scorer import RunScorer
from tests.eval.objects import RADIUS, two_material_sphere


class SphereField(nn.Module):
    """SDF of a sphere of `radius`; plastic (0) where y > 0, fabric (2) elsewhere."""

    def __init__(self, radius: float = RADIUS, everywhere: int | None = None) -> None:
        super().__init__()
        self.radius = radius
        self.everywhere = everywhere
        self.anchor = nn.Parameter(torch.zeros(1))  # gives the field a device

    def sdf(self, x: torch.Tensor) -> torch.Tensor:
        return x.norm(dim=1) - self.radius

    def predict_material(self, x: torch.Tensor) -> torch.Tensor:
        if self.everywhere is not None:
            return torch.full((len(x),), self.everywhere, dtype=torch.int64)
        return torch.where(x[:, 1] > 0, 0, 2)

    def material_logits(self, x: torch.Tensor) -> torch.Tensor:
        return 20.0 * nn.functional.one_hot(self.predict_material(x), 4).float()


@pytest.fixture(scope="module")
def scorer() -> RunScorer:
    return RunScorer(
        two_material_sphere(),
        num_surface_samples=3000,
        image_views=2,
        image_size=64,
        image_elevation_deg=30.0,
        fscore_thresholds_mm=[5.0],
        shape_samples=3000,
        mesh_resolution=48,
        seed=0,
        mesh_match_tolerance_m=0.005,
    )


def test_a_right_field_beats_the_majority_map(scorer: RunScorer) -> None:
    out, mesh = scorer.field_metrics(SphereField(), bound=1.2 * RADIUS)
    assert mesh is not None and out["notes"] == []
    assert out["matching_pct"] == 100.0 and out["matching_mean_class_pct"] == 100.0
    assert out["matching_miou_pct"] == 100.0
    assert out["matching_mesh_pct"] > 97.0  # labels at the mesh's vertices, border cells differ
    majority = scorer.majority_baseline()
    assert majority["matching_mean_class_pct"] == pytest.approx(50.0)
    labels = scorer.matching.labels
    assert majority["matching_pct"] == pytest.approx(
        100.0 * np.bincount(labels).max() / len(labels)
    )
    assert majority["matching_mesh_pct"] == majority["matching_pct"]


def test_a_constant_field_scores_the_majority_figures(scorer: RunScorer) -> None:
    majority = scorer.majority_baseline()
    field = SphereField(everywhere=scorer.matching.majority_class)
    out, _ = scorer.field_metrics(field, bound=1.2 * RADIUS)
    for key in ("matching_pct", "matching_mean_class_pct", "matching_miou_pct"):
        assert out[key] == pytest.approx(majority[key]), key


def test_a_misplaced_surface_costs_only_the_shape_aware_form(scorer: RunScorer) -> None:
    out, _ = scorer.field_metrics(SphereField(radius=RADIUS + 0.01), bound=1.5 * RADIUS)
    assert out["matching_pct"] == 100.0  # the field is still right at the true surface
    assert out["matching_mesh_pct"] == 0.0  # but its surface is 1 cm off everywhere


def test_final_metrics_carry_curves_margins_and_baselines(scorer: RunScorer) -> None:
    field = SphereField()
    scorer.score(field, 0, 0.0)
    baseline, _ = scorer.field_metrics(SphereField(everywhere=3), bound=1.2 * RADIUS)
    metrics, _ = scorer.final_metrics(field, 1.2 * RADIUS, baseline)
    assert metrics["matching_mean_class_curve"][-1] == [0, 0.0, 100.0]
    assert metrics["baseline"]["matching_mean_class_pct"] == 0.0  # wood is on no face
    assert metrics["margin_over_majority"]["matching_mean_class_pct"] == pytest.approx(50.0)
    state = scorer.state()
    assert state["mean_class_curve"] == metrics["matching_mean_class_curve"]


def test_a_material_no_touch_read_rightly_is_named_in_the_metrics_and_notes(
    scorer: RunScorer,
) -> None:
    """plastic (0) and fabric (2) are on the sphere: fabric only abstained on -> named."""
    saved = scorer.touch_log
    try:
        scorer.touch_log = [[0, "index", 0, 0, 0.9, 0, ""], [1, "ring", -1, 2, 0.6, 2, "edge"]]
        metrics, _ = scorer.final_metrics(SphereField(), 1.2 * RADIUS, {})
        assert metrics["materials_never_read"] == {"fabric": "never labelled"}
        recall = metrics["matching_per_class"]["fabric"]
        note = (
            f"no touch read fabric rightly (never labelled); the map's recall of it {recall:.1f} %"
        )
        assert note in metrics["notes"]
        # No touch with a ground truth (a real rig): nothing to judge, no note.
        scorer.touch_log = [[0, "index", 0, -1, 0.9, 0, ""]]
        metrics, _ = scorer.final_metrics(SphereField(), 1.2 * RADIUS, {})
        assert metrics["materials_never_read"] is None
        assert not any(note.startswith("no touch read") for note in metrics["notes"])
    finally:
        scorer.touch_log = saved


def test_a_failed_extraction_keeps_every_other_figure(scorer: RunScorer, monkeypatch) -> None:
    def broken(*args, **kwargs):
        raise ValueError("marching cubes ran out of patience")

    monkeypatch.setattr(run_scorer, "extract_mesh", broken)
    out, mesh = scorer.field_metrics(SphereField(), bound=1.2 * RADIUS)
    assert mesh is None and out["matching_mean_class_pct"] == 100.0
    assert out["matching_mesh_pct"] is None and out["fscore_5mm"] is None
    assert any("mesh extraction failed" in note for note in out["notes"])

    def empty(*args, **kwargs):
        raise NoDataError("no zero crossing")

    monkeypatch.setattr(run_scorer, "extract_mesh", empty)
    out, _ = scorer.field_metrics(SphereField(), bound=1.2 * RADIUS)
    assert out["matching_mesh_pct"] == 0.0 and out["fscore_5mm"] == 0.0  # no surface at all
    assert out["notes"] == ["no zero crossing"]


class ShiftedBorderField(SphereField):
    """Plastic where y > 1 cm (the truth: y > 0), unsure near its own border: wrong on 0 < y < 1 cm."""

    def predict_material(self, x: torch.Tensor) -> torch.Tensor:
        return torch.where(x[:, 1] > 0.01, 0, 2)

    def material_logits(self, x: torch.Tensor) -> torch.Tensor:
        sureness = 300.0 * (x[:, 1] - 0.01).abs()
        return nn.functional.one_hot(self.predict_material(x), 4).float() * sureness[:, None]


def test_uncertainty_predicts_where_the_map_is_wrong(scorer: RunScorer) -> None:
    metrics, _ = scorer.final_metrics(ShiftedBorderField(), 1.2 * RADIUS, {})
    block = metrics["uncertainty"]
    wrong = 100.0 - metrics["matching_pct"]
    assert block["error_share"] == pytest.approx(wrong / 100.0)
    assert block["auroc"] > 0.85  # right samples just past the border are unsure too
    assert block["mean_entropy_wrong"] > 2 * block["mean_entropy_correct"]
    assert 0.0 < block["ece"] < 1.0 and block["ece_bins"] == 15
    sure, _ = scorer.final_metrics(SphereField(), 1.2 * RADIUS, {})
    assert sure["uncertainty"]["auroc"] is None and "undefined" in sure["uncertainty"]["note"]


def test_snapshots_carry_the_uncertainty_of_every_object_pixel(scorer: RunScorer) -> None:
    maps = scorer.snapshot(ShiftedBorderField())
    entropy = maps["entropy"]
    assert entropy.shape == maps["gt"].shape
    on_object = maps["gt"] != -2
    assert np.isfinite(entropy[on_object]).all() and np.isnan(entropy[~on_object]).all()
    assert entropy[maps["diff"]].mean() > entropy[on_object & ~maps["diff"]].mean()


def test_touches_csv_says_what_an_abstained_touch_read_and_why(scorer, tmp_path) -> None:
    import csv

    from neuralfeels_sem.perception.touch import TouchLabel, abstention
    from neuralfeels_sem.pipeline.run_outputs import write_touches

    probs = np.array([0.1, 0.2, 0.7, 0.0])
    edge = TouchLabel("ring", True, probs=probs, confidence=0.7, low_confidence=True, at_edge=True)
    unsure = TouchLabel("index", True, probs=probs, confidence=0.7, low_confidence=True)
    read = TouchLabel("thumb", True, label=2, probs=probs, confidence=0.7)
    assert [abstention(t) for t in (edge, unsure, read)] == ["edge", "low_confidence", ""]
    assert abstention(TouchLabel("middle", False)) == ""
    saved = scorer.touch_log
    try:
        # A checkpoint from before the two columns: neither is known.
        scorer.load_state({"touch_log": [[3, "index", 2, 2, 0.9]]})
        assert scorer.touch_log == [[3, "index", 2, 2, 0.9, -1, ""]]
        scorer.touch_log.append([4, "ring", -1, 0, 0.7, 2, abstention(edge)])
        write_touches(scorer.touch_log, list(scorer.class_names), tmp_path / "touches.csv")
        rows = list(csv.DictReader((tmp_path / "touches.csv").open()))
        assert [(r["predicted"], r["top_class"], r["abstained"]) for r in rows] == [
            ("fabric", "none", ""),
            ("none", "fabric", "edge"),
        ]
    finally:
        scorer.touch_log = saved
