"""The rheometer's tests as functions returning DataFrames (units in the column names).

Every transient is a :class:`~rheometer.transient.Rheometer` run (SUNDIALS IDA on the 0-D DAE);
the steady flow curves come from :mod:`rheology.steady` (exact steady states, no time stepping).

Transient columns: ``time_s, step, strain, shear_rate_per_s, shear_stress_Pa`` (mixture:
granular + eta0 (1 + 5/2 phi) gdot), ``granular_shear_stress_Pa, plastic_shear_rate_per_s, f,
granular_pressure_Pa, viscosity_Pa_s, jamming_gap`` (phi_m(f) - phi; <= 0 when jammed). Stresses
and rates are signed (negative where the flow reverses: oscillation steps, recoil after a stress
drop); the pressure is the critical-state pressure of their magnitudes; ``viscosity_Pa_s`` is
tau/gdot, empty where gdot = 0 and in oscillation steps.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

import rheology
from rheology.run_end import EndedEarly

from .limits import POSITIVE_STRESS
from .program import Program, Start, parse_program
from .transient import Rheometer, State, Step, check_phi

#: Columns of a flow curve (``branch``, ``stable``, ``index`` added for rate or mixture-stress
#: control, ``jammed`` for granular-stress control).
FLOW_COLUMNS = ("phi", "shear_stress_Pa", "granular_shear_stress_Pa", "shear_rate_per_s",
                "viscosity_Pa_s", "relative_viscosity", "f", "granular_pressure_Pa")
CONTROLS = ("stress", "mixture-stress", "rate")


def flow_curve(material, phi, *, stress=None, rate=None, control: str = "stress") -> pd.DataFrame:
    """Steady flow curves at one or several volume fractions.

    Parameters
    ----------
    material : str or Material
    phi : float or sequence of float
        Volume fractions, each in [1e-6, phi_j) (:func:`rheometer.transient.check_phi`).
    stress : array_like, optional
        Imposed stresses [Pa] (default 200 values log-spaced over 1e-3..1e4 Pa). Granular shear
        stress for ``control="stress"``, mixture shear stress for ``control="mixture-stress"``.
    rate : array_like, optional
        Imposed shear rates [1/s] for ``control="rate"`` (default 200 values over 1e-4..1e3).
    control : {"stress", "mixture-stress", "rate"}
        "stress": imposed granular shear stress taubar, one steady state each (the curve is unique
        in this parametrisation, including the S-shaped DST part); "mixture-stress": imposed
        mixture stress tau = taubar + eta0 (1 + 5/2 phi) gdot, every steady state; "rate": imposed
        shear rate, every steady state (0, 1 or several: DST), each with ``branch`` (0, 1, ... by
        increasing stress) and ``stable`` (stable under that control, rigid-rheometer limit).

    Returns
    -------
    DataFrame
        :data:`FLOW_COLUMNS` (+ ``jammed`` or ``index, branch, stable``), sorted by phi.
    """
    m = rheology.get_material(material)
    phis = np.atleast_1d(np.asarray(phi, dtype=float)).ravel()
    if phis.size == 0:
        raise ValueError("give at least one volume fraction phi")
    phis = np.array([check_phi("phi", p, m) for p in phis])      # in [PHI_MIN, phi_j)
    if control not in CONTROLS:
        raise ValueError(f"control = {control!r} must be one of {', '.join(CONTROLS)}")
    if (rate is not None and control != "rate") or (stress is not None and control == "rate"):
        raise ValueError(f"control = {control!r} takes "
                         f"{'rate' if control == 'rate' else 'stress'} values, not "
                         f"{'stress' if control == 'rate' else 'rate'}")
    if control == "rate":
        values = np.logspace(-4, 3, 200) if rate is None else np.asarray(rate, dtype=float)
    else:
        values = np.logspace(-3, 4, 200) if stress is None else np.asarray(stress, dtype=float)
    values = np.atleast_1d(values).ravel()
    if control == "stress":
        T, Ph = np.meshgrid(values, phis)
        df = rheology.steady_state_stress(T, Ph, m).to_frame()
    else:
        solve = (rheology.steady_states_rate if control == "rate"
                 else rheology.steady_states_mixture_stress)
        df = pd.concat([solve(values, ph, m).to_frame() for ph in phis], ignore_index=True)
    # the viscosity tau/gdot is undefined where the steady rate is zero (jammed): an empty cell
    df.loc[~np.isfinite(df["viscosity_Pa_s"]), "viscosity_Pa_s"] = np.nan
    df["relative_viscosity"] = df["viscosity_Pa_s"] / m.eta0
    extra = [c for c in ("jammed", "index", "branch", "stable") if c in df.columns]
    df = df[list(FLOW_COLUMNS) + extra]
    df.attrs.update(material=m.name, control=control)
    return df


# ------------------------------------------------------------------ transients
def startup(material, phi: float, rate: float, t_end: float, *, G=None, K0=None, f0: float = 0.0,
            points: int = 300, name: str = "", label=str, **options) -> pd.DataFrame:
    """Start-up of steady shear: rate ``rate`` [1/s] imposed from rest (structure ``f0``) for
    ``t_end`` [s]. ``options`` go to :class:`Rheometer` (rtol, atol, form, jacobian). Every
    transient's inputs are checked once, by :class:`Rheometer` and :class:`Step` (``name``: what
    a refusal calls the rate, e.g. the command line's option; ``label(name)``: what it calls
    ``t_end``, ``rtol``, ``points``)."""
    r = Rheometer(material, phi, G=G, K0=K0, label=label, **options)
    return r.run([Step("rate", float(rate), duration=float(t_end),
                       label=f"shear at {rate:g} 1/s", name=name,
                       duration_name=label("t_end"))], r.rest(f0), points=points)


def creep(material, phi: float, stress: float, t_end: float, *, G=None, K0=None, f0: float = 0.0,
          points: int = 300, name: str = "", label=str, **options) -> pd.DataFrame:
    """Creep: mixture shear stress ``stress`` [Pa] imposed from rest for ``t_end`` [s]; the
    fluid carries it at once (gdot(0) = stress/(eta0 (1 + 5/2 phi))), the skeleton loads up.
    ``stress`` > 0 (at zero the sample never leaves rest); ``name``, ``label`` as for
    :func:`startup`."""
    r = Rheometer(material, phi, G=G, K0=K0, label=label, **options)
    return r.run([Step("stress", float(stress), duration=float(t_end),
                       label=f"stress {stress:g} Pa", name=name, quantity=POSITIVE_STRESS,
                       duration_name=label("t_end"))], r.rest(f0), points=points)


def relax(material, phi: float, stress: float, t_end: float, *, G=None, K0=None,
          points: int = 300, label=str, **options) -> pd.DataFrame:
    """Stress relaxation after cessation of steady shear (Eqs. 35-37, Fig. 15).

    Starts from the steady state at granular shear stress ``stress`` [Pa] (its f from Eq. 13),
    stops the flow (gdot = 0) and follows taubar(t), f(t) for ``t_end`` [s]. With gdot = 0 the
    mixture stress equals the granular one (column ``shear_stress_Pa``). ``label`` as for
    :func:`startup`.
    """
    r = Rheometer(material, phi, G=G, K0=K0, label=label, **options)
    return r.run([Step("rate", 0.0, duration=float(t_end), label="rest",
                       duration_name=label("t_end"))], r.steady(stress), points=points)


def at_phi(run, phi: float, ends: list) -> pd.DataFrame | None:
    """``run(phi)``; of a run that ends early (:mod:`rheology.run_end`) its rows up to the end
    (None without any), its end appended to ``ends`` named by ``phi``."""
    try:
        return run(phi)
    except EndedEarly as exc:
        ends.append(exc.ends[0].replace(run=f"phi = {phi:g}"))
        return exc.partial


def combined(frames, ends: list, attrs: dict | None = None) -> pd.DataFrame:
    """The rows of the runs at several phi together, ``attrs`` (default the first run's) and
    the ``ends`` in ``attrs["ends"]``; RuntimeError (the first end's reason) when none has a
    row."""
    frames = [f for f in frames if f is not None and len(f)]
    if not frames:
        raise RuntimeError(ends[0].reason)
    out = pd.concat(frames, ignore_index=True)
    out.attrs.update(frames[0].attrs if attrs is None else attrs)
    out.attrs["ends"] = list(ends)
    return out


def initial_state(r: Rheometer, start: Start) -> State:
    """The state a program starts from (rest, steady at a granular stress, or at a rate)."""
    if start.kind == "rest":
        return r.rest()
    if start.kind == "stress":
        return r.steady(start.value)
    branches = rheology.steady_states_rate(start.value, r.phi, r.material)
    stable = np.flatnonzero(branches.stable)
    if stable.size == 0:
        raise ValueError(f"no stable steady state at shear rate {start.value:g} 1/s and phi = "
                         f"{r.phi:g} ({r.material.name}): above the DST rate the flow jams; "
                         f"start from a steady stress instead")
    return r.steady(float(branches.taubar[stable[0]]))


def run_program(material, phi: float, program, *, G=None, K0=None, points: int = 200,
                resume=None, on_step=None, **options) -> pd.DataFrame:
    """Run a test program: text (see :mod:`rheometer.program`), a :class:`Program`, or a list
    of :class:`Step` (started at rest). Column ``step`` numbers the steps from 1.

    ``resume`` and ``on_step`` go to :meth:`Rheometer.run` (checkpoints between steps; see
    :mod:`rheometer.checkpoint`)."""
    if isinstance(program, str):
        program = parse_program(program)
    elif not isinstance(program, Program):
        program = Program(Start(), tuple(program))
    r = Rheometer(material, phi, G=G, K0=K0, **options)
    start = None if resume is not None else initial_state(r, program.start)
    where = f"{program.start.kind} {program.start.value:g}"
    try:
        df = r.run(program.steps, start, points=points, resume=resume, on_step=on_step)
    except EndedEarly as exc:                    # the rows up to the end (rheology.run_end)
        if exc.partial is not None:
            exc.partial.attrs["start"] = where
        raise
    df.attrs["start"] = where
    return df
