"""Transient tests of the 0-D model on SUNDIALS IDA: a :class:`Rheometer` runs a list of steps.

A :class:`Step` imposes a shear rate or a mixture shear stress, constant or ramped (linear or
logarithmic), for a duration or until a strain; "rest" is a zero rate; an oscillation imposes
the strain ``gamma0 sin(omega (t - t_s))`` (as the rate, about the strain reached so far) or the
mixture stress ``sigma0 sin(omega (t - t_s))`` for a number of cycles. A step is one IDA solve
of the DAE of :mod:`rheometer.model` (signed stress) from a consistent state, restarted at each
jamming/unjamming event. After every solve the state is checked (finite, ``0 <= f <= max(f0,
f_m)``, the plastic rate of the stress's sign); a violation, a failed solve and, with
``elastic_limit=True`` (every command line run), an elastic strain taubar/G past
:data:`rheology.elastic.ELASTIC_STRAIN_LIMIT` end the run there
(:class:`rheology.run_end.EndedEarly`, the rows before it kept).

An oscillation step samples every cycle at the same phases; the harmonic analysis of its last
full cycle (as :mod:`rheometer.oscillation`) is in ``attrs["oscillations"]``.

Defaults where the material has none: ``G = 1e4 Pa`` (Fig. 15: relaxation times of tens of
seconds need G ~ 10 kPa) and ``K0 = 1`` (Tables 5 and 7).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

import rheology
from rheology import laws
from rheology.elastic import (ELASTIC_STRAIN_LIMIT, elastic_strain_limit_stress,
                              past_elastic_limit)
from rheology.materials import Material
from rheology.run_end import EndedEarly, RunEnd
from runkit.ida import IDAFailed, Solver
from runkit.limits import PHI_MIN, le, lt
from runkit.params import Param, check_nonnegative, check_positive, check_range

from . import limits, model
from .harmonics import cycle_harmonics
from .model import GAP, GD, GP, NEVENTS, NVAR, STRAIN, TAU

#: Defaults for materials without G or K0 (see module docstring).
DEFAULT_G = 1.0e4
DEFAULT_K0 = 1.0
#: Longest time a step "until strain ..." may run when it gives no limit [s].
DEFAULT_MAX_TIME = 1.0e4

#: Rows of the output interval in which a run reaches the elastic-strain limit (resolved again).
END_ROWS = 32
#: What to change when a run ends at the elastic-strain limit.
_ADVICE = ("impose a lower rate or stress or a shorter time (a shear-jammed sample under an "
           "imposed rate strains elastically by the imposed strain), or a stiffer skeleton (--G) "
           "under an imposed stress")
#: Output columns of every transient (units in the names).
COLUMNS = ("time_s", "step", "strain", "shear_rate_per_s", "shear_stress_Pa",
           "granular_shear_stress_Pa", "plastic_shear_rate_per_s", "f", "granular_pressure_Pa",
           "viscosity_Pa_s", "jamming_gap")


def check_phi(name: str, phi, m: Material, where: str = "", source: str = "") -> float:
    """The volume fraction ``phi`` in [PHI_MIN, phi_j) of ``m`` (runkit.limits.PHI_MIN = 1e-6,
    the dilute limit): the one check of every entry point (the command line's ``--phi`` too);
    ValueError naming ``name``, and where phi_j came from: ``source`` (e.g. ``"(--set
    phi_j)"``), default ``"of <material name>"``."""
    why = (f"{where}below phi_j = {m.phi_j:g} {source or 'of ' + m.name}: no steady flow at or "
           "above it")
    return float(Param(PHI_MIN, lt(m.phi_j, why)).check(name, phi))


def skeleton(m: Material, G=None, K0=None) -> tuple[float, float]:
    """(G [Pa], K0 [-]): as given, else the material's, else :data:`DEFAULT_G`,
    :data:`DEFAULT_K0`; ValueError for G <= 0 or K0 < 0."""
    G = check_positive("G [Pa]", G if G is not None else (m.G or DEFAULT_G))
    K0 = check_nonnegative("K0", K0 if K0 is not None else
                           (m.K0 if m.K0 is not None else DEFAULT_K0))
    return float(G), float(K0)


@dataclass(frozen=True)
class Maxwell:
    """Linearised model at rest: Maxwell element (G, eta_g) in parallel with the fluid eta_F.

    Attributes
    ----------
    G : granular shear modulus [Pa]
    eta_g : granular low-stress viscosity (Eq. 24, granular part) [Pa s]
    eta_F : fluid-phase viscosity eta0 (1 + 5/2 phi) [Pa s]
    relaxation_time : eta_g/G [s]
    """

    G: float
    eta_g: float
    eta_F: float

    @property
    def relaxation_time(self) -> float:
        return self.eta_g / self.G

    def modulus(self, omega) -> np.ndarray:
        """G*(omega) = G i omega lambda/(1 + i omega lambda) + i omega eta_F [Pa] (complex)."""
        w = np.asarray(omega, dtype=float)
        iwl = 1j * w * self.relaxation_time
        return self.G * iwl / (1.0 + iwl) + 1j * w * self.eta_F


def drive(control: str, amplitude: float, omega: float, t0: float = 0.0, duration: float = 0.0,
          strain_target: float = np.inf) -> np.ndarray:
    """Control vector (:func:`rheometer.model.control`) of an oscillation from ``t0`` [s]: strain
    ``amplitude sin(omega (t - t0))`` imposed as the rate ``amplitude omega cos(...)``
    (``control="strain"``), or mixture stress ``amplitude sin(omega (t - t0))`` [Pa]
    (``"stress"``); the model's residual (signed stress) integrates either."""
    if control == "strain":
        return model.control(model.RATE, model.COSINE, amplitude * omega, omega, t0, duration,
                             strain_target)
    return model.control(model.STRESS, model.SINE, amplitude, omega, t0, duration, strain_target)


@dataclass(frozen=True)
class Step:
    """One step of a test.

    Attributes
    ----------
    control : {"rate", "stress", "strain"}
        Imposed shear rate [1/s] or imposed mixture shear stress [Pa]; rest is rate 0. "strain"
        (strain amplitude [-]) only for an oscillation (``ramp="sine"``).
    start, end : float
        Imposed value at the start and end of the step (equal for a constant step); the
        amplitude of an oscillation (> 0).
    ramp : {"const", "linear", "log", "sine"}
        How the value goes from start to end over ``duration``; "sine": an oscillation
        ``start sin(2 pi frequency (t - t_step))`` of the strain or the mixture stress.
    duration : float or None
        Length of the step [s] (None: until ``strain`` is reached, at most ``max_time``); of an
        oscillation, cycles/frequency.
    strain : float or None
        Strain increment [-] at which the step ends (None: runs for ``duration``).
    max_time : float
        Longest time a step ending on strain may run [s].
    label : str
        Text shown in plots and tables (e.g. the program line).
    frequency : float or None
        Frequency of an oscillation [Hz] (only with ``ramp="sine"``).
    name : str
        What a refusal calls the imposed value: the option or program line it came from
        (default ``"imposed <control>"``).
    duration_name : str
        What a refusal calls the duration (default ``"duration"``; the command line's
        ``--t-end``).
    quantity : runkit.params.Param or None
        Its valid values (default :data:`rheometer.limits.RATE` or ``STRESS``); the one static
        check, the liquid's rate limit is :meth:`Rheometer.run`'s (it needs eta_F).
    """

    control: str
    start: float
    end: float | None = None
    ramp: str = "const"
    duration: float | None = None
    strain: float | None = None
    max_time: float = DEFAULT_MAX_TIME
    label: str = ""
    frequency: float | None = None
    name: str = ""
    quantity: Param | None = None
    duration_name: str = ""

    def __post_init__(self) -> None:
        if self.control not in ("rate", "stress", "strain"):
            raise ValueError(f"step control = {self.control!r} must be 'rate', 'stress' or "
                             f"'strain' (oscillation)")
        if self.ramp not in ("const", "linear", "log", "sine"):
            raise ValueError(f"step ramp = {self.ramp!r} must be 'const', 'linear', 'log' or "
                             f"'sine'")
        if self.ramp == "sine":
            self._check_oscillation()
        elif self.control == "strain":
            raise ValueError("a strain-controlled step is an oscillation (ramp 'sine')")
        elif self.frequency is not None:
            raise ValueError("only an oscillation (ramp 'sine') has a frequency")
        if self.end is None:
            object.__setattr__(self, "end", self.start)
        if not self.oscillation:
            value = self.quantity or (limits.RATE if self.control == "rate" else limits.STRESS)
            value.check(self.value_name, self.start)
            if self.end != self.start:
                value.check(f"{self.value_name} at the end of the ramp", self.end)
        if self.ramp == "log" and (self.start <= 0 or self.end <= 0):
            unit = "1/s" if self.control == "rate" else "Pa"
            raise ValueError(f"a log ramp needs positive values, got {self.start:g} to "
                             f"{self.end:g} {unit} (use a linear ramp to or from 0)")
        if self.ramp != "const" and self.duration is None:
            raise ValueError("a ramp needs a duration ('over T s')")
        if self.duration is None and self.strain is None:
            raise ValueError("a step needs a duration ('for T s') or a strain ('until strain X')")
        if self.duration is not None:
            limits.DURATION.check(self.duration_name or "duration", self.duration)
        if self.strain is not None:
            limits.STRAIN.check("step strain", self.strain)
        limits.DURATION.check("max_time", self.max_time)

    def _check_oscillation(self) -> None:
        if self.control not in ("strain", "stress"):
            raise ValueError(f"an oscillation imposes a strain or a stress amplitude, not a "
                             f"{self.control}")
        limits.AMPLITUDE[self.control].check(f"{self.control} amplitude", self.start)
        if self.end is not None and self.end != self.start:
            raise ValueError("an oscillation has one amplitude (end = start)")
        if self.frequency is None:
            raise ValueError("an oscillation needs a frequency [Hz]")
        limits.FREQUENCY.check("oscillation frequency", self.frequency)
        if self.control == "strain":
            limits.check_peak_rate(self.frequency, self.start)
        if self.strain is not None:
            raise ValueError("an oscillation runs for a number of cycles, not until a strain")
        if self.duration is None:
            raise ValueError("an oscillation needs a duration (cycles/frequency)")

    @property
    def value_name(self) -> str:
        """What a refusal calls the imposed value."""
        return self.name or f"imposed {self.control}"

    @property
    def t_max(self) -> float:
        """Longest time the step may last [s]."""
        return self.duration if self.duration is not None else self.max_time

    @property
    def oscillation(self) -> bool:
        """Whether the step is an oscillation."""
        return self.ramp == "sine"

    @property
    def omega(self) -> float:
        """Angular frequency of an oscillation [rad/s] (0 for other steps)."""
        return 2.0 * np.pi * self.frequency if self.oscillation else 0.0

    @property
    def cycles(self) -> float:
        """Number of cycles of an oscillation (0 for other steps)."""
        return self.duration * self.frequency if self.oscillation else 0.0


@dataclass
class State:
    """State of the sample between steps.

    Attributes
    ----------
    t : time [s]
    taubar : granular shear stress [Pa]
    gap : jamming gap phi_m(f) - phi [-] (<= 0 when jammed); it carries the structure exactly
    strain : accumulated shear strain [-]
    f : structure [-] (derived from the gap; informative)
    """

    t: float
    taubar: float
    gap: float
    strain: float = 0.0
    f: float = float("nan")


@dataclass
class _Piece:
    t: np.ndarray
    y: np.ndarray
    step: int


def _joined(pieces) -> tuple:
    """(t, y, step index) of the pieces' rows, in order."""
    return (np.concatenate([p.t for p in pieces]), np.concatenate([p.y for p in pieces]),
            np.concatenate([np.full(p.t.size, p.step) for p in pieces]))


@dataclass
class Progress:
    """A run between two steps: the rows so far (t, unknowns y, step index), the state at the
    end of the last completed step and the index of the next step; what a checkpoint holds."""

    t: np.ndarray
    y: np.ndarray
    step: np.ndarray
    state: State
    next_step: int
    events: list = field(default_factory=list)
    solves: int = 0
    nfev: int = 0
    njev: int = 0

    @classmethod
    def of(cls, pieces, st: State, next_step: int, stats: "RunStats") -> "Progress":
        return cls(*_joined(pieces), st, next_step, list(stats.events), stats.solves, stats.nfev,
                   stats.njev)

    def pieces(self) -> list:
        return [_Piece(self.t[self.step == k], self.y[self.step == k], int(k))
                for k in np.unique(self.step)]


@dataclass
class RunStats:
    """Solver statistics of a run (summed over every IDA solve)."""

    solves: int = 0
    nfev: int = 0
    njev: int = 0
    seconds: float = 0.0
    events: list = field(default_factory=list)

    def count(self, sol) -> None:
        """Add an IDA solve's counts."""
        self.solves += 1
        self.nfev += int(sol.nfev)
        self.njev += int(sol.njev)


class Rheometer:
    """A virtual rheometer loaded with one material at one volume fraction.

    Parameters
    ----------
    material : str or Material
        Parameter set (see ``rheometer materials``).
    phi : float
        Volume fraction, 0 < phi < phi_j.
    G : float, optional
        Granular shear modulus [Pa]; default the material's, else 1e4 Pa.
    K0 : float, optional
        Structure-rate scale [-]; default the material's, else 1. K0 = 0 freezes f.
    rtol : float
        IDA relative tolerance (1e-13 .. 1e-2).
    atol : float, optional
        Absolute tolerance relative to each unknown's scale; default ``1e-3 rtol``.
    form : {"dae", "ode"}
        "dae": taubar, jamming gap, strain differential, gdot_p and gdot algebraic (default);
        "ode": gdot_p and gdot eliminated (three unknowns).
    jacobian : bool
        Give IDA the exact Jacobian (True) or let it difference the residuals.
    max_restarts : int
        Jamming/unjamming events after which a step stops restarting at events (and only records
        them), against chatter.
    elastic_limit : bool
        End the run (:class:`rheology.run_end.EndedEarly`, the rows before it kept) where the
        elastic strain taubar/G passes :data:`rheology.elastic.ELASTIC_STRAIN_LIMIT` (0.1),
        beyond which the hypoelastic law is used outside its range. The command line always
        sets it; the default False lets tests and validation follow the law's algebra to large
        strains.
    label : callable
        What a refusal calls ``rtol`` and :meth:`run`'s ``points``, ``label(name)`` (the command
        line: its option; default the name itself).
    """

    def __init__(self, material, phi: float, *, G: float | None = None, K0: float | None = None,
                 rtol: float = 1e-7, atol: float | None = None, form: str = "dae",
                 jacobian: bool = True, max_restarts: int = 50, elastic_limit: bool = False,
                 label=str):
        self.material: Material = rheology.get_material(material)
        m = self.material
        self.phi = check_phi("phi", phi, m)
        self.G, self.K0 = skeleton(m, G, K0)
        self.label = label
        self.rtol = float(limits.RTOL.check(label("rtol"), rtol))
        self.atol = float(check_positive("atol", atol)) if atol is not None else 1e-3 * self.rtol
        if form not in ("dae", "ode"):
            raise ValueError(f"form = {form!r} must be 'dae' or 'ode'")
        self.form, self.jacobian, self.max_restarts = form, bool(jacobian), int(max_restarts)
        self.elastic_limit = bool(elastic_limit)
        self.P = model.parameters(m, self.phi, self.G, self.K0)
        self.f_m = float(laws.f_max(self.phi, m.phi_c, m.phi_j, m.Delta))
        self.f_jam = (m.phi_j - self.phi) / (m.phi_j - m.phi_c)
        self.eta_fluid = float(self.P[-1])
        self.eta_low = m.eta0 * float(rheology.granular_viscosity(self.phi, 0.0, m))

    # ------------------------------------------------------------------ initial states
    def state(self, taubar: float, f: float, t: float = 0.0, strain: float = 0.0) -> State:
        """A state from the granular shear stress [Pa] and the structure f."""
        check_nonnegative("granular shear stress [Pa]", taubar)
        f = float(check_range("f", f, 0.0, 1.0))
        gap = float(model.gap_of_structure(f, self.P))
        return State(float(t), float(taubar), gap, float(strain), f)

    def rest(self, f0: float = 0.0) -> State:
        """The sample at rest: no stress, structure ``f0`` (default 0, the state at rest)."""
        return self.state(0.0, f0)

    def steady(self, taubar: float) -> State:
        """The steady state at granular shear stress ``taubar`` [Pa] (unique; Eq. 13)."""
        st = rheology.steady_state_stress(float(taubar), self.phi, self.material)
        return self.state(float(taubar), float(st.f))

    # ------------------------------------------------------------------ running
    def run(self, steps, state: State | None = None, points: int = 300, *,
            resume: "Progress | None" = None, on_step=None) -> pd.DataFrame:
        """Run ``steps`` (a list of :class:`Step`) from ``state`` (default: at rest).

        Returns a DataFrame with :data:`COLUMNS`; ``attrs`` holds the events, the solver
        statistics and the parameters.

        ``on_step(progress)`` is called after every completed step with a :class:`Progress`
        (the rows so far, the state, the next step): what a checkpoint stores. ``resume`` (such
        a Progress) continues from it: every step starts from the exact state at the end of the
        previous one, so a resumed run's rows are identical to the uninterrupted run's.

        Raises
        ------
        rheology.run_end.EndedEarly
            The run ended before its last step's end (:meth:`_check_solution`: IDA failed or
            returned an unphysical state, or with ``elastic_limit`` the elastic strain passed
            0.1): ``partial`` is the DataFrame of the rows up to there (None if there were
            none), ``ends[0]`` the :class:`~rheology.run_end.RunEnd`, also in its attrs["end"].
        """
        steps = list(steps)
        if not steps:
            raise ValueError("a test needs at least one step")
        points = int(limits.STEP_ROWS.check(self.label("points"), points))
        liquid = le(limits.RATE_MAX * self.eta_fluid, (
            f"the liquid alone takes an imposed stress at once, at the rate stress/eta_F (eta_F "
            f"= eta0 (1 + 5/2 phi) = {self.eta_fluid:.4g} Pa s): up to the largest shear rate "
            f"{limits.RATE_MAX:g} 1/s"))
        for step in steps:             # the step's own range, its top lowered to the liquid's
            if step.control == "stress":
                own = step.quantity or limits.STRESS
                Param(own.lo, liquid, unit="Pa", also=own.also).check(
                    step.value_name, max(abs(step.start), abs(step.end)))
        self._points = points
        stats, pieces, first = RunStats(), [], 0
        st = state or self.rest()
        if resume is not None:
            st, first = resume.state, int(resume.next_step)
            if not 0 < first <= len(steps):
                raise ValueError(f"resume: next step {first + 1} is not a step of this "
                                 f"{len(steps)}-step test")
            pieces = resume.pieces()
            stats = RunStats(resume.solves, resume.nfev, resume.njev, events=list(resume.events))
        if not (np.isfinite(st.gap) and np.isfinite(st.taubar) and np.isfinite(st.strain)):
            raise ValueError(f"initial state {st} must be finite")
        t0 = time.perf_counter()
        try:
            for k in range(first, len(steps)):
                st = self._run_step(k, steps[k], st, points, pieces, stats)
                if on_step is not None:
                    on_step(Progress.of(pieces, st, k + 1, stats))
        except EndedEarly as exc:        # the rows up to the end, the end in attrs["end"]
            stats.seconds = time.perf_counter() - t0
            end = exc.ends[0] if pieces else exc.ends[0].replace(time_s=None)
            exc.ends[0] = end
            exc.partial = self._frame(pieces, stats, steps) if pieces else None
            if exc.partial is not None:
                exc.partial.attrs["end"] = end
            raise
        stats.seconds = time.perf_counter() - t0
        return self._frame(pieces, stats, steps)

    def linear_modulus(self, omega: float) -> complex:
        """Small-amplitude complex modulus G*(omega) [Pa] at rest (:class:`Maxwell`, derived in
        :mod:`rheometer.oscillation`); the tolerance scales of an oscillation step."""
        return complex(Maxwell(self.G, self.eta_low, self.eta_fluid).modulus(omega))

    def scales(self, step: Step, st: State) -> np.ndarray:
        """Scale of each DAE unknown for the absolute tolerances: stress [Pa], gap (tiny, so that
        the gap is controlled relatively down to ~1e-8), rates [1/s] (under stress control the
        shear rate's is the stress scale over the fluid viscosity), strain (of an oscillation:
        its amplitude, at most 1)."""
        if step.oscillation:
            G_abs = abs(self.linear_modulus(step.omega))
            amp_strain = step.start if step.control == "strain" else step.start / G_abs
            stress_max = step.start if step.control == "stress" else amp_strain * G_abs
            tau = max(abs(st.taubar), stress_max, 1e-6 * self.material.tau_star)
            g = max(amp_strain * step.omega, tau / self.eta_low)
            # under an imposed stress gdot = (sigma - taubar)/eta_f: taubar's own error, rtol
            # |taubar| (oscillation) or atol_tau, IS an error /eta_f in gdot; no tighter test
            # of gdot can be met (IDA would crawl at the fluid time eta_f/G)
            gd = (max(g, tau / self.eta_fluid * self.rtol / self.atol) if step.control == "stress"
                  else g)
            return np.array([tau, 1e-8, g, gd, min(1.0, amp_strain)])
        rate_max = max(step.start, step.end) if step.control == "rate" else 0.0
        stress_max = max(step.start, step.end) if step.control == "stress" else 0.0
        tau = max(abs(st.taubar), stress_max, self.eta_low * rate_max,
                  1e-6 * self.material.tau_star)
        g = max(rate_max, tau / self.eta_low)
        gd = max(g, tau / self.eta_fluid) if step.control == "stress" else g
        return np.array([tau, 1e-8, g, gd, 1.0])

    def output_times(self, step: Step, t_end: float, points: int) -> np.ndarray:
        """Output times from the step start: even for ramps; for constant steps half even and
        half log-spaced from a tenth of the fastest elastic time, eta/G (fluid viscosity under
        imposed stress, low-stress granular viscosity under imposed rate), so that the fast
        loading is resolved. An oscillation: :meth:`samples_per_cycle` at equal phases in every
        cycle (the step's end added if the cycles are not whole)."""
        if step.oscillation:
            n = self.samples_per_cycle(step, points)
            dt = 1.0 / (step.frequency * n)
            m = int(np.floor(step.cycles * n * (1 + 1e-12)))
            t = np.arange(m + 1) * dt
            return t if t[-1] >= t_end * (1 - 1e-12) else np.append(t, t_end)
        if step.ramp != "const":
            return np.linspace(0.0, t_end, points)
        eta = self.eta_fluid if step.control == "stress" else self.eta_low
        t_first = min(1e-6 * t_end, 0.1 * eta / self.G)
        n_log = points // 2
        return np.unique(np.concatenate([[0.0], np.geomspace(t_first, t_end, n_log),
                                         np.linspace(0.0, t_end, points - n_log)]))

    @staticmethod
    def samples_per_cycle(step: Step, points: int) -> int:
        """Output samples per cycle of an oscillation step: ``max(32, ceil(points/cycles))``."""
        return max(32, int(np.ceil(points / max(step.cycles, 1e-300))))

    @staticmethod
    def control_of(step: Step, st: State) -> np.ndarray:
        """The control vector (:func:`rheometer.model.control`) of ``step`` started at ``st``."""
        target = st.strain + step.strain if step.strain is not None else np.inf
        if step.oscillation:
            return drive(step.control, step.start, step.omega, st.t, step.duration, target)
        mode = model.RATE if step.control == "rate" else model.STRESS
        kind = {"const": model.CONST, "linear": model.LINEAR, "log": model.LOG}[step.ramp]
        return model.control(mode, kind, step.start, step.end, st.t, step.duration or 0.0, target)

    def _run_step(self, k: int, step: Step, st: State, points: int, pieces: list,
                  stats: RunStats) -> State:
        C = self.control_of(step, st)
        # an oscillation: at most 1/16 period per IDA step, as in rheometer.oscillation
        max_step = 1.0 / (16.0 * step.frequency) if step.oscillation else None
        if step.t_max < limits.clock_floor(st.t):
            # the program parser checks this at the earliest start; a strain step that ran
            # longer can still bring a later step here
            raise RuntimeError(f"step {k + 1} ({step.label or step.control}) lasts "
                               f"{step.t_max:g} s, too short for the run's clock at t = "
                               f"{st.t:.6g} s (IDA's t is one double: at least "
                               f"{limits.clock_floor(st.t):.3g} s there, rheometer.limits)")
        t_stop = st.t + step.t_max
        grid = st.t + self.output_times(step, step.t_max, points)
        grid[-1] = t_stop
        grid = np.unique(grid)           # output times that round to one value of the clock
        scale = self.scales(step, st)
        restarts = 0
        while True:
            sol = self.integrate(grid, st, C, scale, jam_events=self._may_jam(st),
                                 terminal_jam=restarts < self.max_restarts, max_step=max_step)
            stats.count(sol)
            y = self._full(sol.t, sol.y, C)
            keep, end = self._check_solution(sol, y, step, k, st)
            st_solve = st
            first = 1 if restarts else 0                 # a restart repeats the event point
            if keep > first:
                pieces.append(_Piece(sol.t[first:keep], y[first:keep], k))
            if end is not None:
                raise EndedEarly([end])
            st = self._state_at(sol.t[-1], y[-1])
            at_limit = False
            for t_ev, i_ev in zip(sol.t_events if sol.t_events is not None else (),
                                  sol.i_events if sol.i_events is not None else ()):
                if len(i_ev) > NEVENTS and i_ev[NEVENTS]:
                    at_limit = True                    # the run's end, not an event
                    continue
                what = ("strain reached" if i_ev[1] else
                        "jammed" if i_ev[0] < 0 else "unjammed")
                stats.events.append((float(t_ev), k + 1, what))
            stopped = (sol.t_events is not None and sol.t_events[-1] == sol.t[-1]
                       and st.t < t_stop)
            if stopped and at_limit:
                st = self._resample_end(pieces, step, k, st_solve, C, scale, grid, max_step,
                                        stats) or st
                strain = abs(st.taubar) / self.G
                raise EndedEarly([RunEnd("validity_limit", (
                    f"{self._where(step, k)}: elastic strain taubar/G reached {strain:.3g} at t "
                    f"= {st.t:.6g} s (taubar = {abs(st.taubar):.4g} Pa, G = {self.G:.4g} Pa), the "
                    f"small-elastic-strain limit {ELASTIC_STRAIN_LIMIT:g} of the hypoelastic law; "
                    f"{_ADVICE}"), st.t, "elastic strain taubar/G", strain,
                    ELASTIC_STRAIN_LIMIT, st.t)])
            if not stopped:
                if st.t < t_stop * (1 - 1e-12) - 1e-300:
                    raise EndedEarly([RunEnd("solver_failure", (
                        f"step {k + 1} ({step.label or step.control}): IDA stopped at t = "
                        f"{st.t:.6g} s before t = {t_stop:.6g} s: {sol.message}"), st.t)])
                if step.strain is not None:
                    stats.events.append((st.t, k + 1, f"strain {step.strain:g} not reached "
                                                      f"within {step.t_max:g} s"))
                return st
            if sol.i_events[-1][1]:                            # strain target reached
                return st
            restarts += 1                                      # jamming or unjamming
            grid = np.concatenate([[st.t], grid[grid > st.t * (1 + 1e-14) + 1e-300]])
            if grid.size < 2:
                return st

    def _resample_end(self, pieces, step: Step, k: int, st_solve: State, C, scale, grid,
                      max_step, stats) -> State | None:
        """The output interval in which the elastic limit was reached (a jam can take the stress
        from tens of Pa to the limit within it), again with :data:`END_ROWS` even rows up to the
        limit: solved from the state of the output before it to the same root. Replaces the
        last piece's rows after that output and returns the state at the limit; None (rows kept
        as they are) when the resolve does not end on the limit or fails a check."""
        p = pieces[-1] if pieces else None
        if p is None or p.step != k:
            return None
        t_lim, skip = p.t[-1], int(p.t.size < 2)
        # the solve's only row: from its start, else from the row before the last
        st0 = st_solve if skip else self._state_at(p.t[-2], p.y[-2])
        fine = np.append(np.linspace(st0.t, t_lim, END_ROWS + 1)[:-1], grid[grid > t_lim][0])
        sol = self.integrate(fine, st0, C, scale, max_step=max_step)
        stats.count(sol)
        y = self._full(sol.t, sol.y, C)
        keep, end = self._check_solution(sol, y, step, k, st_solve)
        hit = (sol.i_events is not None and len(sol.i_events)
               and sol.i_events[-1][NEVENTS] and sol.t_events[-1] == sol.t[-1])
        if end is not None or not hit:
            return None
        pieces[-1] = _Piece(np.concatenate([p.t[:-2], sol.t[skip:]]),
                            np.concatenate([p.y[:-2], y[skip:]]), k)
        return self._state_at(sol.t[-1], y[-1])

    def _state_at(self, t, row) -> State:
        return State(float(t), float(row[TAU]), float(row[GAP]), float(row[STRAIN]),
                     float(model.structure_of_gap(row[GAP], self.P)))

    def _may_jam(self, st: State) -> bool:
        """Whether the gap can cross zero in this run: jammed now, or f can exceed f_jam.

        f stays below max(f0, f_m); at f = f_m = f_jam (Delta = 0, phi_c <= phi <= phi*) df/dt <= 0,
        so the gap cannot close there either; no root function is then needed (cheaper steps).
        """
        return st.gap <= 0.0 or self.f_m > self.f_jam * (1.0 + 1e-12)

    def integrate(self, grid, st: State, C, scale, jam_events: bool = False,
                  terminal_jam: bool = True, max_step: float | None = None):
        """One IDA solve of the model from state ``st`` over the output times ``grid`` [s].

        ``C`` is the control vector (:func:`rheometer.model.control`), ``scale`` the scale of
        each unknown (atol = self.atol * scale), ``max_step`` [s] IDA's largest step (None:
        unlimited). Returns the raw ``IDAResult`` (unknowns in the order of the chosen form);
        :meth:`run` is the checked, user-level path.
        """
        P, ode = self.P, self.form == "ode"
        y = np.empty(NVAR)
        yp = np.empty(NVAR)
        model.consistent_state(grid[0], st.taubar, st.gap, st.strain, P, C, y, yp)
        if ode:
            res_k, jac_k, ev_k = model.ode_residual, model.ode_residual_jacobian, model.ode_events
            y, yp, atol = y[[TAU, GAP, STRAIN]], yp[[TAU, GAP, STRAIN]], scale[[0, 1, 4]]
        else:
            res_k, jac_k, ev_k = model.residual, model.jacobian, model.events
            atol = scale

        # with elastic_limit a third root, |taubar| - 0.1 G: the run ends on the limit itself
        limit = elastic_strain_limit_stress(self.G) if self.elastic_limit else None

        def eventsfn(t, yy, yyp, ev):          # the jam, the strain target, the elastic limit
            ev_k(t, yy, ev, P, C)
            if limit is not None:
                ev[NEVENTS] = abs(yy[TAU]) - limit

        events = {}
        if jam_events or np.isfinite(C[6]) or limit is not None:
            # a switched-off root function is held at -1 (never crosses); see model.events
            n = 2 + (limit is not None)
            events = dict(events=eventsfn, names=("jam", "strain", "elastic_limit")[:n],
                          stop=[bool(terminal_jam) and jam_events] + [True] * (n - 1),
                          direction=[(1 if st.gap <= 0.0 else -1) if jam_events else 0]
                          + [1] * (n - 1))
        if max_step is not None:
            events["max_step"] = float(max_step)
        solver = Solver(lambda t, yy, yyp, res: res_k(t, yy, yyp, res, P, C), rtol=self.rtol,
                        atol=self.atol * atol, algebraic_idx=None if ode else [GP, GD],
                        jacfn=(lambda t, yy, yyp, res, cj, JJ: jac_k(t, yy, yyp, cj, JJ, P, C))
                        if self.jacobian else None, max_num_steps=200_000, **events)
        try:
            sol, _ = solver.solve(grid, y, yp)
        except IDAFailed as exc:         # the rows up to the failure are kept (_check_solution)
            sol = exc.sol
        if solver.printed:               # what SUNDIALS printed: into the diagnostics
            sol.message = f"{sol.message} [SUNDIALS: {solver.printed.lstrip('[')[:300]}]"
        return sol

    def _full(self, t, y, C) -> np.ndarray:
        """All five unknowns at the output times (fills gdot_p, gdot for the ODE form)."""
        if self.form == "dae":
            return y
        out = np.empty((t.size, NVAR))
        yp = np.empty(NVAR)
        for i in range(t.size):
            model.consistent_state(t[i], y[i, 0], y[i, 1], y[i, 2], self.P, C, out[i], yp)
        return out

    # ------------------------------------------------------------------ checks and output
    def _where(self, step: Step, k: int) -> str:
        return (f"step {k + 1} ({step.label or step.control}) at phi = {self.phi:g}, "
                f"G = {self.G:g} Pa, K0 = {self.K0:g}, rtol = {self.rtol:g}")

    def _check_solution(self, sol, y, step: Step, k: int, st0: State):
        """(rows of this solve to keep, RunEnd or None): the rows before the first that fails a
        check, and the end it makes. A failed solve keeps its rows at the output times (its last
        row is where IDA stopped); then, from the first row on: an unphysical state (non-finite,
        f outside [0, max(f0, f_m)], a plastic rate against the stress) and, with
        ``elastic_limit``, an elastic strain taubar/G past the limit. The earliest row decides."""
        where = self._where(step, k)
        f = model.structure_of_gap(y[:, GAP], self.P)
        cuts = []                                           # (row, RunEnd), earliest wins
        n = len(sol.t)
        if not sol.success:        # where IDA stopped is not an output time: not written
            n -= 1
            cuts.append((n, RunEnd("solver_failure", (
                f"IDA failed in {where} at t = {sol.t[n]:.6g} s: {sol.message} (state taubar = "
                f"{y[n, TAU]:.6g} Pa, f = {f[n]:.6g}; {sol.nfev} residuals)"),
                past_s=float(sol.t[n]))))
        f_hi = max(float(model.structure_of_gap(st0.gap, self.P)), self.f_m)
        tol_f = 10 * self.rtol
        # the plastic rate has the sign of the stress (signed law, rheometer.model), to the
        # tolerance the algebraic pair (gdot_p, gdot) is solved to: relative to the step's rate
        # scale (near jamming the flow rule hardly constrains gdot_p: a recoiling sample at a
        # positive stress may show |gdot_p| ~ 1e-5 1/s of the wrong sign at gdot ~ 65 1/s)
        yy, ff = y[:n], f[:n]
        tol_gp = 10 * self.rtol * max(1e-300, float(np.max(np.abs(yy[:, [GP, GD]]),
                                                            initial=0.0)))
        bad = (~np.all(np.isfinite(yy), axis=1) | (ff < -tol_f) | (ff > f_hi + tol_f)
               | (yy[:, GP] * np.where(yy[:, TAU] >= 0, 1.0, -1.0) < -tol_gp))
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            cuts.append((i, RunEnd("solver_failure", (
                f"unphysical state in {where} at t = {sol.t[i]:.6g} s: taubar = {y[i, TAU]:.6g} "
                f"Pa, f = {f[i]:.6g} (valid [0, {f_hi:.6g}]), gdot_p = {y[i, GP]:.6g} 1/s (of "
                f"the stress's sign); IDA reported '{sol.message}' after {sol.nfev} residuals: "
                f"tighten rtol"), past_s=float(sol.t[i]))))
        # the hypoelastic law holds for small elastic strains taubar/G only (rheology.elastic);
        # checked on every row, where IDA stopped included: a sample strained past it before IDA
        # gave up names that as the cause (rate 1e9 1/s to t_end 1e9 s failed at taubar 1e20 Pa)
        past = (past_elastic_limit(sol.t, y[:, TAU], self.G, where=where, advice=_ADVICE)
                if self.elastic_limit else None)
        if past is not None:
            cuts.insert(0, past)
        cut = min(cuts, key=lambda c: c[0]) if cuts else None
        if cut is None:
            return n, None
        i, end = cut
        return i, end.replace(time_s=float(sol.t[i - 1]) if i > 0 else st0.t)

    def _frame(self, pieces: list[_Piece], stats: RunStats, steps) -> pd.DataFrame:
        t, y, k = _joined(pieces)
        m, phi = self.material, self.phi
        tau_g, gap, gp, g = y[:, TAU], y[:, GAP], y[:, GP], y[:, GD]    # signed
        f = np.clip(model.structure_of_gap(gap, self.P), 0.0, 1.0)
        tau = tau_g + self.eta_fluid * g
        # tau/gdot: the viscosity of a shear or creep step; undefined (empty) at gdot = 0 and in
        # an oscillation (its |eta*| = |G*|/omega is in attrs["oscillations"])
        osc = np.isin(k, [i for i, s in enumerate(steps) if s.oscillation])
        defined = (g != 0) & ~osc
        with np.errstate(divide="ignore", invalid="ignore"):
            visc = np.where(defined, tau / np.where(defined, g, 1.0), np.nan)
        df = pd.DataFrame({
            "time_s": t, "step": k + 1, "strain": y[:, STRAIN], "shear_rate_per_s": g,
            "shear_stress_Pa": tau, "granular_shear_stress_Pa": tau_g,
            "plastic_shear_rate_per_s": gp, "f": f,
            "granular_pressure_Pa": critical_state_pressure(np.abs(tau_g), np.abs(gp), phi, f,
                                                            gap, m),
            "viscosity_Pa_s": visc, "jamming_gap": gap})
        df.attrs.update(material=m.name, phi=phi, G_Pa=self.G, K0=self.K0, rtol=self.rtol,
                        form=self.form, events=stats.events, solves=stats.solves,
                        nfev=stats.nfev, njev=stats.njev, seconds=stats.seconds,
                        steps=[s.label or s.control for s in steps],
                        oscillations=[self.analyse_oscillation(steps[i], df[k == i], i)
                                      for i in sorted(set(k.tolist())) if steps[i].oscillation])
        return df

    def analyse_oscillation(self, step: Step, d: pd.DataFrame, index: int) -> dict:
        """Harmonic analysis of the last full cycle of an oscillation step's rows ``d``.

        The cycle's samples at phases 2 pi j/N (N = :meth:`samples_per_cycle`, phase 0 at the
        step's start); the same definitions as :mod:`rheometer.oscillation`: ``G* = c_sigma,1 /
        c_gamma,1`` (strain control: ``c_gamma,1 = -i gamma0``; stress control: ``c_sigma,1 = -i
        sigma0`` and the strain's harmonic with its drift over the cycle removed), ``I3/I1`` of
        the response (stress under strain control, strain under stress control). Keys: step (from
        1), control, frequency_Hz, cycles, storage_modulus_Pa, loss_modulus_Pa,
        complex_viscosity_Pa_s, I3_over_I1, strain_amplitude, stress_amplitude_Pa,
        mean_stress_Pa, cycle_change (relative change of c_1 from the cycle before; NaN with one
        cycle). Fewer than one full cycle: only step, control, frequency_Hz, cycles.
        """
        out = dict(step=index + 1, control=step.control, frequency_Hz=step.frequency,
                   cycles=step.cycles)
        full = int(np.floor(step.cycles * (1 + 1e-12)))
        if full < 1 or d.empty:
            return out
        n = self.samples_per_cycle(step, self._points)
        t = d["time_s"].to_numpy()
        u = (t - t[0]) * step.frequency * n
        j = np.rint(u)
        on = np.abs(u - j) < 1e-6

        def c1(c):                       # the harmonics of cycle c's n + 1 samples, or None
            idx = np.flatnonzero(on & (j >= (c - 1) * n) & (j <= c * n))
            idx = idx[np.unique(j[idx], return_index=True)[1]]
            if idx.size != n + 1:
                return None
            stress = d["shear_stress_Pa"].to_numpy()[idx]
            return (*cycle_harmonics(step.control, step.start, stress[:n],
                                     d["strain"].to_numpy()[idx]), float(np.mean(stress[:n])))

        last = c1(full)
        if last is None:
            return out
        cs, cg, resp, mean = last
        Gs = complex(cs / cg)
        change = np.nan
        if full >= 2:
            prev = c1(full - 1)
            if prev is not None:
                change = float(abs(prev[2][0] - resp[0]) / abs(resp[0]))
        out.update(storage_modulus_Pa=Gs.real, loss_modulus_Pa=Gs.imag,
                   complex_viscosity_Pa_s=abs(Gs) / step.omega,
                   I3_over_I1=float(abs(resp[1]) / abs(resp[0])),
                   strain_amplitude=float(abs(cg)), stress_amplitude_Pa=float(abs(cs)),
                   mean_stress_Pa=mean, cycle_change=change)
        return out


def critical_state_pressure(taubar, gdot_p, phi, f, gap, m: Material) -> np.ndarray:
    """Granular pressure slaved to the critical state [Pa] (the 0-D model's pressure).

    Table 8's f_3 = 0 (Eq. 2 in the viscous limit) while flowing; ``taubar/mu*`` (the critical
    friction) when the plastic rate is zero (at rest or jammed). ``gap`` = phi_m(f) - phi.
    """
    y = np.maximum(gap, 0.0)
    a = laws.dilatancy_a(f, m.a0, m.a_inf)
    flowing = (gdot_p > 0) & (y > 0)
    p_flow = laws.critical_pressure(gdot_p, phi, y, a, m.eta0, m.d, m.rho_s or 0.0)
    p_yield = taubar / laws.critical_friction(phi, y, a, m.mu_c, m.mu2, m.b)
    return np.where(flowing, p_flow, p_yield)
