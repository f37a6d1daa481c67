"""Progress of a run on stderr through tqdm: simulated time done, wall time per step, ETA."""

from __future__ import annotations

import sys
import time

from tqdm import tqdm


class Progress:
    """A tqdm bar over the simulated time ``t0 .. t_end`` [s] of a run.

    The bar counts simulated seconds (so tqdm's rate and ETA are in simulated time per wall
    second); the postfix shows the step number and the wall time per step since the start (or
    the resume). On a terminal the bar redraws in place; otherwise (a log file) tqdm writes a
    line at most every ``interval * 20`` seconds.
    """

    def __init__(self, t0: float, t_end: float, step0: int = 0, stream=None, interval=0.5,
                 label=""):
        self.t0, self.t_end, self.step0 = float(t0), float(t_end), int(step0)
        stream = stream or sys.stderr
        tty = hasattr(stream, "isatty") and stream.isatty()
        self.start = time.perf_counter()
        self.done = 0.0
        self.bar = tqdm(total=max(self.t_end - self.t0, 0.0), initial=0.0, file=stream,
                        desc=label or None, unit="s(sim)", unit_scale=False, dynamic_ncols=True,
                        mininterval=interval if tty else 20 * interval, leave=True,
                        bar_format="{desc}: {percentage:5.1f}%|{bar}| "
                                   "[{elapsed}<{remaining}{postfix}]")
        self.bar.set_postfix_str(self._postfix(self.t0, self.step0), refresh=False)

    def _postfix(self, t: float, step: int) -> str:
        steps = max(step - self.step0, 1)
        per = (time.perf_counter() - self.start) / steps
        return f"t = {t:.4g}/{self.t_end:.4g} s, step {step}, {per * 1e3:.3g} ms/step"

    def update(self, t: float, step: int) -> None:
        """Advance to simulated time ``t`` [s] at step ``step``."""
        target = min(max(t - self.t0, 0.0), self.bar.total)
        delta = target - self.done
        if delta > 0:
            self.done = target
            self.bar.set_postfix_str(self._postfix(t, step), refresh=False)
            self.bar.update(delta)

    def close(self, t: float, step: int) -> None:
        self.bar.set_postfix_str(self._postfix(t, step), refresh=False)
        self.update(t, step)
        self.bar.refresh()
        self.bar.close()
