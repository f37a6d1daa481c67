"""A text progress bar on stderr with the wall time per step and the remaining time."""

from __future__ import annotations

import sys
import time


class Progress:
    """Progress of a run from ``t0`` to ``t_end`` [s] of simulated time.

    Redraws at most every ``interval`` seconds of wall time: in place (carriage return) on a
    terminal, as a new line every ``10 * interval`` seconds otherwise (logs stay short).
    """

    def __init__(self, t0: float, t_end: float, step0: int = 0, stream=None, interval=0.5,
                 label=""):
        self.t0, self.t_end, self.step0 = t0, t_end, step0
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.interval = interval if self.tty else 10.0 * interval
        self.start = self.last = time.perf_counter()
        self.label = label
        self.width = 30

    def line(self, t: float, step: int) -> str:
        now = time.perf_counter()
        frac = min(max((t - self.t0) / max(self.t_end - self.t0, 1e-300), 0.0), 1.0)
        steps = max(step - self.step0, 1)
        per = (now - self.start) / steps
        eta = (now - self.start) * (1.0 - frac) / frac if frac > 0 else float("nan")
        bar = "#" * int(self.width * frac) + "-" * (self.width - int(self.width * frac))
        return (f"{self.label}[{bar}] {100 * frac:5.1f}%  t = {t:.4g}/{self.t_end:.4g} s  "
                f"step {step}  {per * 1e3:.3g} ms/step  ETA {eta:.0f} s")

    def update(self, t: float, step: int) -> None:
        now = time.perf_counter()
        if now - self.last < self.interval:
            return
        self.last = now
        self.stream.write(("\r" if self.tty else "") + self.line(t, step) + ("" if self.tty else "\n"))
        self.stream.flush()

    def close(self, t: float, step: int) -> None:
        self.stream.write(("\r" if self.tty else "") + self.line(t, step) + "\n")
        self.stream.flush()
