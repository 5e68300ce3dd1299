"""Farm-friendly output of long CLI runs: a progress line per unit of work (done/left, time per
unit, time left), and a quiet mode that drops Blender's own log (Cycles' per-frame "Saved:" and
"Fra:" lines) instead of sending it to stderr."""
from __future__ import annotations

import contextlib
import os
import sys
import time


QUIET_HELP = "farm logs: drop Blender's own log (Cycles' 'Saved:' lines); keep PlateLight's progress lines"


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    minutes, seconds = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes} min {seconds:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


class Progress:
    """``step(label)`` after each unit: prints 'platelight render: frame 7 done (3/10, 7 left),
    4.1 s; 4.3 s per frame, about 30 s left' on stderr."""

    def __init__(self, command: str, total: int, unit: str = "frame", stream=None):
        self.command, self.total, self.unit = command, total, unit
        self.stream = stream or sys.stderr
        self.done = 0
        self.start = self.last = time.monotonic()

    def step(self, label: str) -> str:
        now = time.monotonic()
        self.done += 1
        this, mean = now - self.last, (now - self.start) / self.done
        self.last = now
        left = self.total - self.done
        line = (f"platelight {self.command}: {label} done ({self.done}/{self.total}, {left} left), "
                f"{this:.1f} s; {mean:.1f} s per {self.unit}")
        if left:
            line += f", about {_duration(mean * left)} left"
        print(line, file=self.stream, flush=True)
        return line


@contextlib.contextmanager
def blender_output(quiet: bool, log_path=None):
    """While Blender works: its C-level stdout goes to stderr (stdout keeps only PlateLight's
    summary), or, when ``quiet``, both its stdout and stderr go to /dev/null, or, given
    ``log_path``, both are appended to that file. Yields a stream to the real stderr, for
    PlateLight's own lines inside the block (progress callbacks)."""
    both = quiet or log_path is not None
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)] if both else [os.dup(1)]
    if log_path is not None:
        target = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    else:
        target = os.open(os.devnull, os.O_WRONLY) if quiet else 2
    log = os.fdopen(os.dup(saved[1] if both else 2), "w", buffering=1)
    # Python's own prints (operator reports among them) follow the descriptors too, also where a
    # harness has replaced sys.stdout with a stream that bypasses them.
    python_streams = sys.stdout, sys.stderr
    try:
        os.dup2(target, 1)
        sys.stdout = open(1, "w", buffering=1, closefd=False)
        if both:
            os.dup2(target, 2)
            sys.stderr = open(2, "w", buffering=1, closefd=False)
        yield log
    finally:
        log.close()
        sys.stdout.flush()
        sys.stderr.flush()
        if sys.stdout is not python_streams[0]:
            sys.stdout.close()
        if sys.stderr is not python_streams[1]:
            sys.stderr.close()
        sys.stdout, sys.stderr = python_streams
        os.dup2(saved[0], 1)
        if both:
            os.dup2(saved[1], 2)
            os.close(target)
        for fd in saved:
            os.close(fd)
