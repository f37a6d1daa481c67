"""Time integration of a :class:`~shear1d.model.Couette` problem, and its results.

Three methods on the same finite-volume grid and the same Table 8 law:

- ``"ida"``: method of lines on SUNDIALS IDA (``sksundae.ida.IDA``), BDF of order <= 2 with
  adaptive steps, banded finite-difference Jacobian (unknowns interleaved cell by cell), the local
  update used as a rate over delta (:meth:`Couette.rhs`, :meth:`Couette.rate_step_at`: delta =
  rtol times the flow time, so one tolerance sets both errors), and two root events: the jammed
  band reaching the outer wall (``front_at_wall``: the structure front passes WALL_FRACTION of
  the gap) and the flow stopping (``flow_stopped``: the bulk speed falls below FLOW_STOP_LEVEL of
  the wall speed);
- ``"explicit"``: symplectic Euler with the Table 8 local update as a true step
  (:func:`shear1d.kernels.explicit_steps`), the scheme of the paper's MPM in 1-D. It is stable for
  ``dt <= 4/(lambda + sqrt(lambda^2 + 4 omega^2))`` (omega: fastest elastic shear mode, ~2c/dx with
  c = sqrt(G/rho); lambda: fastest fluid-viscous rate ~4 eta_f/(rho dx^2)) and, in two-phase mode,
  ``dt <= dx^2/(2 D)`` with the consolidation diffusivity D = (K + 4G/3) n^2/C; a larger user dt is
  refused with a ValueError (:func:`stable_time_step`);
- ``"dae"`` (locked mode only): the same law in its continuous form as a smooth DAE on IDA
  (:mod:`shear1d.dae`: the plastic state algebraic with the flow rule as its equation, compaction
  by Table 8's rule with a regularising K4 > 0), whose cost grows about linearly with the cells.

All three write results at the requested output times and check the physics there (finite
state, 0 <= f <= 1, 0 < phi < 1, p >= 0; with ``elastic_limit`` the elastic strains taubar/G and
p/K of every cell within :data:`rheology.elastic.ELASTIC_STRAIN_LIMIT`). An output that breaks a
check, a failed IDA step or a failed local update ends the run there:
:class:`rheology.run_end.EndedEarly` with the diagnostics and the :class:`Result` of the outputs
before it (``Result.end`` says where and why, :mod:`rheology.run_end`). Runs can checkpoint to an
``.npz`` file and resume from it (:mod:`runkit.io`, atomic; an ended run resumes as ended).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rheology import f_jam
from runkit.params import check_positive, check_range
from rheology.elastic import past_elastic_limit
from rheology.flow_rule import invariants
from runkit.io import CorruptCheckpoint, load_checkpoint, save_checkpoint
from rheology.run_end import EndedEarly, RunEnd
from runkit.ida import IDAFailed, Solver

from . import analysis, kernels
from . import dae as dae_mod
from .model import STRESS_COMPONENTS, Couette

METHODS = ("ida", "explicit", "dae")
EVENTS = ("front_at_wall", "flow_stopped")
#: flow_stopped fires when the bulk speed (analysis.bulk_speed) falls below this fraction of u_wall.
FLOW_STOP_LEVEL = 0.1


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
    wall_time : float, seconds spent integrating (this process; excludes a resumed part)
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
    rho_min = min(m.rho_s, m.rho_f)
    cg, w, A, M = mt["cg"], mt["w"], mt["A"], mt["M"]
    n = g.n
    rows = []
    for k in range(1, n):               # interior faces: |coefficients| of v_{k-1}, v_k, v_{k+1}
        rows.append((A[k - 1] * cg[k - 1] * (w[k - 1] + w[k]) + A[k] * cg[k] * (w[k] + w[k + 1]))
                    / M[k])
    if problem.stress_driven:
        rows.append(A[0] * cg[0] * (w[0] + w[1]) / M[0])
    op = max(rows) / rho_min             # omega^2 = G op, lambda = eta op
    omega = math.sqrt(m.G * op)
    phi_hi = min(problem.phi0 + 0.05, 0.99)
    eta_max = m.eta0 * (1.0 + 2.5 * phi_hi)
    lam = eta_max * op
    dt_mech = 4.0 / (lam + math.sqrt(lam * lam + 4.0 * omega * omega))
    dt_darcy = math.inf
    if problem.two_phase:
        phis = np.linspace(max(problem.phi0 - 0.05, 0.01), phi_hi, 11)
        mob = np.max(problem.coefficients(phis)[2][1:-1])
        diff = (m.K + 4.0 * m.G / 3.0) * mob
        dt_darcy = 0.9 * g.dx ** 2 / (2.0 * diff)
    return dict(dt=min(dt_mech, dt_darcy), dt_wave=2.0 / omega, dt_viscous=2.0 / lam,
                dt_darcy=dt_darcy, omega=omega, lam=lam)


def check_time_step(problem: Couette, dt: float) -> float:
    """Return dt if the explicit scheme is stable with it, else raise ValueError naming the limit."""
    check_positive("dt", dt, note="s")
    lim = stable_time_step(problem)
    if dt > lim["dt"]:
        parts = (f"elastic shear waves ~dx/c: {lim['dt_wave']:.3g} s, fluid viscosity "
                 f"~rho dx^2/(2 eta_f): {lim['dt_viscous']:.3g} s")
        if math.isfinite(lim["dt_darcy"]):
            parts += f", Darcy consolidation dx^2/(2D): {lim['dt_darcy']:.3g} s"
        raise ValueError(f"dt = {dt:.6g} s is outside the explicit stability range (0, "
                         f"{lim['dt']:.6g}] s of this grid ({parts}); use a smaller dt or "
                         f"method='ida'")
    return dt


# ----------------------------------------------------------------------------- events
class _Events:
    """The two root functions, shared by IDA (root finding) and the explicit scheme (sampling)."""

    directions = (1, -1)

    def __init__(self, problem: Couette):
        self.pb = problem
        self.active = not problem.stress_driven
        self.f_ref = float(f_jam(problem.phi0, problem.material))
        self.times: dict[str, list[float]] = {k: [] for k in EVENTS}
        self._last: tuple[float, np.ndarray] | None = None

    def values(self, t: float, y: np.ndarray) -> np.ndarray:
        pb, g = self.pb, self.pb.grid
        u = pb.wall_velocity(t)
        st = pb.unpack(y, t)
        if u == 0:
            return np.array([-1.0, 1.0])
        return np.array([analysis.structure_front(g, st["f"], self.f_ref)
                         - (g.inner + analysis.WALL_FRACTION * g.gap),
                         analysis.bulk_speed(g, st["v"], u) - FLOW_STOP_LEVEL])

    def ida_events(self, t, y, yp, out) -> None:
        """The root functions as IDA takes them (:class:`runkit.ida.Solver`)."""
        out[:] = self.values(t, y)

    def sample(self, t: float, y: np.ndarray) -> list[str]:
        """Record crossings between the previous sample and (t, y) (explicit scheme)."""
        g1 = self.values(t, y)
        fired = []
        if self._last is not None:
            t0, g0 = self._last
            for i, name in enumerate(EVENTS):
                d = self.directions[i]
                if (d > 0 and g0[i] < 0 <= g1[i]) or (d < 0 and g0[i] > 0 >= g1[i]):
                    te = t0 + (t - t0) * g0[i] / (g0[i] - g1[i])
                    self.times[name].append(float(te))
                    fired.append(name)
        self._last = (t, g1)
        return fired


# ----------------------------------------------------------------------------- physics checks
def check_state(problem: Couette, t: float, y: np.ndarray, diag: np.ndarray,
                f_tol: float = 1e-6) -> None:
    """Raise RuntimeError with diagnostics if a state is unphysical (non-finite, f or phi out of
    bounds, negative pressure)."""
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
    if np.any(p < 0):
        problems.append(f"negative granular pressure {p.min():.6g} Pa")
    if problems:
        raise RuntimeError(f"unphysical state at t = {t:.6g} s ({problem.grid.kind}, "
                           f"{problem.grid.n} cells, mode {problem.mode}): " + "; ".join(problems)
                           + f"; max |v| = {np.nanmax(np.abs(st['v'])):.6g} m/s, "
                           f"max |sigma| = {np.nanmax(np.abs(st['sigma'])):.6g} Pa")


def elastic_strains(problem: Couette, t: float, y: np.ndarray) -> tuple[float, float]:
    """The largest elastic strains (taubar/G, p/K) over the cells of a state (Eq. 11 invariants
    of the cell stresses; p/K of a compression, 0 in tension)."""
    sig = problem.unpack(y, t)["sigma"]
    rr, thth, zz, rth = (sig[:, STRESS_COMPONENTS.index(c)] for c in
                         ("sigma_rr", "sigma_thth", "sigma_zz", "sigma_rth"))
    full = np.zeros((sig.shape[0], 3, 3))
    full[:, 0, 0], full[:, 1, 1], full[:, 2, 2] = rr, thth, zz
    full[:, 0, 1] = full[:, 1, 0] = rth
    taubar, p = invariants(full)
    m = problem.material
    return float(np.max(taubar)) / m.G, max(float(np.max(p)), 0.0) / m.K


def _stored_end(ck) -> RunEnd | None:
    """The end a checkpoint of an ended run holds (None: none, or an older checkpoint)."""
    rec = json.loads(str(ck["end"])) if "end" in ck else None
    return RunEnd(**rec) if rec else None


def _resumed_finished(ck, result: "Result") -> "Result":
    """A finished run read back from its checkpoint: returned, or raised again as ended early."""
    end = _stored_end(ck)
    if end is None:
        return result
    result.end = end
    raise EndedEarly([end], partial=result)


# ----------------------------------------------------------------------------- checkpoints
#: Arrays every checkpoint holds (a file without one of them is named as corrupt).
CHECKPOINT_ARRAYS = ("signature", "t_out", "Y", "D", "event_names", "event_times", "counters",
                     "finished")


def _signature(problem: Couette, method: str, times: np.ndarray, setting: float) -> str:
    """Text identifying a run: material, grid, drive, mode, method, its step or tolerance and the
    output times. A checkpoint is resumed only by the run with the same signature."""
    m, g = problem.material, problem.grid
    params = ",".join(f"{x:.17g}" for x in m.kernel_array()) + f",{m.rho_f!r}"
    tsig = f"{times.size}:{times[0]!r}:{times[-1]!r}:{float(np.sum(times))!r}"
    return (f"{method}|{setting!r}|{m.name}|{params}|{g.kind}|{g.inner!r}|{g.outer!r}|{g.n}|"
            f"{problem.mode}|{problem.wall_speed!r}|{problem.wall_stress!r}|{problem.ramp_time!r}|"
            f"{problem.phi0!r}|{problem.contact_pressure!r}|{problem.rate_step!r}|{tsig}")


class _Outputs:
    """The outputs recorded so far, the counters at each, and the checkpoint they go to.

    Each output is appended as one tuple (time, state, diagnostics, counters), so an interrupt
    (SIGTERM or Ctrl-C raise KeyboardInterrupt between any two bytecodes) never leaves the lists
    inconsistent; events later than the last output are dropped when saving, so a resumed run,
    which restarts from that output, finds them again.
    """

    def __init__(self, problem, method, times, setting, checkpoint, checkpoint_every, events,
                 elastic_limit=False):
        self.pb, self.method, self.times = problem, method, times
        self.elastic_limit = bool(elastic_limit)
        self.sig = _signature(problem, method, times, setting)
        self.path = None if checkpoint is None else Path(checkpoint)
        self.every = float(checkpoint_every)
        self.events = events
        self.rows: list[tuple] = []
        self.extra: dict = {}
        self.last_save = time.perf_counter()
        self.wall_before = 0.0           # integration time of the runs before a resume [s]

    def add(self, t, y, diag, counters, extra=None):
        self.rows.append((float(t), y, diag, np.asarray(counters, dtype=float), extra))

    @property
    def t_last(self) -> float:
        return self.rows[-1][0]

    def arrays(self):
        T = np.array([r[0] for r in self.rows])
        Y = np.array([r[1] for r in self.rows])
        D = np.array([r[2] for r in self.rows])
        return T, Y, D

    def save(self, finished: bool = False, wall: float = 0.0, end: RunEnd | None = None):
        if self.path is None:
            return None
        rows = list(self.rows)
        T, Y, D = (np.array([r[i] for r in rows]) for i in range(3))
        t_last = T[-1]
        names = np.array([k for k, ts in self.events.times.items() for x in ts if x <= t_last],
                         dtype="U32")
        times = np.array([x for ts in self.events.times.values() for x in ts if x <= t_last],
                         dtype=float)
        extra = rows[-1][4] or {}
        save_checkpoint(self.path, signature=np.array(self.sig), t_out=T, Y=Y, D=D,
                        event_names=names, event_times=times, counters=rows[-1][3],
                        finished=np.array(bool(finished)), wall=np.array(wall),
                        end=np.array(json.dumps(end.record() if end else None)), **extra)
        self.last_save = time.perf_counter()
        return self.path

    def due(self) -> bool:
        return self.path is not None and time.perf_counter() - self.last_save >= self.every

    def load(self, log=None) -> dict:
        """Read the checkpoint (refused if absent, corrupt without a readable predecessor, or of
        another run) and restore the outputs and events; returns the checkpoint's arrays."""
        ck = load_checkpoint(self.path, required=CHECKPOINT_ARRAYS, log=log)
        sig = str(ck["signature"])
        if sig != self.sig:
            raise ValueError(f"--resume: checkpoint {self.path} belongs to another run (other "
                             f"parameters, method, step or outputs); delete it or drop --resume")
        T, Y, D = ck["t_out"], ck["Y"], ck["D"]
        if T.ndim != 1 or Y.shape[0] != T.size or D.shape[0] != T.size or T.size == 0:
            raise CorruptCheckpoint(f"checkpoint {self.path} is corrupt (inconsistent output "
                                    "arrays)")
        counters = ck["counters"]
        for k in range(T.size):
            self.rows.append((float(T[k]), Y[k].copy(), D[k].copy(), counters, None))
        for name in EVENTS:
            self.events.times[name] = []
        for name, te in zip(ck["event_names"], ck["event_times"]):
            self.events.times[str(name)].append(float(te))
        self.wall_before = float(ck["wall"]) if "wall" in ck else 0.0
        return ck

    def end_at(self, t: float, y: np.ndarray, diag: np.ndarray, f_tol: float = 1e-6):
        """The end an output at t makes, or None: an unphysical state (:func:`check_state`) and,
        with ``elastic_limit``, an elastic strain taubar/G or p/K past the limit in a cell (the
        largest over the cells, against the last output's)."""
        try:
            check_state(self.pb, t, y, diag, f_tol)
        except RuntimeError as exc:
            return RunEnd("solver_failure", str(exc), past_s=float(t))
        if not self.elastic_limit:
            return None
        m, g = self.pb.material, self.pb.grid
        where = (f"{g.kind} cell, {g.n} cells, mode {self.pb.mode}, largest over the cells at "
                 f"G = {m.G:g} Pa, K = {m.K:g} Pa")
        advice = ("a lower wall speed or stress, a shorter run, or a stiffer skeleton (G, K of "
                  "the material)")
        times = [r[0] for r in self.rows[-1:]] + [t]         # the last output and this one
        strains = [elastic_strains(self.pb, *r[:2]) for r in self.rows[-1:]]
        strains.append(elastic_strains(self.pb, t, y))
        for k, (mod, s_name, m_name) in enumerate(((m.G, "taubar", "G"), (m.K, "p", "K"))):
            past = past_elastic_limit(times, [e[k] * mod for e in strains], mod,
                                      stress_name=s_name, modulus_name=m_name, where=where,
                                      advice=advice)
            if past is not None:
                return past[1]
        return None

    def ended(self, end: RunEnd, result: "Result", wall: float) -> EndedEarly:
        """Save the checkpoint as finished with ``end`` (a run with outputs past t = 0 only: one
        that ends at its start has nothing to resume) and return the EndedEarly of ``result``
        (the outputs so far, ``end`` with the time of the last one)."""
        end = end.replace(time_s=self.t_last)
        if len(self.rows) > 1:
            self.save(finished=True, wall=wall, end=end)
        result.end = end
        return EndedEarly([end], partial=result)

    def interrupted(self, wall: float) -> KeyboardInterrupt:
        """Save the checkpoint (if any) and return the KeyboardInterrupt that says so."""
        path = self.save(wall=wall) if self.rows else None
        if path is None:
            return KeyboardInterrupt("nothing was saved")
        return KeyboardInterrupt(f"checkpoint {path} holds the run to t = {self.t_last:.6g} s; "
                                 f"rerun with --resume to continue")


class _Progress:
    """tqdm bar of the simulated time (with its ETA, on stderr), or nothing. The bar starts at
    the first time it is given (a resumed run's ETA counts only what is left)."""

    def __init__(self, enabled, t_end, label):
        self.enabled, self.t_end, self.label, self.bar = bool(enabled), float(t_end), label, None

    def to(self, t):
        if not self.enabled:
            return
        if self.bar is None:
            from tqdm import tqdm
            self.bar = tqdm(total=self.t_end, initial=float(t), desc=self.label or "shear1d",
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.4g}/{total:.4g}"
                                       " s simulated [{elapsed}<{remaining}]", leave=False,
                            dynamic_ncols=True)
        else:
            self.bar.update(float(t) - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()


# ----------------------------------------------------------------------------- driver
def output_times(t_end: float, n_out: int = 200, t_out=None) -> np.ndarray:
    """Output times from 0: ``t_out`` if given (increasing, starting at 0), else n_out intervals."""
    if t_out is not None:
        t_out = check_range("t_out", np.asarray(t_out, dtype=float), 0.0, None)
        if t_out.ndim != 1 or t_out.size < 2 or np.any(np.diff(t_out) <= 0) or t_out[0] != 0:
            raise ValueError("t_out must be an increasing 1-D array starting at 0 s")
        return t_out
    check_positive("t_end", t_end, note="s")
    if isinstance(n_out, bool) or int(n_out) != n_out or n_out < 1:
        raise ValueError(f"n_out = {n_out!r} must be a positive integer")
    return np.linspace(0.0, float(t_end), int(n_out) + 1)


#: Floats held per cell and output by a run and its post-processing (states, diagnostics, the
#: fields extracted for the files and figures, the checkpoint copy). Measured: the peak resident
#: memory of run_annular grew by 36 floats per cell and output (400 cells, 3000 outputs, one run
#: with its files and figures); the arrays it holds are counted in tests/test_shear1d_cli.py
#: (~29). 48 leaves a margin.
FLOATS_PER_CELL_OUTPUT = 48


def memory_estimate(n_cells: int, n_out: int, runs: int = 1) -> float:
    """Bytes a run of ``runs`` scenes of n_cells cells with n_out output intervals needs (all
    results are kept for the combined figures)."""
    return float(runs) * FLOATS_PER_CELL_OUTPUT * 8.0 * n_cells * (n_out + 1) + 50e6


def solve(problem: Couette, t_end: float | None = None, *, method: str = "ida", n_out: int = 200,
          t_out=None, rtol: float = 1e-4, dt: float | None = None, check_stability: bool = True,
          stop_on=(), checkpoint=None, checkpoint_every: float = 60.0, resume: bool = False,
          max_step: float = 0.0, max_order: int = 2, progress: bool = False, label: str = "",
          stop_hook=None, log=None, elastic_limit: bool = False) -> Result:
    """Integrate a Couette problem from rest.

    Parameters
    ----------
    problem : Couette
    t_end : float
        End time [s] (or give ``t_out``).
    method : {"ida", "explicit", "dae"}
        ``"dae"``: locked mode only, the full Table 8 law as a smooth DAE on IDA
        (:mod:`shear1d.dae`; ValueError for two-phase); ``rtol`` as for ``"ida"``.
    n_out : int
        Number of output intervals (outputs at n_out + 1 evenly spaced times).
    t_out : array_like, optional
        Explicit output times [s], increasing from 0.
    rtol : float
        IDA relative tolerance (absolute tolerances: rtol times the wall speed for v, times tau*
        for stresses, rtol for f, rtol/100 for phi). It also sets the rate-form step delta
        (:meth:`Couette.rate_step_at`): one knob for both errors.
    dt : float, optional
        Explicit step [s]; default half the stability limit. Beyond the limit: ValueError unless
        ``check_stability=False`` (used to chart where the scheme fails).
    stop_on : iterable of str
        Event names (``front_at_wall``, ``flow_stopped``) that end the run when they fire.
    checkpoint : path, optional
        ``.npz`` checkpoint (:func:`runkit.io.save_checkpoint`, the previous one kept as
        ``.prev.npz``) written at an output at most every ``checkpoint_every`` seconds of wall
        time, at the end, and when the run is interrupted (KeyboardInterrupt: Ctrl-C, or SIGTERM
        under :func:`runkit.command.run`); the interrupt is re-raised with a message
        naming the checkpoint.
    resume : bool
        Continue from ``checkpoint`` (ValueError if there is none or it belongs to another run;
        :class:`runkit.io.CorruptCheckpoint` if it and its predecessor are unreadable). The
        run restarts from the checkpoint's last output: with the explicit method the result is
        bit-for-bit the uninterrupted one; IDA restarts its BDF history there, so the result
        agrees with the uninterrupted one to the integration tolerance (measured: see
        tests/test_shear1d_resume.py).
    max_step : float
        Largest IDA step [s] (0: unbounded).
    max_order : int
        Largest BDF order of IDA, 1-5. Default 2: BDF1-2 are A-stable (BDF3-5 are not near the
        imaginary axis) and the jammed band is an elastic solid whose grid-scale shear waves only
        the small fluid viscosity damps.
    progress : bool
        Show a tqdm bar of the simulated time with its ETA (on stderr).
    label : str
        The bar's description.
    stop_hook : callable, optional
        Called as ``stop_hook(t)`` after every output is recorded (tests use it to interrupt a
        run at a given output by raising KeyboardInterrupt).
    log : callable, optional
        Told when a corrupt checkpoint is replaced by its predecessor.
    elastic_limit : bool
        End the run at an output where a cell's elastic strain taubar/G or p/K passes
        :data:`rheology.elastic.ELASTIC_STRAIN_LIMIT` (the scenes' command lines set it; the
        default False lets validation follow the law's algebra).

    Returns
    -------
    Result (``stats`` count every step and residual evaluation since t = 0, resumed parts
    included; ``wall_time`` too).

    Raises
    ------
    ValueError
        Bad input (method, times, rtol, an unstable dt, a missing or foreign checkpoint).
    rheology.run_end.EndedEarly (a RuntimeError)
        The integration failed (IDA, the explicit scheme, the local update), produced an
        unphysical state or, with ``elastic_limit``, passed the elastic-strain limit (with
        diagnostics): ``partial`` is the Result of the outputs before (its ``end`` says where
        and why), saved to the checkpoint as finished.
    KeyboardInterrupt
        Interrupted; the message says where the checkpoint is (or that nothing was saved).
    """
    if method not in METHODS:
        raise ValueError(f"method = {method!r} must be one of {METHODS}")
    if not isinstance(problem, Couette):
        raise ValueError("problem must be a shear1d Couette")
    times = output_times(t_end, n_out, t_out)
    stop_on = tuple(stop_on)
    for name in stop_on:
        if name not in EVENTS:
            raise ValueError(f"stop_on event {name!r} must be one of {EVENTS}")
    check_positive("checkpoint_every", checkpoint_every, note="s of wall time")
    if resume and checkpoint is None:
        raise ValueError("resume=True needs a checkpoint path")
    events = _Events(problem)
    if method in ("ida", "dae"):
        check_range("rtol", rtol, 1e-12, 1e-2, lo_closed=True)
        if max_order not in (1, 2, 3, 4, 5):
            raise ValueError(f"max_order = {max_order!r} must be an integer in [1, 5]")
        if method == "dae" and problem.two_phase:
            raise ValueError("method 'dae' is for mode 'locked' only; use method 'ida' or "
                             "'explicit' for two-phase")
        outs = _Outputs(problem, method, times, float(rtol), checkpoint, checkpoint_every,
                        events, elastic_limit)
        ck = outs.load(log) if resume else None
        bar = _Progress(progress, times[-1], label)
        try:
            if method == "dae":
                return _solve_dae(problem, times, rtol, stop_on, outs, ck, max_step, max_order,
                                 bar, stop_hook)
            return _solve_ida(problem, times, rtol, stop_on, outs, ck, max_step, max_order, bar,
                              stop_hook)
        finally:
            bar.close()
    lim = stable_time_step(problem)
    if dt is None:
        dt = 0.5 * lim["dt"]
    elif check_stability:
        check_time_step(problem, dt)
    else:
        check_positive("dt", dt, note="s")
    outs = _Outputs(problem, "explicit", times, float(dt), checkpoint, checkpoint_every, events,
                    elastic_limit)
    ck = outs.load(log) if resume else None
    bar = _Progress(progress, times[-1], label)
    try:
        return _solve_explicit(problem, times, float(dt), lim, stop_on, outs, ck, bar, stop_hook)
    finally:
        bar.close()


def _tolerances(problem: Couette, rtol: float) -> np.ndarray:
    lay = problem.layout()
    atol = np.empty(problem.size)
    atol[lay["i_S"].ravel()] = rtol * problem.stress_scale()
    atol[lay["i_f"]] = rtol
    if problem.two_phase:
        atol[lay["i_phi"]] = 1e-2 * rtol
    iv = lay["i_v"][lay["i_v"] >= 0]
    atol[iv] = rtol * problem.velocity_scale()
    return atol


def _result(problem, method, outs, wall0, stats) -> Result:
    T, Y, D = outs.arrays()
    return Result(problem, method, T, Y, D, {k: list(v) for k, v in outs.events.times.items()},
                  outs.wall_before + (time.perf_counter() - wall0), stats)


def _solve_ida(problem, times, rtol, stop_on, outs, ck, max_step, max_order, bar, stop_hook):
    """Method ``"ida"``: the rate form (:meth:`Couette.rhs` over delta =
    :meth:`Couette.rate_step_at`) as ``y' - rhs(y) = 0`` on :func:`_run_ida`; the solver's state
    is the problem's own (layout of :meth:`Couette.layout`)."""
    work = np.empty(problem.size)
    bw = problem.bandwidth()

    def resfn(t, y, yp, res):
        problem.rhs(t, y, work, problem.rate_step_at(rtol, t))
        np.subtract(yp, work, out=res)

    def start():
        y0 = problem.initial_state()
        yp0 = np.empty_like(y0)
        problem.rhs(0.0, y0, yp0, problem.rate_step_at(rtol, 0.0))
        return y0, yp0

    def convert(t, y):
        diag = problem.diagnostics(t, y, problem.rate_step_at(rtol, t))
        return y.copy(), diag

    def stats(counters):
        return dict(nfev=int(counters[0]), njev=int(counters[1]), rtol=rtol, bandwidth=bw,
                    rate_step_end=problem.rate_step_at(rtol, outs.t_last))

    def failure(sol, t_target):
        return ida_failure_message(problem, sol, t_target, rtol, sol.y)

    return _run_ida(problem, "ida", times, rtol, stop_on, outs, ck, max_step, max_order, bar,
                    stop_hook, residual=resfn, start=start, convert=convert,
                    options=dict(atol=_tolerances(problem, rtol), lband=bw, uband=bw),
                    stats=stats, failure=failure)


def ida_failure_message(problem: Couette, sol, t_target: float, rtol: float, state: np.ndarray,
                        solver: str = "IDA", with_mode: bool = True, extra: str = "") -> str:
    """The one-line diagnosis of a failed IDA step.

    Names the ``solver`` (e.g. ``"IDA"``, ``"IDA (method dae)"``), the time reached
    (``sol.t`` [s]) and the target output time [s], IDA's message and status, the cell count, the
    problem's mode (``with_mode``), ``rtol``, and the largest f and |sigma| [Pa] of ``state`` (the
    solver's state in the layout of :meth:`Couette.layout`, size ``problem.size``), followed by
    ``extra`` (further diagnostics, starting with ", ").
    """
    st = problem.unpack(state, sol.t)
    mode = f", mode {problem.mode}" if with_mode else ""
    return (f"{solver} failed at t = {sol.t:.6g} s (target {t_target:.6g} s): {sol.message} "
            f"(status {sol.status}); {problem.grid.n} cells{mode}, rtol {rtol:g}; max f = "
            f"{st['f'].max():.6g}, max |sigma| = {np.abs(st['sigma']).max():.6g} Pa{extra}")


def _run_ida(problem, method, times, rtol, stop_on, outs, ck, max_step, max_order, bar,
             stop_hook, *, residual, start, convert, options, stats, failure) -> Result:
    """Integrate a DAE ``residual(t, y, yp, res)`` on SUNDIALS IDA (:class:`runkit.ida.Solver`,
    banded Jacobian) from ``start() -> (y0, yp0)`` at t = 0 or from the checkpoint ``ck``'s last
    output (y, yp, counters; a finished run is returned as it is): the one stepping loop of
    methods ``"ida"`` and ``"dae"``.

    Steps to every output time of ``times`` (IDA restarts its BDF history there) with the root
    events of ``outs.events`` when active (``stop_on`` names those that end the run). At each
    output ``convert(t, y) -> (state, diag)`` gives the Couette layout, which is checked
    (:func:`check_state`, f within 100 rtol of [0, 1]), recorded with the solver's y and y' (what
    a resume restarts from), shown on ``bar`` and checkpointed at the end or when
    ``outs.due()``; ``stop_hook(t)`` follows every output but the last. ``options``: the
    method's IDA options (``atol`` array, ``lband``, ``uband``, ...); ``stats(counters)``: the
    result's stats; ``failure(sol, t_target)``: the message of a failed step.

    Raises :class:`rheology.run_end.EndedEarly` (IDA or the law failed, or an output fails
    :meth:`_Outputs.end_at`: the Result of the outputs before it) and KeyboardInterrupt after
    saving the checkpoint (:meth:`_Outputs.interrupted`).
    """
    wall0 = time.perf_counter()
    events = outs.events
    if ck is None:
        y0, yp0 = start()
        yc, dg = convert(0.0, y0)
        outs.add(0.0, yc, dg, (0, 0, 0), dict(y=y0.copy(), yp=yp0.copy()))
        base = np.zeros(3)
    else:
        y0, yp0 = ck["y"], ck["yp"]
        base = np.asarray(ck["counters"], dtype=float)
        outs.rows[-1] = outs.rows[-1][:4] + (dict(y=y0, yp=yp0),)
        if bool(ck["finished"]):
            return _resumed_finished(ck, _result(problem, method, outs, wall0, stats(base)))
    t0 = outs.t_last
    i_next = int(np.searchsorted(times, t0, side="right"))
    opts = dict(options)
    if events.active:
        opts.update(events=events.ida_events, names=EVENTS, direction=events.directions)
    solver = Solver(residual, rtol=rtol, atol=opts.pop("atol"), linsolver="band",
                    max_num_steps=500000, max_step=max_step, max_order=max_order, **opts)
    solver.start(t0, y0, yp0)
    bar.to(t0)
    stopped, end = False, None
    counters = base.copy()
    try:
        for t_target in times[i_next:]:
            try:
                sol, fired = solver.advance(float(t_target), stop_on=stop_on)
            except IDAFailed as exc:
                sol = exc.sol
                counters = base + np.array([sol.nfev, sol.njev, 0.0])
                said = f" [SUNDIALS: {exc.printed.lstrip('[')[:300]}]" if exc.printed else ""
                end = RunEnd("solver_failure", failure(sol, t_target) + said, past_s=exc.t)
                fired = []
            except RuntimeError as exc:          # the law failed inside a residual
                end = RunEnd("law_failure", f"{' '.join(str(exc).split())} (in IDA's "
                                            f"residual, stepping to t = {t_target:.6g} s)")
                fired = []
            else:
                counters = base + np.array([sol.nfev, sol.njev, 0.0])
            for t_root, name, _ in fired:
                events.times[name].append(t_root)
                stopped = stopped or name in stop_on
            if end is None:
                t_now = float(sol.t)
                yc, diag = convert(t_now, sol.y)
                end = outs.end_at(t_now, yc, diag, f_tol=100 * rtol)
            if end is not None:          # the outputs so far are the run (rheology.run_end)
                wall = outs.wall_before + time.perf_counter() - wall0
                raise outs.ended(end, _result(problem, method, outs, wall0, stats(counters)),
                                 wall)
            outs.add(t_now, yc, diag, counters, dict(y=sol.y.copy(), yp=sol.yp.copy()))
            bar.to(t_now)
            last = stopped or t_target == times[-1]
            if last or outs.due():
                outs.save(finished=last, wall=outs.wall_before + time.perf_counter() - wall0)
            if stop_hook is not None and not last:
                stop_hook(t_now)
            if stopped:
                break
    except KeyboardInterrupt:
        raise outs.interrupted(outs.wall_before + time.perf_counter() - wall0) from None
    return _result(problem, method, outs, wall0, stats(counters))


def _solve_explicit(problem, times, dt, lim, stop_on, outs, ck, bar, stop_hook):
    lay, mt, n = problem.layout(), problem.metrics(), problem.grid.n
    events = outs.events

    def stats(steps):
        return dict(steps=int(steps), dt=dt, dt_stable=float(lim["dt"]))

    wall0 = time.perf_counter()
    if ck is None:
        y0 = problem.initial_state()
        outs.add(0.0, y0, problem.diagnostics(0.0, y0, dt), (0,))
        steps = 0
    else:
        steps = int(ck["counters"][0])
        if bool(ck["finished"]):
            return _resumed_finished(ck, _result(problem, "explicit", outs, wall0, stats(steps)))
    t_last, y_last = outs.rows[-1][0], outs.rows[-1][1]
    st = problem.unpack(y_last, t_last)
    v, S, f, phi = st["v"].copy(), st["sigma"].copy(), st["f"].copy(), st["phi"].copy()
    events.sample(t_last, y_last)
    i_next = len(outs.rows)
    diag = np.empty((n, kernels.NDIAG))
    m, P = problem.material, problem.parameters()
    common = (mt["cg"], mt["w"], mt["A"], mt["M"], mt["A_wall"], mt["a"], mt["V"], mt["hoop_c"],
              mt["hoop_f"], mt["dx"])
    bar.to(t_last)
    try:
        for k in range(i_next, len(times)):
            t0, t1 = times[k - 1], times[k]
            nsub = max(1, int(math.ceil((t1 - t0) / dt * (1 - 1e-12))))
            h = (t1 - t0) / nsub
            did, bad = kernels.explicit_steps(
                nsub, t0, h, problem.drive_amplitude, problem.ramp_time, problem.stress_driven, v,
                S, f, phi, *common, m.eta0, m.d, m.rho_s, m.rho_f, P, problem.contact_pressure,
                diag, problem.two_phase)
            t_bad = t0 + did * h
            if bad >= 0:
                end = RunEnd("law_failure", f"Table 8 local update failed in cell {bad} at t = "
                                            f"{t_bad:.6g} s (explicit, dt = {h:.3g} s)",
                             past_s=t_bad)
            elif did < nsub or not np.all(np.isfinite(v)):
                end = RunEnd("solver_failure", f"explicit scheme diverged at t = {t_bad:.6g} s "
                                               f"with dt = {h:.6g} s (stability limit "
                                               f"{lim['dt']:.6g} s)", past_s=t_bad)
            else:
                y = problem.pack(v, S, f, phi)
                dg = problem.diagnostics(float(t1), y, dt)
                end = outs.end_at(float(t1), y, dg)
            if end is not None:          # the outputs so far are the run (rheology.run_end)
                wall = outs.wall_before + time.perf_counter() - wall0
                raise outs.ended(end, _result(problem, "explicit", outs, wall0, stats(steps)),
                                 wall)
            fired = events.sample(float(t1), y) if events.active else []
            stopped = any(name in stop_on for name in fired)
            outs.add(float(t1), y, dg, (steps + did,))
            steps += did
            bar.to(t1)
            last = stopped or k == len(times) - 1
            if last or outs.due():
                outs.save(finished=last, wall=outs.wall_before + time.perf_counter() - wall0)
            if stop_hook is not None and not last:
                stop_hook(float(t1))
            if stopped:
                break
    except KeyboardInterrupt:
        raise outs.interrupted(outs.wall_before + time.perf_counter() - wall0) from None
    return _result(problem, "explicit", outs, wall0, stats(steps))


class _DAEEvents(_Events):
    """The events of :mod:`shear1d.integrate` evaluated on the converted state."""

    def __init__(self, problem: Couette, dae: "dae_mod.FullLawDAE"):
        super().__init__(problem)
        self.dae = dae

    def values(self, t, y):
        if len(y) == self.dae.size:
            y = self.dae.convert(t, y)[0]
        return super().values(t, y)


def _solve_dae(problem, times, rtol, stop_on, outs, ck, max_step, max_order, bar, stop_hook,
              k4=None, width=None):
    """Integrate with IDA (banded difference-quotient Jacobian, BDF order <= max_order, x
    algebraic) on the stepping loop of method ``"ida"`` (:func:`_run_ida`), so
    with the same outputs, events, checkpoints and stats as :func:`solve` with
    ``method="ida"`` (called from there with ``method="dae"``); the outputs and checks see the
    DAE state converted to the Couette layout (:meth:`shear1d.dae.FullLawDAE.convert`), and the checkpoint
    also keeps the DAE state (y, y') a resume restarts from. ``k4`` and ``width`` default to the
    module's :data:`shear1d.dae.K4_REG` and :data:`shear1d.dae.COMPACTION_WIDTH` at call time. Raises ValueError when the
    checkpoint's DAE state does not fit the grid, RuntimeError with diagnostics (min p included)
    when IDA fails or a state is unphysical."""
    dae = dae_mod.FullLawDAE(problem, dae_mod.K4_REG if k4 is None else k4,
                             dae_mod.COMPACTION_WIDTH if width is None else width)
    events = _DAEEvents(problem, dae)
    events.times = outs.events.times
    outs.events = events
    if ck is not None and ck["y"].shape != (dae.size,):
        raise ValueError("--resume: the checkpoint's DAE state does not match this grid")

    def stats(counters):
        return dict(nfev=int(counters[0]), njev=int(counters[1]), rtol=rtol,
                    bandwidth=dae_mod.BANDWIDTH, k4=dae.k4, width=dae.width)

    def failure(sol, t_target):
        return ida_failure_message(problem, sol, t_target, rtol, dae.convert(sol.t, sol.y)[0],
                                   solver="IDA (method dae)", with_mode=False,
                                   extra=f", min p = {sol.y[dae.i_p].min():.6g} Pa")

    return _run_ida(problem, "dae", times, rtol, stop_on, outs, ck, max_step, max_order, bar,
                    stop_hook, residual=dae.residual, start=dae.initial_state, convert=dae.convert,
                    options=dict(atol=dae.tolerances(rtol), lband=dae_mod.BANDWIDTH, uband=dae_mod.BANDWIDTH,
                                 algebraic_idx=dae.algebraic()),
                    stats=stats, failure=failure)
