"""Time integration of a :class:`~shear1d.model.Couette` problem, and its results.

Three methods on the same finite-volume grid and the same Table 8 law:

- ``"ida"``: method of lines on SUNDIALS IDA (:class:`runkit.ida.Solver`), BDF of order <= 2
  with adaptive steps and a banded finite-difference Jacobian, the local update used as a rate
  over delta (:meth:`Couette.rhs`; delta = rtol times the flow time,
  :meth:`Couette.rate_step_at`, so one tolerance sets both errors);
- ``"explicit"``: symplectic Euler with the local update as a true step
  (:func:`shear1d.kernels.explicit_steps`), the scheme of the paper's MPM in 1-D, stable for
  ``dt <= 4/(lambda + sqrt(lambda^2 + 4 omega^2))`` (omega ~ 2c/dx the fastest elastic shear
  mode, c = sqrt(G/rho); lambda ~ 4 eta_f/(rho dx^2) the fastest viscous rate) and, two-phase,
  ``dt <= dx^2/(2 D)`` with D = (K + 4G/3) n^2/C (:func:`stable_time_step`);
- ``"dae"`` (locked mode): the law's continuous form as a smooth DAE on IDA (:mod:`shear1d.dae`).

Two events are recorded: ``front_at_wall`` (the structure front passes WALL_FRACTION of the
gap) and ``flow_stopped`` (the bulk speed falls below FLOW_STOP_LEVEL of the wall speed); IDA
finds their roots, the explicit scheme interpolates between outputs.

Every output is checked (finite state, 0 <= f <= 1, 0 < phi < 1, p >= 0; with
``elastic_limit`` the elastic strains taubar/G and p/K within
:data:`rheology.elastic.ELASTIC_STRAIN_LIMIT`). A failing output, IDA step or local update ends
the run there: :class:`rheology.run_end.EndedEarly` with the :class:`Result` of the outputs
before it. The outputs are the steps of :func:`runkit.run.drive` (signals, progress, periodic
checkpoints to an ``.npz`` file); a run resumes from its checkpoint's last output.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field

import numpy as np

from rheology import f_jam
from rheology.elastic import past_elastic_limit
from rheology.flow_rule import invariants
from rheology.run_end import EndedEarly, RunEnd
from runkit.ida import IDAFailed, Solver
from runkit.io import CorruptCheckpoint
from runkit.limits import TIME_MAX, TIME_MIN, ge, le
from runkit.params import Param, check_range
from runkit.run import Checkpoint, Progress, drive

from . import analysis, kernels
from . import dae as dae_mod
from .model import STRESS_COMPONENTS, Couette

METHODS = ("ida", "explicit", "dae")
EVENTS = ("front_at_wall", "flow_stopped")
#: flow_stopped fires when the bulk speed (analysis.bulk_speed) falls below this fraction of u_wall.
FLOW_STOP_LEVEL = 0.1
#: Largest BDF order of IDA: BDF1-2 are A-stable (BDF3-5 are not near the imaginary axis), and
#: the jammed band is an elastic solid whose grid-scale shear waves only the fluid viscosity damps.
MAX_ORDER = 2

#: IDA's relative tolerance (and the rate form's step, delta = rtol x the flow time).
RTOL = Param(ge(1e-12, "IDA reaches no tighter tolerance: each step's error is then the "
                       "rounding of its doubles (~1e-16) summed over 1e4-1e6 steps"),
             le(1e-2, "a looser tolerance leaves fewer than two meaningful digits, and its "
                      "delta = rtol x the flow time smears the start-up"))
#: The explicit step [s]: a duration (runkit.limits), at most the stability limit
#: (:func:`check_time_step`).
DT = Param(TIME_MIN, TIME_MAX, unit="s")
#: The duration of a run [s] (runkit.limits).
DURATION = Param(TIME_MIN, TIME_MAX, unit="s")
#: Output intervals of a run.
OUTPUTS = Param(ge(1, "the end of the run is its one output"),
                le(100000, "more profiles than any figure or file resolves (1e5 rows per cell)"),
                kind="integer")
#: Wall-time seconds between checkpoints: the durations of runkit.limits.
CHECKPOINT_EVERY = Param(ge(TIME_MIN.value, "a checkpoint takes time to write: an interval of "
                                            "1 ps, the shortest duration, already writes one at "
                                            "every output"), TIME_MAX, unit="s")


@dataclass
class Result:
    """Output of :func:`solve`.

    Attributes
    ----------
    problem : Couette
    method : str
    t : (n_out,) output times [s]
    y : (n_out, size) state vectors (layout of :meth:`Couette.layout`)
    diag : (n_out, n, 4) per-cell shear rate, plastic shear rate [1/s], pressure [Pa], case
    events : dict name -> list of times [s] (``front_at_wall``, ``flow_stopped``)
    wall_time : float, seconds spent integrating (resumed parts included)
    stats : dict (IDA: nfev, njev, rtol; explicit: steps, dt, dt_stable)
    end : RunEnd or None, where and why the run ended early (None: it reached its end time)
    """

    problem: Couette
    method: str
    t: np.ndarray
    y: np.ndarray
    diag: np.ndarray
    events: dict = field(default_factory=dict)
    wall_time: float = 0.0
    stats: dict = field(default_factory=dict)
    end: RunEnd | None = None

    def field(self, name: str) -> np.ndarray:
        """A field over (output time, position): ``v`` (faces), ``f``, ``phi``, ``sigma_rth``,
        ``sigma_rr``, ``sigma_thth``, ``sigma_zz``, ``shear_rate``, ``plastic_shear_rate``,
        ``pressure``, ``shear_stress`` (mixture, cells) [SI]."""
        pb = self.problem
        if name in ("shear_rate", "plastic_shear_rate", "pressure"):
            return self.diag[:, :, kernels.DIAG_FIELDS.index(name)]
        if name == "shear_stress":
            eta = np.array([pb.coefficients(ph)[1] for ph in self.field("phi")])
            return self.field("sigma_rth") + eta * self.field("shear_rate")
        per = [pb.unpack(y, t) for t, y in zip(self.t, self.y)]
        if name in ("v", "f", "phi"):
            return np.array([p[name] for p in per])
        if name in STRESS_COMPONENTS:
            return np.array([p["sigma"][:, STRESS_COMPONENTS.index(name)] for p in per])
        raise ValueError(f"unknown field {name!r}")

    def front(self) -> np.ndarray:
        """Kinematic front position at every output [m] (see :mod:`shear1d.analysis`)."""
        pb = self.problem
        return np.array([analysis.front_position(pb.grid, v, pb.wall_velocity(t))
                         for t, v in zip(self.t, self.field("v"))])


# ----------------------------------------------------------------------------- stability
def stable_time_step(problem: Couette) -> dict:
    """Largest stable explicit step [s] and its parts (Gershgorin bounds on the grid operators).

    Returns dict with ``dt`` (the limit), ``dt_wave`` (elastic shear waves alone, ~dx/c),
    ``dt_viscous`` (fluid viscosity alone, ~rho dx^2/(2 eta_f)), ``dt_darcy`` (two-phase
    consolidation, inf when locked), ``omega`` [rad/s] and ``lam`` [1/s].
    """
    m, g, mt = problem.material, problem.grid, problem.metrics()
    cg, w, A, M = mt["cg"], mt["w"], mt["A"], mt["M"]
    # interior faces k = 1 .. n-1: |coefficients| of v_{k-1}, v_k, v_{k+1}; the driven wall's
    rows = (A[:-1] * cg[:-1] * (w[:-2] + w[1:-1]) + A[1:] * cg[1:] * (w[1:-1] + w[2:])) / M[1:-1]
    wall = A[0] * cg[0] * (w[0] + w[1]) / M[0] if problem.stress_driven else 0.0
    op = max(float(rows.max()), wall) / min(m.rho_s, m.rho_f)   # omega^2 = G op, lambda = eta op
    omega = math.sqrt(m.G * op)
    phi_hi = min(problem.phi0 + 0.05, 0.99)
    lam = m.eta0 * (1.0 + 2.5 * phi_hi) * op
    dt_mech = 4.0 / (lam + math.sqrt(lam * lam + 4.0 * omega * omega))
    dt_darcy = math.inf
    if problem.two_phase:
        phis = np.linspace(max(problem.phi0 - 0.05, 0.01), phi_hi, 11)
        mob = np.max(problem.coefficients(phis)[2][1:-1])
        dt_darcy = 0.9 * g.dx ** 2 / (2.0 * (m.K + 4.0 * m.G / 3.0) * mob)
    return dict(dt=min(dt_mech, dt_darcy), dt_wave=2.0 / omega, dt_viscous=2.0 / lam,
                dt_darcy=dt_darcy, omega=omega, lam=lam)


def check_time_step(problem: Couette, dt: float | None, lim: dict, name: str = "dt",
                    instead: str = "method='ida'") -> float:
    """Return dt (checked against :data:`DT` already) if the explicit scheme is stable with it
    (None: the default, half the stability limit ``lim`` of :func:`stable_time_step`, at least
    TIME_MIN), else ValueError naming ``name``, the limit and its parts, and ``instead``; a
    limit below TIME_MIN leaves no step."""
    parts = (f"elastic shear waves ~dx/c: {lim['dt_wave']:.3g} s, fluid viscosity "
             f"~rho dx^2/(2 eta_f): {lim['dt_viscous']:.3g} s")
    if math.isfinite(lim["dt_darcy"]):
        parts += f", Darcy consolidation dx^2/(2D): {lim['dt_darcy']:.3g} s"
    if lim["dt"] < TIME_MIN.value:
        raise ValueError(f"{name}: the explicit stability limit of this grid, {lim['dt']:.3g} s "
                         f"({parts}), is below the shortest duration {TIME_MIN.value:g} s "
                         f"({TIME_MIN.why}); use {instead}")
    if dt is None:
        return max(0.5 * lim["dt"], TIME_MIN.value)
    if dt > lim["dt"]:
        raise ValueError(f"{name} = {dt:.6g} s is outside the explicit stability range "
                         f"[{TIME_MIN.value:g}, {lim['dt']:.6g}] s of this grid ({parts}); use a "
                         f"smaller dt or {instead}")
    return dt


# ----------------------------------------------------------------------------- events, checks
class _Events:
    """The two root functions on a Couette-layout state (``convert``: the solver's state to it),
    found by IDA or sampled between outputs (explicit scheme)."""

    directions = (1, -1)

    def __init__(self, problem: Couette, convert=None):
        self.pb, self.convert = problem, convert
        self.active = not problem.stress_driven
        self.f_ref = float(f_jam(problem.phi0, problem.material))
        self.times: dict[str, list[float]] = {k: [] for k in EVENTS}
        self._last: tuple[float, np.ndarray] | None = None

    def values(self, t: float, y: np.ndarray) -> np.ndarray:
        pb, g = self.pb, self.pb.grid
        u = pb.wall_velocity(t)
        if u == 0:
            return np.array([-1.0, 1.0])
        st = pb.unpack(y if self.convert is None else self.convert(t, y)[0], t)
        out = np.array([analysis.structure_front(g, st["f"], self.f_ref)
                        - (g.inner + analysis.WALL_FRACTION * g.gap),
                        analysis.bulk_speed(g, st["v"], u) - FLOW_STOP_LEVEL])
        # never exactly 0 (0 counts as crossed): a front slower than one rounding step of its
        # position over IDA's probe after a root, smallh ~ 100 eps t, is 0 there too, and IDA
        # stops with status -22 "Root found at and very near t"
        return np.where(out == 0.0, np.asarray(self.directions) * np.finfo(float).tiny, out)

    def ida_events(self, t, y, yp, out) -> None:
        """The root functions as IDA takes them (:class:`runkit.ida.Solver`)."""
        out[:] = self.values(t, y)

    def sample(self, t: float, y: np.ndarray) -> None:
        """Record the crossings between the previous sample and (t, y) (explicit scheme)."""
        g1 = self.values(t, y)
        if self._last is not None:
            t0, g0 = self._last
            for i, name in enumerate(EVENTS):
                d = self.directions[i]
                if (d > 0 and g0[i] < 0 <= g1[i]) or (d < 0 and g0[i] > 0 >= g1[i]):
                    self.times[name].append(float(t0 + (t - t0) * g0[i] / (g0[i] - g1[i])))
        self._last = (t, g1)


def check_state(problem: Couette, t: float, y: np.ndarray, diag: np.ndarray,
                f_tol: float = 1e-6) -> None:
    """Raise RuntimeError with diagnostics if a state is unphysical (non-finite, f outside
    [0, 1] by more than ``f_tol``, phi outside (0, 1), a pressure below -f_tol tau*: f_tol is the
    integrator's resolution, 100 rtol for IDA, whose absolute tolerance of f is rtol and of the
    stresses rtol tau*)."""
    st = problem.unpack(y, t)
    problems = []
    if not np.all(np.isfinite(y)):
        bad = np.flatnonzero(~np.isfinite(y))
        problems.append(f"{bad.size} non-finite unknown(s), first at index {bad[0]}")
    f, phi = st["f"], st["phi"]
    if np.any(f < -f_tol) or np.any(f > 1.0 + f_tol):
        j = int(np.argmax(np.maximum(-f, f - 1.0)))
        problems.append(f"f = {f[j]:.6g} outside [0, 1] in cell {j}")
    if np.any(phi <= 0) or np.any(phi >= 1):
        j = int(np.argmax(np.abs(phi - 0.5)))
        problems.append(f"phi = {phi[j]:.6g} outside (0, 1) in cell {j}")
    p = diag[:, kernels.DIAG_FIELDS.index("pressure")]
    if np.any(p < -f_tol * problem.stress_scale()):
        problems.append(f"negative granular pressure {p.min():.6g} Pa")
    if problems:
        raise RuntimeError(f"unphysical state at t = {t:.6g} s ({problem.grid.kind}, "
                           f"{problem.grid.n} cells, mode {problem.mode}): " + "; ".join(problems)
                           + f"; max |v| = {np.nanmax(np.abs(st['v'])):.6g} m/s, "
                           f"max |sigma| = {np.nanmax(np.abs(st['sigma'])):.6g} Pa")


def elastic_strains(problem: Couette, t: float, y: np.ndarray) -> tuple[float, float]:
    """The largest elastic strains (taubar/G, p/K) over the cells of a state (Eq. 11 invariants
    of the cell stresses; p/K of a compression, 0 in tension)."""
    sig = problem.unpack(y, t)["sigma"]            # (n, 4): rr, thth, zz, rth
    full = np.zeros((sig.shape[0], 3, 3))
    full[:, [0, 1, 2], [0, 1, 2]] = sig[:, :3]
    full[:, 0, 1] = full[:, 1, 0] = sig[:, 3]
    taubar, p = invariants(full)
    m = problem.material
    return float(np.max(taubar)) / m.G, max(float(np.max(p)), 0.0) / m.K


# ----------------------------------------------------------------------------- outputs
#: Arrays every checkpoint holds (a file without one of them is named as corrupt).
CHECKPOINT_ARRAYS = ("t_out", "Y", "D", "event_names", "event_times", "counters", "finished")


def fingerprint(problem: Couette, method: str, times: np.ndarray, setting: float) -> dict:
    """What identifies a run (:class:`runkit.run.Checkpoint`): material, grid, drive, mode,
    method, its step or tolerance and the output times; a checkpoint is resumed only by the run
    with the same."""
    m, g = problem.material, problem.grid
    return dict(method=method, setting=setting, material=m.name,
                parameters=[None if x != x else float(x) for x in m.kernel_array()] + [m.rho_f],
                grid=[g.kind, g.inner, g.outer, g.n], mode=problem.mode,
                drive=[problem.wall_speed, problem.wall_stress, problem.ramp_time],
                phi0=problem.phi0, contact_pressure=problem.contact_pressure,
                rate_step=problem.rate_step, outputs=[times.size, float(times[0]),
                                                      float(times[-1]), float(np.sum(times))])


class _Outputs:
    """The outputs of a run (time, Couette-layout state, diagnostics, counters, the solver's
    state a resume restarts from), checked as they come, and their checkpoint (``save``), as
    :func:`runkit.run.drive` advances them: ``advance`` steps to the next output time by
    ``to(t_target) -> (t, state, diag, counters, extra, end)`` (set by the method), checks and
    records the output (with ``to.sample``: samples the events there) and calls
    ``stop_hook(t)`` (after every output but the last). ``stats(counters)`` gives the result's
    stats."""

    def __init__(self, problem, method, times, setting, checkpoint, events, elastic_limit,
                 f_tol):
        self.pb, self.method, self.events = problem, method, events
        self.elastic_limit, self.f_tol = bool(elastic_limit), f_tol
        self.ck = None if checkpoint is None else Checkpoint(
            checkpoint, fingerprint(problem, method, times, setting))
        self.rows: list[tuple] = []
        self.wall0, self.wall_before = time.perf_counter(), 0.0
        self.stats, self.times, self.t_end = dict, times, float(times[-1])
        self.to, self.stop_hook, self.k = None, None, 0     # k: the next output's index

    def add(self, t, y, diag, counters, extra=None):
        """One output, appended as one tuple (an interrupt never leaves the lists unequal)."""
        self.rows.append((float(t), y, diag, np.asarray(counters, dtype=float), extra))

    @property
    def t(self) -> float:
        """The time of the last output [s]."""
        return self.rows[-1][0]

    @property
    def steps(self) -> int:
        return len(self.rows) - 1

    def advance(self) -> None:
        t, y, diag, counters, extra, end = self.to(float(self.times[self.k]))
        if end is None:
            end = self.end_at(t, y, diag)
        if end is not None:              # the outputs so far are the run (rheology.run_end)
            raise self.ended(end, counters)
        if getattr(self.to, "sample", False):
            self.events.sample(t, y)
        self.add(t, y, diag, counters, extra)
        self.k += 1
        if self.stop_hook is not None and self.k < len(self.times):
            self.stop_hook(t)

    def wall(self) -> float:
        return self.wall_before + time.perf_counter() - self.wall0

    def result(self, counters=None) -> Result:
        T, Y, D = (np.array([r[i] for r in self.rows]) for i in range(3))
        return Result(self.pb, self.method, T, Y, D,
                      {k: list(v) for k, v in self.events.times.items()}, self.wall(),
                      self.stats(self.rows[-1][3] if counters is None else counters))

    def state(self, finished: bool = False, end: RunEnd | None = None) -> dict:
        """The checkpoint's arrays; events after the last output are left to the resumed run."""
        T, Y, D = (np.array([r[i] for r in self.rows]) for i in range(3))
        ev = [(k, x) for k, ts in self.events.times.items() for x in ts if x <= T[-1]]
        return dict(t_out=T, Y=Y, D=D,
                    event_names=np.array([k for k, _ in ev], dtype="U32"),
                    event_times=np.array([x for _, x in ev], dtype=float),
                    counters=self.rows[-1][3], finished=np.array(bool(finished)),
                    wall=np.array(self.wall()), end=np.array(json.dumps(end.record() if end
                                                                       else None)),
                    **(self.rows[-1][4] or {}))

    def save(self, state: dict):
        return self.ck.save(state) if self.ck is not None else None

    def load(self, log=None) -> dict:
        """Read the checkpoint (refused if absent, corrupt without a readable predecessor, or of
        another run) and restore the outputs and events; returns the checkpoint's arrays."""
        ck = self.ck.load(required=CHECKPOINT_ARRAYS, log=log)
        T, Y, D = ck["t_out"], ck["Y"], ck["D"]
        if T.ndim != 1 or Y.shape[0] != T.size or D.shape[0] != T.size or T.size == 0:
            raise CorruptCheckpoint(f"checkpoint {self.ck.path} is corrupt (inconsistent output "
                                    "arrays)")
        extra = {k: ck[k] for k in ("y", "yp") if k in ck}
        for k in range(T.size):
            self.add(T[k], Y[k].copy(), D[k].copy(), ck["counters"],
                     extra if k == T.size - 1 else None)
        for name, te in zip(ck["event_names"], ck["event_times"]):
            self.events.times[str(name)].append(float(te))
        self.wall_before = float(ck["wall"]) if "wall" in ck else 0.0
        return ck

    def end_at(self, t: float, y: np.ndarray, diag: np.ndarray) -> RunEnd | None:
        """The end an output at t makes, or None: an unphysical state (:func:`check_state`) and,
        with ``elastic_limit``, an elastic strain taubar/G or p/K past the limit in a cell (the
        largest over the cells, against the last output's)."""
        try:
            check_state(self.pb, t, y, diag, self.f_tol)
        except RuntimeError as exc:
            return RunEnd("solver_failure", str(exc), past_s=float(t))
        if not self.elastic_limit:
            return None
        m, g = self.pb.material, self.pb.grid
        where = (f"{g.kind} cell, {g.n} cells, mode {self.pb.mode}, largest over the cells at "
                 f"G = {m.G:g} Pa, K = {m.K:g} Pa")
        advice = ("a lower wall speed or stress, a shorter run, or a stiffer skeleton (G, K of "
                  "the material)")
        strains = [elastic_strains(self.pb, *self.rows[-1][:2]), elastic_strains(self.pb, t, y)]
        for k, (mod, s_name, m_name) in enumerate(((m.G, "taubar", "G"), (m.K, "p", "K"))):
            past = past_elastic_limit([self.t, t], [e[k] * mod for e in strains], mod,
                                      stress_name=s_name, modulus_name=m_name, where=where,
                                      advice=advice)
            if past is not None:
                return past[1]
        return None

    def ended(self, end: RunEnd, counters) -> EndedEarly:
        """Save the checkpoint as finished with ``end`` (a run with outputs past t = 0 only: one
        that ends at its start has nothing to resume) and return the EndedEarly of the outputs
        so far (``end`` at the time of the last one)."""
        end = end.replace(time_s=self.t)
        if len(self.rows) > 1:
            self.save(self.state(finished=True, end=end))
        result = self.result(counters)
        result.end = end
        return EndedEarly([end], partial=result)

    def read_back(self, ck) -> Result:
        """A finished run from its checkpoint: returned, or raised again as ended early."""
        rec = json.loads(str(ck["end"])) if "end" in ck else None
        result = self.result()
        if not rec:
            return result
        result.end = RunEnd(**rec)
        raise EndedEarly([result.end], partial=result)


# ----------------------------------------------------------------------------- driver
def output_times(t_end: float, n_out: int = 200, t_out=None) -> np.ndarray:
    """Output times from 0: ``t_out`` if given (increasing, starting at 0), else n_out intervals
    to t_end (:data:`DURATION`, :data:`OUTPUTS`)."""
    if t_out is not None:
        t_out = check_range("t_out", np.asarray(t_out, dtype=float), 0.0, None)
        if t_out.ndim != 1 or t_out.size < 2 or np.any(np.diff(t_out) <= 0) or t_out[0] != 0:
            raise ValueError("t_out must be an increasing 1-D array starting at 0 s")
        DURATION.check("t_out[-1]", float(t_out[-1]))
        return t_out
    return np.linspace(0.0, DURATION.check("t_end", t_end), OUTPUTS.check("n_out", n_out) + 1)


#: Floats held per cell and output by a run and its post-processing (states, diagnostics, the
#: fields extracted for the files and figures, the checkpoint copy): the peak resident memory of
#: run_annular grows by 36 floats per cell and output; 48 leaves a margin (the arrays a run holds
#: are counted in tests/test_shear1d_cli.py).
FLOATS_PER_CELL_OUTPUT = 48


def memory_estimate(n_cells: int, n_out: int, runs: int = 1) -> float:
    """Bytes a run of ``runs`` scenes of n_cells cells with n_out output intervals needs (all
    results are kept for the combined figures)."""
    return float(runs) * FLOATS_PER_CELL_OUTPUT * 8.0 * n_cells * (n_out + 1) + 50e6


@dataclass(frozen=True)
class Plan:
    """A run's settings, checked once by :func:`prepare` and integrated by :func:`integrate`:
    output ``times``, ``dt`` and the stability limits ``lim`` (explicit), the
    :class:`shear1d.dae.FullLawDAE` (method ``"dae"``)."""

    problem: Couette
    method: str
    times: np.ndarray
    rtol: float
    dt: float | None = None
    lim: dict | None = None
    dae: dae_mod.FullLawDAE | None = None
    checkpoint: object = None
    checkpoint_every: float = 60.0
    resume: bool = False

    @property
    def setting(self) -> float:
        """The step (explicit) or the tolerance that identifies the run's checkpoint."""
        return float(self.dt if self.method == "explicit" else self.rtol)


def prepare(problem: Couette, t_end: float | None = None, *, method: str = "ida",
            n_out: int = 200, t_out=None, rtol: float = 1e-4, dt: float | None = None,
            check_stability: bool = True, checkpoint=None, checkpoint_every: float = 60.0,
            resume: bool = False) -> Plan:
    """The settings of :func:`solve` checked once (ValueError naming the parameter, its range
    and reason: :data:`METHODS`, :data:`RTOL`, :data:`DT` within the stability limit unless
    ``check_stability=False``, :func:`output_times`, :data:`CHECKPOINT_EVERY`; method ``"dae"``
    for the problems of :class:`shear1d.dae.FullLawDAE`)."""
    method = Param(kind="choice", choices=METHODS).check("method", method)
    if not isinstance(problem, Couette):
        raise ValueError("problem must be a shear1d Couette")
    times = output_times(t_end, n_out, t_out)
    CHECKPOINT_EVERY.check("checkpoint_every", checkpoint_every)
    if resume and checkpoint is None:
        raise ValueError("resume=True needs a checkpoint path")
    rtol, lim, dae = RTOL.check("rtol", rtol), None, None
    if dt is not None:                   # refused even where the method does not use it
        dt = DT.check("dt", dt)
    if method == "explicit":
        lim = stable_time_step(problem)
        if dt is None or check_stability:
            dt = check_time_step(problem, dt, lim)
    if method == "dae":                  # K4_REG, COMPACTION_WIDTH read at call time
        dae = dae_mod.FullLawDAE(problem, dae_mod.K4_REG, dae_mod.COMPACTION_WIDTH)
    return Plan(problem, method, times, rtol, dt, lim, dae, checkpoint, checkpoint_every,
                bool(resume))


def solve(problem: Couette, t_end: float | None = None, *, progress: bool = False,
          label: str = "", stop_hook=None, log=None, elastic_limit: bool = False,
          **settings) -> Result:
    """Integrate a Couette problem from rest (see the module docstring): :func:`prepare` (the
    ``settings``: method, n_out, t_out, rtol, dt, check_stability, checkpoint,
    checkpoint_every, resume) then :func:`integrate`.

    ``t_end`` [s] with ``n_out`` output intervals, or ``t_out`` (output times [s] increasing
    from 0). ``rtol`` (:data:`RTOL`): IDA's relative tolerance (absolute: rtol times the
    velocity scale for v, tau* for stresses, 1 for f, 1e-2 for phi) and the rate-form step
    (:meth:`Couette.rate_step_at`). ``dt`` [s]: the explicit step (default half the stability
    limit; beyond it ValueError unless ``check_stability=False``, which charts where the scheme
    fails). ``checkpoint``: an ``.npz`` path written at most every ``checkpoint_every`` wall
    seconds, at the end and on an interrupt; ``resume`` continues from its last output (explicit:
    bit for bit; IDA restarts its BDF history there and agrees to its tolerance). For
    ``progress``, ``label``, ``stop_hook``, ``log`` and ``elastic_limit`` see :func:`integrate`.

    Returns the :class:`Result` (``stats`` and ``wall_time`` count resumed parts too).

    Raises
    ------
    ValueError
        Bad input (method, times, rtol, an unstable dt, a missing or foreign checkpoint;
        :class:`runkit.io.CorruptCheckpoint`).
    rheology.run_end.EndedEarly
        The integration failed (IDA, the explicit scheme, the local update), produced an
        unphysical state or passed the elastic-strain limit: ``partial`` is the Result of the
        outputs before, saved to the checkpoint as finished.
    KeyboardInterrupt
        Interrupted; the message says where the checkpoint is (or that nothing was saved).
    """
    return integrate(prepare(problem, t_end, **settings), progress=progress, label=label,
                     stop_hook=stop_hook, log=log, elastic_limit=elastic_limit)


def integrate(plan: Plan, *, progress: bool = False, label: str = "", stop_hook=None, log=None,
              elastic_limit: bool = False) -> Result:
    """Integrate the checked ``plan`` (:func:`prepare`; errors as :func:`solve`). ``progress``:
    a :class:`runkit.run.Progress` labelled ``label``; ``stop_hook(t)`` after every output but
    the last (tests interrupt runs with it); ``log`` is told when a corrupt checkpoint is
    replaced by its predecessor; ``elastic_limit`` ends the run where a cell's elastic strain
    passes :data:`rheology.elastic.ELASTIC_STRAIN_LIMIT`."""
    problem, method, times, dae = plan.problem, plan.method, plan.times, plan.dae
    events = _Events(problem, None if dae is None else dae.convert)
    outs = _Outputs(problem, method, times, plan.setting, plan.checkpoint, events, elastic_limit,
                    1e-6 if method == "explicit" else 100 * plan.rtol)
    ck = outs.load(log) if plan.resume else None
    if method == "explicit":
        to = _explicit(problem, outs, ck, plan.dt, plan.lim)
    else:
        to = _ida(problem, outs, ck, plan.rtol, dae)
    if ck is not None and bool(ck["finished"]):
        return outs.read_back(ck)
    outs.to, outs.stop_hook = to, stop_hook
    outs.k = int(np.searchsorted(times, outs.t, side="right"))
    bar = Progress(outs.t, outs.t_end, outs.steps, label=label or "shear1d",
                   t_start=float(times[0])) if progress else None
    outs.wall0 = time.perf_counter()     # the integration's wall time, not the set-up's
    drive(outs, checkpoint=outs.ck, every=plan.checkpoint_every, progress=bar)
    outs.save(outs.state(finished=True))
    return outs.result()


def _ida(problem: Couette, outs: _Outputs, ck, rtol: float, dae=None):
    """Methods ``"ida"`` (the rate form ``y' - rhs(y) = 0``, the problem's own layout) and
    ``"dae"`` (``dae``: :class:`shear1d.dae.FullLawDAE`, its state converted to the Couette
    layout at every output) on :class:`runkit.ida.Solver`, started at rest or from the
    checkpoint ``ck``'s last output (y, y', counters). Returns the ``to`` of :class:`_Outputs`."""
    if dae is None:
        work = np.empty(problem.size)
        bw = problem.bandwidth()

        def residual(t, y, yp, res):
            problem.rhs(t, y, work, problem.rate_step_at(rtol, t))
            np.subtract(yp, work, out=res)

        def convert(t, y):
            return y.copy(), problem.diagnostics(t, y, problem.rate_step_at(rtol, t))

        def start():
            y0 = problem.initial_state()
            yp0 = np.empty_like(y0)
            problem.rhs(0.0, y0, yp0, problem.rate_step_at(rtol, 0.0))
            return y0, yp0

        atol, opts, name = _tolerances(problem, rtol), {}, "IDA"
        more = lambda: dict(rate_step_end=problem.rate_step_at(rtol, outs.t))
    else:
        if ck is not None and ck["y"].shape != (dae.size,):
            raise ValueError("--resume: the checkpoint's DAE state does not match this grid")
        residual, convert, start, bw = dae.residual, dae.convert, dae.initial_state, \
            dae_mod.BANDWIDTH
        atol, opts, name = dae.tolerances(rtol), dict(algebraic_idx=dae.algebraic()), \
            "IDA (method dae)"
        more = lambda: dict(k4=dae.k4, width=dae.width)
    outs.stats = lambda c: dict(nfev=int(c[0]), njev=int(c[1]), rtol=rtol, bandwidth=bw, **more())

    def describe(t, y):
        st = problem.unpack(y if dae is None else dae.convert(t, y)[0], t)
        return (f"{problem.grid.n} cells{'' if dae else f', mode {problem.mode}'}, rtol "
                f"{rtol:g}; max f = {st['f'].max():.6g}, max |sigma| = "
                f"{np.abs(st['sigma']).max():.6g} Pa"
                + (f", min p = {y[dae.i_p].min():.6g} Pa" if dae else ""))

    if ck is None:
        y0, yp0 = start()
        outs.add(0.0, *convert(0.0, y0), (0, 0, 0), dict(y=y0.copy(), yp=yp0.copy()))
    else:
        y0, yp0 = ck["y"], ck["yp"]
    base = outs.rows[-1][3].copy()
    ev = outs.events
    if ev.active:
        opts.update(events=ev.ida_events, names=EVENTS, direction=ev.directions)
    solver = Solver(residual, rtol=rtol, atol=atol, band=bw, max_num_steps=500000,
                    max_order=MAX_ORDER, describe=describe, solver=name, **opts)
    solver.start(outs.t, y0, yp0)

    def to(t_target):
        try:
            sol, fired = solver.advance(t_target)
        except IDAFailed as exc:
            c = base + np.array([exc.sol.nfev, exc.sol.njev, 0.0])
            return None, None, None, c, None, RunEnd("solver_failure", str(exc), past_s=exc.t)
        except RuntimeError as exc:          # the law failed inside a residual
            return None, None, None, outs.rows[-1][3], None, RunEnd(
                "law_failure", f"{' '.join(str(exc).split())} (in IDA's residual, stepping to "
                               f"t = {t_target:.6g} s)")
        for t_root, event, _ in fired:
            ev.times[event].append(t_root)
        t = float(sol.t)
        return (t, *convert(t, sol.y), base + np.array([sol.nfev, sol.njev, 0.0]),
                dict(y=sol.y.copy(), yp=sol.yp.copy()), None)

    return to


def _tolerances(problem: Couette, rtol: float) -> np.ndarray:
    lay = problem.layout()
    atol = np.empty(problem.size)
    atol[lay["i_S"].ravel()] = rtol * problem.stress_scale()
    atol[lay["i_f"]] = rtol
    if problem.two_phase:
        atol[lay["i_phi"]] = 1e-2 * rtol
    atol[lay["i_v"][lay["i_v"] >= 0]] = rtol * problem.velocity_scale()
    return atol


def _explicit(problem: Couette, outs: _Outputs, ck, dt: float, lim: dict):
    """Method ``"explicit"``: :func:`shear1d.kernels.explicit_steps` between outputs, from rest
    or the checkpoint ``ck``'s last output. Returns the ``to`` of :class:`_Outputs`."""
    outs.stats = lambda c: dict(steps=int(c[0]), dt=dt, dt_stable=float(lim["dt"]))
    if ck is None:
        y0 = problem.initial_state()
        outs.add(0.0, y0, problem.diagnostics(0.0, y0, dt), (0,))
    t_last, y_last = outs.rows[-1][:2]
    st = problem.unpack(y_last, t_last)
    v, S, f, phi = st["v"].copy(), st["sigma"].copy(), st["f"].copy(), st["phi"].copy()
    outs.events.sample(t_last, y_last)
    diag = np.empty((problem.grid.n, kernels.NDIAG))
    m, mt = problem.material, problem.metrics()
    grid = tuple(mt[k] for k in ("cg", "w", "A", "M", "A_wall", "a", "V", "hoop_c", "hoop_f",
                                 "dx"))

    def to(t1):
        t0, steps = outs.t, outs.rows[-1][3][0]
        nsub = max(1, int(math.ceil((t1 - t0) / dt * (1 - 1e-12))))
        h = (t1 - t0) / nsub
        did, bad = kernels.explicit_steps(
            nsub, t0, h, problem.drive_amplitude, problem.ramp_time, problem.stress_driven, v, S,
            f, phi, *grid, m.eta0, m.d, m.rho_s, m.rho_f, problem.parameters(),
            problem.contact_pressure, diag, problem.two_phase)
        t_bad = t0 + did * h
        if bad >= 0:
            return None, None, None, (steps,), None, RunEnd(
                "law_failure", f"Table 8 local update failed in cell {bad} at t = {t_bad:.6g} s "
                               f"(explicit, dt = {h:.3g} s)", past_s=t_bad)
        if did < nsub or not np.all(np.isfinite(v)):
            return None, None, None, (steps,), None, RunEnd(
                "solver_failure", f"explicit scheme diverged at t = {t_bad:.6g} s with dt = "
                                  f"{h:.6g} s (stability limit {lim['dt']:.6g} s)", past_s=t_bad)
        y = problem.pack(v, S, f, phi)
        return t1, y, problem.diagnostics(t1, y, dt), (steps + did,), None, None

    to.sample = outs.events.active

    return to
