"""task=eval: recompute metrics and pictures of a finished (or killed) mapping run.

    python run.py task=eval run_dir=outputs/map/plushie/sim/2026-11-21_10-00-00

Loads the run's own config and its checkpoint.pt, scores the field with the current
`eval.*` settings and writes metrics.json, material_mesh.ply and the pictures into
`<run_dir>/eval/`. Nothing is re-run: the sensor is not opened.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

from hydra import compose
from hydra.errors import ConfigCompositionException
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from neuralfeels_sem.core.errors import ConfigError, DataError
from neuralfeels_sem.mapping.checkpoint import load_checkpoint
from neuralfeels_sem.pipeline.run_outputs import write_metrics
from neuralfeels_sem.tasks.build import BOUND_MARGIN, build_mapper, build_scorer, model_config
from neuralfeels_sem.utils.atomic import atomic_write
from neuralfeels_sem.utils.device import resolve_device
from neuralfeels_sem.viz.run_report import print_summary, write_pictures

log = logging.getLogger(__name__)


def load_run_config(run_dir: Path) -> DictConfig:
    config_file = run_dir / ".hydra" / "config.yaml"
    if not run_dir.is_dir():
        raise DataError(f"run_dir={run_dir} does not exist; pass the directory of a task=map run")
    if not config_file.is_file() or not (run_dir / "checkpoint.pt").is_file():
        raise DataError(
            f"run_dir={run_dir} is not a mapping run (needs .hydra/config.yaml and checkpoint.pt); "
            "pass the directory a task=map run wrote"
        )
    saved = OmegaConf.load(config_file)
    if saved.get("task", {}).get("name") != "map":
        raise DataError(f"run_dir={run_dir} was written by task={saved.task.name}, not task=map")
    # Re-compose from the run's own overrides so the config gets its schemas (typed nodes) back.
    overrides_file = run_dir / ".hydra" / "overrides.yaml"
    overrides = list(OmegaConf.load(overrides_file)) if overrides_file.is_file() else []
    try:
        return compose(
            config_name="config", overrides=[o for o in overrides if not o.startswith("hydra.")]
        )
    except ConfigCompositionException as exc:  # e.g. an option removed since the run
        reason = str(exc).strip().splitlines()[0]
        raise ConfigError(
            f"run_dir={run_dir}: its overrides no longer compose ({reason}); "
            "re-run it or edit .hydra/overrides.yaml"
        ) from exc


def run(cfg: DictConfig) -> dict:
    if not cfg.run_dir:
        raise ConfigError("task=eval needs run_dir=PATH (the directory of a task=map run)")
    run_dir = Path(cfg.run_dir)
    run_cfg = load_run_config(run_dir)
    out = run_dir / "eval"
    out.mkdir(exist_ok=True)
    obj = instantiate(run_cfg.object)
    bound = BOUND_MARGIN * obj.bounds_radius
    mapper = build_mapper(run_cfg, bound, resolve_device(cfg.device))
    resumed = load_checkpoint(run_dir / "checkpoint.pt", mapper, model_config(run_cfg))
    # The current eval settings (so a run can be re-scored more finely), the run's own object.
    scorer = build_scorer(OmegaConf.merge(run_cfg, {"eval": cfg.eval}), obj)
    scorer.load_state(resumed["extra"].get("scorer", {}))
    previous = {}
    if (run_dir / "metrics.json").is_file():
        try:
            previous = json.loads((run_dir / "metrics.json").read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise DataError(
                f"{run_dir / 'metrics.json'} is damaged ({type(exc).__name__}); "
                "move it aside to re-score the run from its checkpoint"
            ) from exc
    # The untrained field's figures cannot be recomputed from a checkpoint: keep the run's.
    scores, mesh = scorer.final_metrics(mapper.field, bound, previous.get("baseline") or {})
    if mesh is not None:
        with atomic_write(out / "material_mesh.ply", "wb") as f:
            mesh.export(f, file_type="ply")
    metrics = {
        **previous,
        **scores,
        "trained_on": mapper.trained_on,
        "evaluated_checkpoint_frame": resumed["frame_index"],
    }
    metrics.setdefault("baseline", {})
    metrics.setdefault(
        "config",
        {"object": run_cfg.object.name, "sensor": run_cfg.sensor.name, "seed": int(run_cfg.seed)},
    )
    metrics.setdefault("frames", resumed["frame_index"] + 1)
    metrics.setdefault("wall_s", 0.0)
    metrics.setdefault("realtime_factor", None)
    write_metrics(metrics, out / "metrics.json")
    if cfg.viz.plots:
        write_pictures(scorer.class_names, metrics, run_dir / "progression", out, int(cfg.viz.dpi))
    print_summary(metrics, out)
    return metrics
