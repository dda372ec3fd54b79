"""task=record: write what any sensor yields (real, sim, replay) into a recording directory.

    python run.py task=record sensor=real task.duration_s=30
    python run.py sensor=replay sensor.recording=outputs/record/<object>/real/<date>/recording

The sensor is opened before anything is written, so a missing device ends the run at
once (one line per device, exit 2). Frames are written as they arrive; an interrupted or
failing run keeps everything recorded so far.
"""

from __future__ import annotations

import json
import logging

from hydra.utils import get_class, instantiate
from omegaconf import DictConfig, OmegaConf
from tqdm import tqdm

from neuralfeels_sem.sensors.base import Sensor
from neuralfeels_sem.sensors.factory import build_sensor
from neuralfeels_sem.sensors.hand_spec import hand_model_spec
from neuralfeels_sem.sensors.replay.recording import RecordingReader, RecordingWriter
from neuralfeels_sem.tasks.runner import output_dir

log = logging.getLogger(__name__)


def make_sensor(cfg: DictConfig) -> Sensor:
    """The configured sensor, completed like every task does (sensors/factory.py).

    Hardware and replay sensors declare `needs_object = False`: building the object (mesh
    generation) is skipped for them, so a missing device is reported at once.
    """
    target = get_class(cfg.sensor._target_)
    obj = instantiate(cfg.object) if getattr(target, "needs_object", True) else None
    return build_sensor(cfg.sensor, obj, list(cfg.materials))


def _config_dict(cfg: DictConfig) -> dict:
    try:
        return OmegaConf.to_container(cfg, resolve=True)
    except Exception:  # an unresolvable interpolation must not stop a recording
        return OmegaConf.to_container(cfg, resolve=False)


def record(
    sensor: Sensor, writer: RecordingWriter, duration_s: float | None, max_frames: int | None
) -> dict:
    """Pump frames from an opened sensor into an opened writer; returns counts and stream info."""
    total = len(sensor) if len(sensor) > 0 else None
    if max_frames is not None:
        total = max_frames if total is None else min(total, max_frames)
    count, first_time, last_time, streams = 0, None, None, set()
    with tqdm(total=total, desc="record", unit="frame") as bar:
        for frame in sensor.frames():
            first_time = frame.time_s if first_time is None else first_time
            if duration_s is not None and frame.time_s - first_time >= duration_s:
                break
            stamps = getattr(sensor, "stream_times", None) or {}
            writer.write(frame, stamps=dict(stamps))
            streams.update(f"digit/{f}" for f in frame.tactile)
            if frame.camera is not None:
                streams.add("camera")
            count += 1
            last_time = frame.time_s
            bar.update()
            if max_frames is not None and count >= max_frames:
                break
    return {
        "frames": count,
        "recorded_s": 0.0 if count == 0 else float(last_time - first_time),
        "streams": sorted(streams),
    }


def run(cfg: DictConfig) -> dict:
    sensor = make_sensor(cfg)
    sensor.open()
    out = output_dir() / cfg.task.out
    writer = RecordingWriter(
        out,
        class_names=list(cfg.materials),
        frame_period_s=sensor.frame_period_s,
        config=_config_dict(cfg),
        calibration=getattr(sensor, "calibration", None),
        hand_model=hand_model_spec(sensor.hand_model()),
    )
    try:
        writer.open()
        summary = record(sensor, writer, cfg.task.duration_s, cfg.task.max_frames)
    finally:
        writer.close()
        sensor.close()
    summary["recording"] = str(out)
    if cfg.task.feelsight and summary["frames"]:
        from neuralfeels_sem.sensors.replay.feelsight import export_feelsight

        reader = RecordingReader(out)
        feelsight_dir = out.parent / f"{out.name}_feelsight"
        export_feelsight(reader.frames(), feelsight_dir, total=len(reader))
        summary["feelsight"] = str(feelsight_dir)
    (output_dir() / "record.json").write_text(json.dumps(summary, indent=2))
    log.info("recorded %d frames (%.1f s) to %s", summary["frames"], summary["recorded_s"], out)
    return summary
