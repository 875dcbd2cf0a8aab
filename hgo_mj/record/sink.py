"""The row sink: the one place where a recording talks to rerun.

:class:`RowSink` owns an explicit :class:`rerun.RecordingStream` (never rerun's global or
thread default) with a file sink (a temporary beside the ``.rrd`` path, renamed onto it when
closed and checked, as every file hgo_mj writes), and sends what the recorder computed: columns of rows
(``rr.send_columns`` with ``rr.TimeColumn`` indexes, one call per entity and block), static
styles and geometry (``rr.log(..., static=True)``), text documents, recording properties and
the blueprint. It decides nothing about what is sent (:mod:`hgo_mj.record.rows`,
:mod:`hgo_mj.record.layout`); it paces flushes and closes the file, raising
:class:`~hgo_mj.exceptions.RecordingError` where rerun would only log a failed write.

Internal: :class:`hgo_mj.record.Recorder` is the public interface.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from .._io import temporary_beside
from ..exceptions import DesignError, RecordingError
from .layout import EPISODE, SIM_TIME, STEP

#: least wall time between two flushes started after blocks, seconds
FLUSH_INTERVAL = 0.25
#: the chunk batcher of a recorder's own stream (rerun's default holds chunks up to 200 ms or
#: 2 MiB: the file writer would then encode a run's last blocks at close)
BATCHER = rr.ChunkBatcherConfig(flush_tick=0.01, flush_num_bytes=262144)
#: streams whose file sink failed, kept for the rest of the process (see :meth:`RowSink.close`)
STUCK: list[Any] = []


class DeferSigint:
    """Hold a SIGINT (Ctrl-C) until a block is written, so a chunk is never half-recorded."""

    def __enter__(self) -> DeferSigint:
        self._old: Any = None
        self._hit = False
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            self._old = signal.signal(signal.SIGINT, self._handler)
        return self

    def _handler(self, signum: int, frame: Any) -> None:
        self._hit = True

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
        if self._hit and et is None:
            raise KeyboardInterrupt


def time_columns(t: Any, steps: Any, episode: int | None, *,
                 step: bool = True) -> list[rr.TimeColumn]:
    """The ``sim_time`` (nanoseconds), ``step`` (unless ``step=False``) and ``episode`` index
    columns of rows."""
    ns = np.rint(np.asarray(t, dtype=float) * 1e9).astype(np.int64).astype("timedelta64[ns]")
    cols = [rr.TimeColumn(SIM_TIME, duration=ns)]
    if step:
        cols.append(rr.TimeColumn(STEP, sequence=np.asarray(steps, dtype=np.int64)))
    if episode is not None:
        cols.append(rr.TimeColumn(EPISODE, sequence=np.full(ns.size, int(episode), np.int64)))
    return cols


class RowSink:
    """A rerun stream with (optionally) a file sink on ``path``; sends columns and static data.

    ``stream`` given: written through as it is (its sinks set by the caller), a file sink
    added on ``path`` when one is given. A file that cannot be opened is a
    :class:`~hgo_mj.exceptions.RecordingError`.
    """

    def __init__(self, path: Path | None, stream: rr.RecordingStream | None,
                 application_id: str, footer: bool, recording_name: str | None) -> None:
        self.path = path
        self.own_file = path is not None
        self.footer = bool(footer)
        if stream is None:
            if path is None:
                raise DesignError("give a path for the .rrd file, or a stream with its sinks set")
            stream = rr.RecordingStream(application_id, make_default=False,
                                        make_thread_default=False, batcher_config=BATCHER)
        elif not isinstance(stream, rr.RecordingStream):
            raise DesignError(f"stream must be a rerun.RecordingStream; found "
                              f"{type(stream).__name__}")
        #: the file written: a temporary beside ``path``, renamed onto it by :meth:`publish`
        self.file: Path | None = None
        if path is not None:
            if path.suffix != ".rrd":
                raise DesignError(f"a recording path must end in .rrd; found {str(path)!r}")
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                self.file = Path(temporary_beside(path))
                stream.save(self.file, write_footer=self.footer)
            except (RuntimeError, OSError) as exc:  # the header could not be written
                self.discard()
                raise RecordingError(f"cannot write the recording {str(path)!r}: "
                                     f"{exc}") from None
        self.stream = stream
        if recording_name:
            stream.send_recording_name(recording_name)
        self._flushed = time.monotonic()  # the first flush 0.25 s after the start

    # ------------------------------------------------------------------ sending
    def scalars(self, path: str, index: list[rr.TimeColumn], values: Any) -> None:
        """One entity's rows of scalars (``(T,)`` or ``(T, k)``)."""
        rr.send_columns(path, indexes=index,
                        columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)),
                        recording=self.stream)

    def transforms(self, path: str, index: list[rr.TimeColumn], translation: Any,
                   quaternion: Any) -> None:
        """One body's rows of 3D poses (``xyzw`` quaternions)."""
        rr.send_columns(path, indexes=index,
                        columns=rr.Transform3D.columns(translation=translation,
                                                       quaternion=quaternion),
                        recording=self.stream)

    def static(self, items: Sequence[tuple[str, Sequence[Any]]]) -> None:
        """Log ``(path, archetypes)`` pairs as static data."""
        for path, archetypes in items:
            rr.log(path, *archetypes, static=True, recording=self.stream)

    def document(self, path: str, text: str) -> None:
        """A static markdown document."""
        rr.log(path, rr.TextDocument(text, media_type="text/markdown"), static=True, strict=True,
               recording=self.stream)
        self.tick()

    def properties(self, name: str, values: dict[str, Any]) -> None:
        """Recording properties ``name`` (``rr.AnyValues``)."""
        self.stream.send_property(name, rr.AnyValues(**values))

    def blueprint(self, bp: rrb.Blueprint) -> None:
        """The recording's default (and active) blueprint."""
        self.stream.send_blueprint(bp, make_active=True, make_default=True)

    # ------------------------------------------------------------------ lifetime
    def tick(self) -> None:
        """After a block: start a flush to the file without waiting for it, at most every
        :data:`FLUSH_INTERVAL` seconds of wall time (rerun's own thread writes each block
        within a few milliseconds anyway)."""
        now = time.monotonic()
        if now - self._flushed >= FLUSH_INTERVAL:
            self._flushed = now
            self.stream.flush(timeout_sec=0.0)

    def flush(self) -> None:
        """Wait until everything sent is written."""
        self.stream.flush()

    def close(self, timeout: float) -> None:
        """Flush and, for an own file, disconnect (rerun writes the footer and closes it). A
        stream handed in without a path is flushed, not disconnected.

        A file sink that cannot write everything within ``timeout`` seconds has failed (rerun
        only logs the failed write, and a flush waiting on it never returns, rerun-sdk 0.41):
        the stream is kept for the rest of the process (its shutdown would wait for ever) and
        :class:`~hgo_mj.exceptions.RecordingError` raised.
        """
        if not self.own_file:
            self.stream.flush()
            return
        try:
            self.stream.flush(timeout_sec=timeout)
        except RuntimeError as exc:  # the sink failed: its shutdown would never return
            import atexit

            STUCK.append(self.stream)
            atexit.unregister(rr.rerun_shutdown)
            self.discard()
            raise RecordingError(f"the recording {str(self.path)!r} could not be written "
                                 f"({exc}: is the disk full?); an earlier file there is kept"
                                 ) from None
        self.stream.disconnect()  # the file sink writes its footer and closes the file

    def publish(self) -> None:
        """Rename the closed temporary onto ``path`` (the earlier recording there, if any, is
        replaced only now: a kill or a failed write before leaves it intact)."""
        if self.file is not None:
            os.replace(self.file, self.path)  # type: ignore[arg-type]
            self.file = None

    def discard(self) -> None:
        """Remove the temporary of a recording that failed."""
        if self.file is not None:
            with contextlib.suppress(FileNotFoundError):
                self.file.unlink()
            self.file = None


__all__: list[str] = []
