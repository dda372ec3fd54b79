"""A sensor run in a process of its own (`mapping.acquire_process`).

The frame producer's stages are threads of one interpreter: where the acquisition is
Python work (the simulated hand's gait planning, the renderers' scene updates) it takes
turns with perception and the mapper on the interpreter lock, so a machine with cores to
spare (a GPU machine) still runs them one at a time. ProcessSensor builds the sensor in a
child process and asks it for frames by index; while the child renders, the thread that
asked waits on a pipe without holding the lock.

Only sensors that make frames by index (IndexedSensor: the simulator) can move: a rig's
device reads stream and belong to the process that opened the devices. The child is a
fresh interpreter (not a fork: the parent holds torch and GL state) running this module's
`child_main`; it is this program's own, so the sensor's recipe goes to it and frames come
back pickled; nothing a user hands in is unpickled.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import multiprocessing as mp
import os
import queue
import signal
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

from neuralfeels_sem.core.errors import FrameSourceError
from neuralfeels_sem.core.frame import Frame
from neuralfeels_sem.sensors.base import IndexedSensor
from neuralfeels_sem.utils.thread_priority import lower_this_thread

log = logging.getLogger(__name__)

# The child interpreter's entry (argv[1]: the fd of its end of the pipe).
CHILD_MAIN = (
    "import sys; from neuralfeels_sem.sensors.process_sensor import child_main; "
    "child_main(int(sys.argv[1]))"
)
OPEN_TIMEOUT_S = 300.0  # building the scene and renderers; a first MuJoCo compile is slow
CLOSE_TIMEOUT_S = 10.0
# What the parent reads once, when the child has opened its sensor, and takes as its own.
STATIC = ("name", "pace", "frame_period_s", "accepts_advice", "confirm_regrasps")
# What comes with every reply (the sensor's methods of these names, where it has them).
STATE = ("touch_plan", "damage_report")


class ProcessSensor(IndexedSensor):
    """`build()`'s sensor, opened and run in a child process; the same frames, in order.

    Args:
        build: makes the sensor in the child (picklable: a module-level function or a
            functools.partial of one); it must return an IndexedSensor.
        nice: added to the child's nice value (mapping.helper_nice, as the producer's
            threads; Linux).
    """

    def __init__(self, build: Callable[[], IndexedSensor], nice: int = 0) -> None:
        self.build, self.nice = build, int(nice)
        self.process_cpu_s = 0.0  # the child's CPU seconds so far (metrics: acquire_process)
        self._state: dict[str, Any] = {}  # STATE, as of the child's last reply
        self._conn = None
        self._process = None
        self._length = -1
        self._hand_model = None
        self._call_lock = threading.Lock()  # one request in flight: its reply is the next
        self._send_lock = threading.Lock()  # advice may be sent while a frame is awaited

    def __len__(self) -> int:
        return self._length

    def open(self) -> None:
        if self._process is not None:
            return
        # A plain child interpreter, not a multiprocessing one: spawn's start-up re-imports
        # the parent's main module and copies its start method, which fails inside a joblib
        # (loky) worker of a multirun sweep and in a script without a main guard.
        self._conn, child_conn = mp.Pipe()
        fd = child_conn.fileno()
        self._process = subprocess.Popen(
            [sys.executable, "-c", CHILD_MAIN, str(fd)],
            pass_fds=(fd,),
            env={**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)},
        )
        child_conn.close()
        # A sensor never closed would leave the child waiting on its pipe: closed at exit.
        atexit.register(self.close)
        self._send(("start", (self.build, self.nice)))
        info = self._reply(OPEN_TIMEOUT_S)
        for name, value in info["static"].items():  # the child's sensor's, as its own
            setattr(self, name, value)
        self._length, self._hand_model = info["length"], info["hand_model"]

    def frame_at(self, index: int, touches_only: bool = False) -> Frame:
        return self._call("frame_at", index, touches_only)

    def hand_model(self):
        return self._hand_model

    # Read from the state that comes with every reply, never asked for: the session reads
    # them on the mapper's thread, and a call would queue behind the frame the child is
    # making, which at offline pace with sensor.policy=active waits for that thread's advice.
    def damage_report(self) -> dict | None:
        return self._state.get("damage_report")

    def touch_plan(self) -> dict | None:
        return self._state.get("touch_plan")

    def advise(self, frame_index: int, advice) -> None:
        """Handed to the child at once, also while a frame is being made (which may wait
        for this very advice)."""
        self._send(("advise", (frame_index, advice)))

    def close(self) -> None:
        process, self._process = self._process, None
        if process is None:
            return
        atexit.unregister(self.close)
        with contextlib.suppress(OSError, ValueError):  # the child is gone already
            self._send(("close", ()))
        try:
            process.wait(CLOSE_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            log.warning("the sensor's process did not stop within %.0f s; ending it",
                        CLOSE_TIMEOUT_S)  # fmt: skip
            process.kill()  # it ignores SIGTERM (child_main)
            process.wait(CLOSE_TIMEOUT_S)
        self._conn.close()

    def _call(self, method: str, *args):
        if self._process is None:
            self.open()
        with self._call_lock:
            self._send(("call", (method, args)))
            return self._reply(None)

    def _send(self, message: tuple) -> None:
        with self._send_lock:
            self._conn.send(message)

    def _reply(self, timeout_s: float | None):
        """The child's next reply; its error raised here, a dead child a FrameSourceError."""
        started = time.monotonic()
        while not self._conn.poll(1.0):
            if self._process.poll() is not None:
                raise self._ended()
            if timeout_s is not None and time.monotonic() - started > timeout_s:
                raise FrameSourceError(
                    f"the sensor's process did not open within {timeout_s:.0f} s"
                )
        try:
            status, value, cpu_s, state = self._conn.recv()
        except EOFError as exc:  # it died: its end of the pipe closed
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._process.wait(CLOSE_TIMEOUT_S)
            raise self._ended() from exc
        self.process_cpu_s, self._state = cpu_s, state
        if status == "error":
            raise value
        return value

    def _ended(self) -> FrameSourceError:
        return FrameSourceError(
            f"the sensor's process ended (exit code {self._process.returncode}) without a "
            "reply; run with mapping.acquire_process=false to see its error"
        )


def child_main(fd: int) -> None:
    """The child interpreter: take the sensor's recipe from the pipe at `fd`, open it,
    then answer calls until told to close."""
    # The parent ends the run on Ctrl-C or a scheduler's SIGTERM (sent to the whole process
    # group) and closes this process; the signal here would only end the stream with an
    # error before the parent has written its outputs.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    conn = Connection(fd)
    try:
        _, (build, nice) = conn.recv()
    except BaseException as exc:  # noqa: BLE001 - a recipe that does not unpickle here
        _answer(conn, "error", _with_traceback(exc))
        return
    _serve(conn, build, nice)


def _serve(conn, build: Callable[[], IndexedSensor], nice: int) -> None:
    lower_this_thread(nice)
    try:
        sensor = build()
        if not isinstance(sensor, IndexedSensor):
            raise TypeError(f"{type(sensor).__name__} cannot make frames by index")
        sensor.open()
        static = {name: getattr(sensor, name, None) for name in STATIC}
        info = {"static": static, "length": len(sensor), "hand_model": sensor.hand_model()}
    except BaseException as exc:  # noqa: BLE001 - the parent raises it
        _answer(conn, "error", _with_traceback(exc))
        return
    _answer(conn, "ok", info, sensor)
    calls: queue.Queue = queue.Queue()
    threading.Thread(target=_read, args=(conn, sensor, calls), daemon=True).start()
    try:
        while (call := calls.get()) is not None:
            method, args = call
            try:
                _answer(conn, "ok", getattr(sensor, method)(*args), sensor)
            except BaseException as exc:  # noqa: BLE001 - the parent raises it
                _answer(conn, "error", _with_traceback(exc), sensor)
    finally:
        sensor.close()


def _read(conn, sensor: IndexedSensor, calls: queue.Queue) -> None:
    """Advice goes to the sensor as it arrives; calls queue for the serving thread."""
    try:
        while True:
            kind, payload = conn.recv()
            if kind == "advise":
                sensor.advise(*payload)
            elif kind == "call":
                calls.put(payload)
            else:
                break
    except (EOFError, OSError):
        pass  # the parent is gone
    calls.put(None)


def _with_traceback(exc: BaseException) -> BaseException:
    """`exc` with the child's traceback as a note (a pickled exception loses its own)."""
    if hasattr(exc, "add_note"):  # Python 3.11+
        exc.add_note("in the sensor's process:\n" + traceback.format_exc().rstrip())
    return exc


def _answer(conn, status: str, value, sensor: IndexedSensor | None = None) -> None:
    cpu_s = time.process_time()
    state = {}
    if sensor is not None:
        state = {name: getattr(sensor, name)() for name in STATE if hasattr(sensor, name)}
    try:
        conn.send((status, value, cpu_s, state))
    except Exception as exc:  # noqa: BLE001 - an error that does not pickle: its text
        error = FrameSourceError(f"{type(value).__name__}: {value} ({exc})")
        conn.send(("error", error, cpu_s, state))
