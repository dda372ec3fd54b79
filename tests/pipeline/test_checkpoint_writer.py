"""Checkpoints written by a worker while the mapper trains on (pipeline/checkpoint_writer.py)."""

from __future__ import annotations

import threading

import pytest
import torch

import neuralfeels_sem.pipeline.checkpoint_writer as writer_module
from neuralfeels_sem.mapping.checkpoint import load_checkpoint, take_checkpoint
from neuralfeels_sem.pipeline.checkpoint_writer import CheckpointWriter
from tests.mapping.test_checkpoint import FRAMES, feed, make_mapper


def hold_writes(monkeypatch) -> threading.Event:
    """The writer's writes wait until the returned event is set."""
    release = threading.Event()
    write = writer_module.write_checkpoint

    def write_later(path, taken) -> None:
        assert release.wait(timeout=60)
        write(path, taken)

    monkeypatch.setattr(writer_module, "write_checkpoint", write_later)
    return release


@pytest.mark.parametrize("storage", ["exact", "compact"])
def test_a_checkpoint_written_behind_holds_the_state_it_was_taken_with(
    tmp_path, monkeypatch, storage: str
) -> None:
    """The worker writes only after training has gone on; resuming from the file still
    continues the run of the moment it was taken (exactly, when stored exact)."""
    reference = make_mapper()
    feed(reference, FRAMES)
    trained_on = hold_writes(monkeypatch)
    mapper = make_mapper()
    feed(mapper, FRAMES[:3])
    path = tmp_path / "checkpoint.pt"
    writer = CheckpointWriter(path)
    writer.submit(take_checkpoint(mapper, 2, {"note": [1]}, storage=storage))
    feed(mapper, FRAMES[3:])  # changes every table row and moment the copy holds
    trained_on.set()
    writer.close()

    resumed = make_mapper(init_seed=7)
    assert load_checkpoint(path, resumed) == {"frame_index": 2, "extra": {"note": [1]}}
    feed(resumed, FRAMES[3:])
    if storage == "exact":
        for (name, a), (_, b) in zip(
            reference.field.state_dict().items(), resumed.field.state_dict().items()
        ):
            assert torch.equal(a, b), name
    else:
        # Compact is lossy (float16 table and memory, 8-bit moment codes): training on from
        # it moves single rows, so the field is compared where it is read, as in
        # tests/mapping/test_checkpoint_storage.py (seen: 2 % of the SDF's range here).
        points = torch.rand(2048, 3, generator=torch.Generator().manual_seed(0)) * 0.16 - 0.08
        with torch.no_grad():
            expected, got = reference.field.sdf(points), resumed.field.sdf(points)
        assert (got - expected).abs().max() < 0.05 * expected.abs().max()
    assert reference.trained_on == resumed.trained_on


def test_a_failed_write_is_raised_on_the_mapper_side(tmp_path) -> None:
    (tmp_path / "a_file").write_text("not a directory")
    writer = CheckpointWriter(tmp_path / "a_file" / "checkpoint.pt")
    mapper = make_mapper()
    feed(mapper, FRAMES[:2])
    writer.submit(take_checkpoint(mapper, 1))
    with pytest.raises(OSError):
        writer.wait()
    writer.close()  # the error was raised once; the worker stops cleanly


def test_a_checkpoint_due_while_a_write_runs_waits_for_it_not_the_mapper(
    tmp_path, monkeypatch
) -> None:
    """`due` says take one once a checkpoint's frame has been reached and no write runs; a
    frame reached during a write keeps it due until the write ends, a submit clears it."""
    release = hold_writes(monkeypatch)
    mapper = make_mapper()
    feed(mapper, FRAMES[:2])
    writer = CheckpointWriter(tmp_path / "checkpoint.pt")
    assert not writer.due(False) and writer.due(True)
    writer.submit(take_checkpoint(mapper, 1))
    assert writer.busy and not writer.due(False)
    assert not writer.due(True)  # reached, but the write runs
    release.set()
    writer.wait()
    assert not writer.busy and writer.due(False)  # still due from the frame reached
    writer.submit(take_checkpoint(mapper, 1))
    writer.wait()
    assert not writer.due(False)
    writer.close()
    assert load_checkpoint(tmp_path / "checkpoint.pt", make_mapper())["frame_index"] == 1
