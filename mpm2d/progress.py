"""Progress of a run on stderr: simulated time done, wall time per step, time left.

On a terminal a tqdm bar redraws in place; otherwise (a log file, a pipe, a batch job) plain
lines, one at most every ``line_every`` wall seconds and one at the end, each complete on its
own (no carriage returns, no bar characters)::

    intruder: 25.2% t = 0.005043/0.02 s, step 4428, 15 ms/step, 1:06 elapsed, ~3:16 left
"""

from __future__ import annotations

import sys
import time

from tqdm import tqdm


def _clock(seconds: float) -> str:
    s = int(round(max(seconds, 0.0)))
    h, m = divmod(s, 3600)
    m, s = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Progress:
    """Progress over the simulated time from ``t0`` to ``t_end`` [s] of a run.

    The postfix (or line) shows the simulated time, the step number and the wall time per step
    since the start (or the resume); the time left extrapolates the simulated time per wall
    second so far. ``interval``: the bar's refresh [wall s] on a terminal; ``line_every``: the
    wall seconds between plain lines otherwise.
    """

    def __init__(self, t0: float, t_end: float, step0: int = 0, stream=None, interval=0.5,
                 label="", line_every: float = 30.0):
        self.t0, self.t_end, self.step0 = float(t0), float(t_end), int(step0)
        self.stream = stream or sys.stderr
        self.label = label or "mpm2d"
        self.start = time.perf_counter()
        self.done = 0.0
        self.line_every = float(line_every)
        self.next_line = self.start + self.line_every
        self.bar = None
        if hasattr(self.stream, "isatty") and self.stream.isatty():
            self.bar = tqdm(total=max(self.t_end - self.t0, 0.0), initial=0.0, file=self.stream,
                            desc=self.label, unit="s(sim)", unit_scale=False,
                            dynamic_ncols=True, mininterval=interval, leave=True,
                            bar_format="{desc}: {percentage:5.1f}%|{bar}| "
                                       "[{elapsed}<{remaining}{postfix}]")
            self.bar.set_postfix_str(self._postfix(self.t0, self.step0), refresh=False)

    def _postfix(self, t: float, step: int) -> str:
        steps = max(step - self.step0, 1)
        per = (time.perf_counter() - self.start) / steps
        return f"t = {t:.4g}/{self.t_end:.4g} s, step {step}, {per * 1e3:.3g} ms/step"

    def line(self, t: float, step: int) -> str:
        """The plain progress line at simulated time ``t`` [s], step ``step``."""
        span = max(self.t_end - self.t0, 1e-300)
        frac = min(max((t - self.t0) / span, 0.0), 1.0)
        wall = time.perf_counter() - self.start
        left = wall * (1.0 - frac) / frac if frac > 0 else float("nan")
        tail = f", ~{_clock(left)} left" if frac < 1.0 and left == left else ""
        return (f"{self.label}: {100 * frac:5.1f}% {self._postfix(t, step)}, "
                f"{_clock(wall)} elapsed{tail}")

    def update(self, t: float, step: int) -> None:
        """Advance to simulated time ``t`` [s] at step ``step``."""
        if self.bar is None:
            now = time.perf_counter()
            if now >= self.next_line:
                self.next_line = now + self.line_every
                print(self.line(t, step), file=self.stream, flush=True)
            return
        target = min(max(t - self.t0, 0.0), self.bar.total)
        delta = target - self.done
        if delta > 0:
            self.done = target
            self.bar.set_postfix_str(self._postfix(t, step), refresh=False)
            self.bar.update(delta)

    def close(self, t: float, step: int) -> None:
        """The last line (or the bar's last state)."""
        if self.bar is None:
            print(self.line(t, step), file=self.stream, flush=True)
            return
        self.bar.set_postfix_str(self._postfix(t, step), refresh=False)
        self.update(t, step)
        self.bar.refresh()
        self.bar.close()
