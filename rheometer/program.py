"""Test programs written the way rheologists say them, one step per line.

::

    # a rate sweep up and down (hysteresis)
    start at rest
    ramp rate from 0.01 to 1 1/s over 120 s log
    ramp rate from 1 to 0.01 1/s over 120 s log
    rest for 60 s

Lines (case-insensitive; ``#`` starts a comment; blank lines are ignored):

=============================================================  ==================================
``shear at <rate> 1/s for <time> s``                            constant shear rate
``shear at <rate> 1/s until strain <x>``                        ... until the strain grew by x
``stress <tau> Pa for <time> s``                                constant mixture shear stress
``stress <tau> Pa until strain <x> [within <time> s]``          creep until a strain (time limit)
``rest for <time> s``                                           zero shear rate (relaxation)
``ramp rate from <a> to <b> 1/s over <time> s [log|linear]``    rate ramp (default log)
``ramp stress from <a> to <b> Pa over <time> s [log|linear]``   mixture-stress ramp (default log)
``oscillate at <F> Hz with strain <A> for <N> cycles``          strain A sin(2 pi F t')
``oscillate at <F> Hz with stress <S> Pa for <N> cycles``       mixture stress S sin(2 pi F t')
``start at rest``                                               initial state (default), first
``start from steady stress <tau> Pa``                           steady state at granular stress
``start from steady rate <rate> 1/s``                           lowest stable steady state
=============================================================  ==================================

An oscillation (t' the time since the step began) runs from whatever state the previous step left
(the strain oscillates about the strain reached so far; the imposed stress oscillates about zero),
on the same equations as every other step and as ``rheometer oscillation`` (signed stress: where it
reverses the plastic rate follows its sign); its length is ``for <N> cycles`` or ``for <time> s``.
Its rows are sampled at equal phases in every cycle, and the harmonic analysis of its last cycle
(G', G'', I3/I1) is in the result's ``attrs["oscillations"]``.

Units: rates ``1/s``, ``/s``, ``s^-1``; times ``ms``, ``s``, ``min``, ``h``; stresses ``mPa``,
``Pa``, ``kPa``, ``MPa``; strains plain or in ``%``; frequencies ``mHz``, ``Hz``, ``kHz``. A line that cannot be read raises
``ValueError("program line N: ...")`` naming what was expected.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import rheology
from rheology.materials import default_fraction
from rheology.steady import dst_fold

from runkit.limits import ge
from runkit.params import Param

from . import limits
from .transient import DEFAULT_MAX_TIME, Step

_NUM = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"
_RATE_U = r"(1/s|/s|s\^-1|s-1)"
_TIME_U = r"(ms|s|sec|secs|seconds?|min|mins|minutes?|h|hours?)"
_STRESS_U = r"(mPa|Pa|kPa|MPa)"
_TIME = {"ms": 1e-3, "s": 1.0, "sec": 1.0, "secs": 1.0, "second": 1.0, "seconds": 1.0,
         "min": 60.0, "mins": 60.0, "minute": 60.0, "minutes": 60.0, "h": 3600.0,
         "hour": 3600.0, "hours": 3600.0}
_STRESS = {"mPa": 1e-3, "Pa": 1.0, "kPa": 1e3, "MPa": 1e6}
_FREQ = {"mHz": 1e-3, "Hz": 1.0, "kHz": 1e3}
_END = (rf"(?:for\s+{_NUM}\s*{_TIME_U}"
        rf"|until\s+strain\s+{_NUM}\s*(%?)(?:\s+within\s+{_NUM}\s*{_TIME_U})?)")

_FORMS = {
    "shear": (rf"shear\s+(?:at\s+)?{_NUM}\s*{_RATE_U}\s+{_END}",
              "'shear at <rate> 1/s for <time> s' or 'shear at <rate> 1/s until strain <x>'"),
    "stress": (rf"stress\s+(?:at\s+)?{_NUM}\s*{_STRESS_U}\s+{_END}",
               "'stress <tau> Pa for <time> s' or 'stress <tau> Pa until strain <x>'"),
    "rest": (rf"rest\s+for\s+{_NUM}\s*{_TIME_U}", "'rest for <time> s'"),
    "ramp": (rf"ramp\s+(rate|stress)\s+from\s+{_NUM}\s+to\s+{_NUM}\s*"
             rf"(1/s|/s|s\^-1|s-1|mPa|Pa|kPa|MPa)\s+over\s+{_NUM}\s*{_TIME_U}"
             r"(?:\s+(log|logarithmic|linear|lin))?",
             "'ramp rate from <a> to <b> 1/s over <time> s [log|linear]' or "
             "'ramp stress from <a> to <b> Pa over <time> s [log|linear]'"),
    "oscillate": (rf"oscillate\s+at\s+{_NUM}\s*(mHz|Hz|kHz)\s+with\s+(strain|stress)\s+"
                  rf"(?:of\s+)?(?:amplitude\s+)?{_NUM}\s*(%|mPa|Pa|kPa|MPa)?\s+for\s+{_NUM}\s*"
                  rf"(cycles?|{_TIME_U[1:-1]})",
                  "'oscillate at <F> Hz with strain <A> for <N> cycles' or 'oscillate at <F> Hz "
                  "with stress <S> Pa for <N> cycles'"),
    "start": (rf"start\s+(?:at\s+rest|from\s+steady\s+(stress|rate)\s+{_NUM}\s*"
              rf"(1/s|/s|s\^-1|s-1|mPa|Pa|kPa|MPa))",
              "'start at rest', 'start from steady stress <tau> Pa' or "
              "'start from steady rate <rate> 1/s'"),
}


@dataclass(frozen=True)
class Start:
    """Initial state of a program: ``kind`` is "rest", "stress" (granular, Pa) or "rate" (1/s)."""

    kind: str = "rest"
    value: float = 0.0

    def __post_init__(self):
        if self.kind != "rest":
            (limits.STRESS if self.kind == "stress" else limits.RATE).check(self.kind, self.value)


@dataclass(frozen=True)
class Program:
    """A parsed test program: its initial state and steps."""

    start: Start
    steps: tuple[Step, ...]


def _unit(table: dict, unit: str, lineno: int, what: str) -> float:
    """The factor of ``unit`` in ``table``, exact or in any case where that is unambiguous (mPa
    and MPa, mHz and MHz are not); ValueError naming the line otherwise."""
    low = {k.lower(): v for k, v in table.items() if k.lower() not in ("mpa", "mhz")}
    if unit in table or unit.lower() in low:
        return table.get(unit, low.get(unit.lower()))
    *first, last = table
    raise ValueError(f"program line {lineno}: {what} unit {unit!r} is ambiguous or unknown; "
                     f"write {', '.join(first)} or {last}")


def _oscillation(g, lineno: int, line: str):
    """Step of an 'oscillate at F Hz with strain|stress X for N cycles|T s' line."""
    f, fu, what, x, xu, n, nu = g
    freq = float(f) * _unit(_FREQ, fu, lineno, "frequency")
    what = what.lower()
    if what == "strain":
        if xu not in (None, "%"):
            raise ValueError(f"program line {lineno}: a strain amplitude is plain or in %, got "
                             f"{xu}")
        amp = float(x) / (100.0 if xu == "%" else 1.0)
    else:
        if xu in (None, "%"):
            raise ValueError(f"program line {lineno}: a stress amplitude needs Pa"
                             f"{', got %' if xu else ''}")
        amp = float(x) * _unit(_STRESS, xu, lineno, "stress")
    if nu.lower().startswith("cycle"):      # the frequency is the Step's to check
        cycles = float(limits.CYCLES.check("cycles", float(n)))
        duration = cycles / freq if freq != 0 else float("inf")
    else:
        duration = float(n) * _TIME[nu.lower()]
    return Step(what, amp, ramp="sine", frequency=freq, duration=duration, label=line,
                name=_name(lineno, line, what))


def _name(lineno: int, line: str, control: str) -> str:
    """What a refusal calls the imposed value of a program line (at parsing or at the run)."""
    return f"program line {lineno}: imposed {control} of {line!r}"


def _is_rate_unit(unit: str) -> bool:
    return unit.lower() in ("1/s", "/s", "s^-1", "s-1")


def _end(groups, lineno: int, text: str) -> dict:
    """Duration or strain clause from the 5 groups of _END."""
    t, tu, strain, pct, within, wu = groups
    if t is not None:
        return dict(duration=float(t) * _TIME[tu.lower()])
    x = float(strain) / (100.0 if pct else 1.0)
    limit = float(within) * _TIME[wu.lower()] if within is not None else DEFAULT_MAX_TIME
    return dict(strain=x, max_time=limit)


def parse_program(text: str) -> Program:
    """Parse a test program (see module docstring) into a :class:`Program`.

    Raises
    ------
    ValueError
        ``program line N: ...`` naming the line and what was expected; or an empty program.
    """
    start, steps = Start(), []
    t_start = 0.0           # the earliest time the next step can start (strain steps: 0 s long)
    for lineno, raw in enumerate(str(text).splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        word = line.split()[0].lower()
        if word not in _FORMS:
            raise ValueError(f"program line {lineno}: unknown step {line.split()[0]!r}; a line "
                             f"starts with shear, stress, rest, ramp, oscillate or start "
                             f"(e.g. 'shear at 10 1/s for 60 s')")
        pattern, expected = _FORMS[word]
        mt = re.fullmatch(pattern, line, flags=re.IGNORECASE)
        if mt is None:
            raise ValueError(f"program line {lineno}: cannot read {line!r}; expected {expected}")
        g = mt.groups()
        try:
            if word == "start":
                if steps:
                    raise ValueError(f"program line {lineno}: 'start' must come before the first "
                                     f"step")
                if g[0] is None:
                    start = Start()
                elif g[0].lower() == "stress":
                    if _is_rate_unit(g[2]):
                        raise ValueError(f"program line {lineno}: a stress needs Pa, got {g[2]}")
                    start = Start("stress", float(g[1]) * _unit(_STRESS, g[2], lineno, "stress"))
                else:
                    if not _is_rate_unit(g[2]):
                        raise ValueError(f"program line {lineno}: a rate needs 1/s, got {g[2]}")
                    start = Start("rate", float(g[1]))
                continue
            if word == "shear":
                step = Step("rate", float(g[0]), label=line, name=_name(lineno, line, "rate"),
                            **_end(g[2:8], lineno, line))
            elif word == "stress":
                scale = _unit(_STRESS, g[1], lineno, "stress")
                step = Step("stress", float(g[0]) * scale, label=line,
                            name=_name(lineno, line, "stress"), **_end(g[2:8], lineno, line))
            elif word == "oscillate":
                step = _oscillation(g, lineno, line)
            elif word == "rest":
                step = Step("rate", 0.0, duration=float(g[0]) * _TIME[g[1].lower()], label=line)
            else:
                what, a, b, unit, T, tu, kind = g
                what = what.lower()
                if (what == "rate") != _is_rate_unit(unit):
                    raise ValueError(f"program line {lineno}: a {what} ramp needs "
                                     f"{'1/s' if what == 'rate' else 'Pa'}, got {unit}")
                scale = 1.0 if what == "rate" else _unit(_STRESS, unit, lineno, "stress")
                ramp = "linear" if (kind or "log").lower() in ("linear", "lin") else "log"
                step = Step(what, float(a) * scale, float(b) * scale, ramp=ramp,
                            duration=float(T) * _TIME[tu.lower()], label=line,
                            name=_name(lineno, line, what))
            if step.duration is not None:
                Param(ge(limits.clock_floor(t_start), (
                    f"too short for the run's clock where the step starts, t >= {t_start:g} s: "
                    f"{limits.CLOCK_WHY}")), limits.DURATION.hi,
                    unit="s").check("duration", step.duration)
            t_start += step.duration if step.strain is None else 0.0
        except ValueError as exc:
            msg = str(exc)
            raise ValueError(msg if msg.startswith("program line") else
                             f"program line {lineno}: {msg}") from None
        steps.append(step)
    if not steps:
        raise ValueError("the program has no steps (e.g. 'shear at 10 1/s for 60 s')")
    return Program(start, tuple(steps))


def _sig(x: float) -> str:
    """x to two significant digits (program text)."""
    return f"{float(f'{x:.2g}'):g}"


def hysteresis_program(material, phi: float) -> str:
    """The built-in demonstration program for ``material`` at volume fraction ``phi`` (text).

    With DST (a fold in the steady curve, :func:`dst_fold`), from the steady state at the
    lowest rate ``r0 = 0.05 gdot_DST`` (Eq. 33, :func:`rheology.gdot_dst`): (1) a mixture-stress
    sweep from the steady stress at r0 (3 digits) up to 10 times the fold stress and back, 60 s
    each way: the rate rises to the fold then FALLS toward gdot_DST while the stress grows
    tenfold (the S-shaped DST curve, stable under stress control; the way down lags); (2) a rate
    sweep from r0 up to 0.95 of the fold rate and back, 20 s each way: below the fold, so the
    sample flows throughout, and the structure lags the rate (on the way down f and the stress
    are higher: hysteresis). A rate sweep past the fold would
    shear-jam the sample and load it elastically (G times the strain: 1e4-1e6 Pa), hence the
    stress sweep to cross DST. The stress sweep comes first so that it starts from a steady
    state (a stress step below the lagging stress of a rate sweep's end would reverse the flow).
    Without DST at this phi: a rate sweep over 0.01-10 1/s up and down.
    """
    m = rheology.get_material(material)
    fold = dst_fold(m, phi)
    lines = [f"# {m.name} at phi = {phi:g}"]
    if fold is None:
        lines += ["# no DST at this phi: a rate sweep up and down (structure lags: hysteresis)",
                  "start at rest",
                  "ramp rate from 0.01 to 10 1/s over 60 s log",
                  "ramp rate from 10 to 0.01 1/s over 60 s log"]
    else:
        r_fold, s_fold = fold
        gd = float(rheology.gdot_dst(phi, m)) if m.phi_c <= phi <= min(m.phi_star, m.phi_j) \
            else r_fold
        lo, hi = _sig(0.05 * min(gd, r_fold)), _sig(0.95 * r_fold)
        ss = rheology.steady_states_rate(float(lo), phi, m)
        s_lo = f"{float(ss.shear_stress[0]):.3g}"
        s_hi = _sig(10.0 * s_fold)
        lines += [f"# gdot_DST = {gd:.3g} 1/s (Eq. 33); the steady curve folds (DST sets in) at "
                  f"{r_fold:.3g} 1/s, {s_fold:.3g} Pa",
                  f"start from steady rate {lo} 1/s",
                  "# stress sweep across DST: the rate peaks at the fold, then falls toward "
                  "gdot_DST",
                  f"ramp stress from {s_lo} to {s_hi} Pa over 60 s log",
                  f"ramp stress from {s_hi} to {s_lo} Pa over 60 s log",
                  "# rate sweep below the fold: on the way down the structure lags (hysteresis)",
                  f"ramp rate from {lo} to {hi} 1/s over 20 s log",
                  f"ramp rate from {hi} to {lo} 1/s over 20 s log"]
    return "\n".join(lines) + "\n"


#: The built-in program of ``rheometer program`` (no file): :func:`hysteresis_program` of the
#: default material (hermes2016) at its default volume fraction (0.50, rheology.materials).
HYSTERESIS_PROGRAM = hysteresis_program("hermes2016", default_fraction("hermes2016"))
