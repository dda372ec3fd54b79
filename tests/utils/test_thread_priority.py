"""Helper threads step back for the mapper: a thread run through `at_priority` adds its
nice value to its own (Linux), leaves the calling thread's alone, stops at 19, and changes
nothing where the system cannot do it per thread."""

from __future__ import annotations

import os
import sys
import threading

import pytest

from neuralfeels_sem.utils import thread_priority
from neuralfeels_sem.utils.thread_priority import MAX_NICE, at_priority

linux = pytest.mark.skipif(sys.platform != "linux", reason="per-thread nice values are Linux's")


def _nice_in_thread(nice: int) -> int:
    seen: list[int] = []

    def work() -> None:
        seen.append(os.getpriority(os.PRIO_PROCESS, threading.get_native_id()))

    thread = threading.Thread(target=at_priority(work, nice))
    thread.start()
    thread.join(timeout=5.0)
    return seen[0]


@linux
def test_a_helper_thread_adds_its_nice_value_and_the_caller_keeps_its_own() -> None:
    own = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    assert _nice_in_thread(5) == min(MAX_NICE, own + 5)
    assert _nice_in_thread(0) == own
    assert _nice_in_thread(40) == MAX_NICE
    assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == own


def test_elsewhere_than_linux_nothing_changes(monkeypatch) -> None:
    monkeypatch.setattr(thread_priority.sys, "platform", "darwin")
    calls = []
    monkeypatch.setattr(thread_priority.os, "setpriority", lambda *a: calls.append(a))
    assert _nice_in_thread(10) == os.getpriority(os.PRIO_PROCESS, 0) and not calls


@linux
def test_a_refused_change_leaves_the_thread_running(monkeypatch) -> None:
    def refuse(*args) -> None:
        raise PermissionError("not allowed here")

    monkeypatch.setattr(thread_priority.os, "setpriority", refuse)
    own = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    assert _nice_in_thread(10) == own


def test_helper_threads_step_back_only_at_offline_pace() -> None:
    """At realtime the producer keeps the sensor's clock: it takes its share of the cores."""
    from neuralfeels_sem.pipeline.session_settings import SessionSettings

    settings = SessionSettings(
        5, 100, 6, 2.0, "auto", True, helper_nice=10, overtaken_touch_frames=4
    )
    assert settings.nice_at("offline") == 10 and settings.nice_at("realtime") == 0
