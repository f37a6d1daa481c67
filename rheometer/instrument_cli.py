"""The instrument's side of the ``rheometer`` command line and ``rheometer oscillation``.

- :func:`finish_table` (the table as written): the mass-fraction column of ``--mass-fraction``
  (Eq. 20), the instrument columns of ``--geometry`` (torque [N m], rotation speed [rad/s],
  apparent stress and rate; :mod:`rheometer.geometry`), normalised column names for the Table 1
  sets;
- :func:`extra_outputs`: for a parallel-plate flow curve the apparent curve of the radial
  integral beside the true one (``<out>_parallel_plate.csv`` and ``.png``);
- :func:`materials_note`: the default volume fractions of every material;
- :func:`add_subcommands`: ``rheometer oscillation``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

import rheology
from rheology.elastic import ELASTIC_STRAIN_LIMIT
from rheology.materials import RULE, default_fractions, has_dst
from rheology.run_end import EndedEarly, run_record
from runkit.io import (atomic_write_csv, atomic_write_json, check_finite,
                       check_output_path)

from . import geometry as geo
from . import limits, plots
from . import oscillation as osc
from .limits import Quantity
from .options import (common_options, number_options, plot_path, sample_material,
                      skeleton_options)


def _phi_column(df: pd.DataFrame) -> str | None:
    return "phi0" if "phi0" in df.columns else ("phi" if "phi" in df.columns else None)


def finish_table(sample, df: pd.DataFrame, empty_ok=(), cmd: str = "") -> tuple[pd.DataFrame,
                                                                               tuple]:
    """The table as written: mass fraction, instrument columns, normalised names (``sample`` a
    :class:`rheometer.options.Sample`, ``cmd`` the command). Returns it with the (renamed)
    columns allowed to hold empty cells."""
    out = df
    empty = list(empty_ok)
    m, mass, g = sample.material, sample.mass, sample.geometry
    col = _phi_column(out)
    if mass and col is not None:
        out = out.copy()
        out.insert(out.columns.get_loc(col) + 1, "mass_fraction",
                   out[col].map(lambda p: mass.get(float(p), np.nan)))
    if g is not None and "shear_stress_Pa" in out.columns and "shear_rate_per_s" in out.columns:
        if g.kind == "parallel-plate" and cmd == "flow-curve":
            out = _plate_columns(out, m, g)
            empty += list(geo.INSTRUMENT_COLUMNS)
        else:
            out = geo.instrument_columns(out, g)
    if m.units == "normalised":
        out = geo.normalise_columns(out, m)
        empty = [geo.normalised_name(c) for c in empty]
    out.attrs.update(df.attrs)
    return out, tuple(empty)


def _plate_columns(df: pd.DataFrame, m, g: geo.Geometry) -> pd.DataFrame:
    """Parallel-plate instrument columns of a flow curve: rows on the rising branch get the
    torque of the radial integral; rows past the fold (no steady state over the whole plate
    under rate control) are left empty."""
    out = df.assign(**dict.fromkeys(geo.INSTRUMENT_COLUMNS, np.nan))
    for ph, idx in out.groupby("phi").groups.items():
        pp = geo.parallel_plate_flow_curve(m, float(ph), g)
        tau_fold = pp["granular_shear_stress_Pa"].max()
        rows = out.loc[idx]
        on = (rows["granular_shear_stress_Pa"] <= tau_fold) & (rows["shear_rate_per_s"] > 0)
        on &= rows["shear_rate_per_s"] >= pp["rim_shear_rate_per_s"].min()
        if not on.any():
            continue
        r = rows.loc[on, "shear_rate_per_s"].to_numpy()
        M = np.exp(np.interp(np.log(r), np.log(pp["rim_shear_rate_per_s"]),
                             np.log(pp["torque_N_m"])))
        out.loc[on[on].index, list(geo.INSTRUMENT_COLUMNS)] = g.readings(r, M)
    out.attrs.update(df.attrs)
    return out


def extra_outputs(args, sample, df: pd.DataFrame, plot=None) -> str:
    """Files beside the main output (parallel-plate flow curve: the apparent curve of the radial
    integral, its Weissenberg-Rabinowitsch correction and the true one, CSV and figure); returns
    the message. Also the notes of the run (mass fraction, geometry)."""
    msg = f"\n{sample.mass_note}" if sample.mass_note else ""
    g, m = sample.geometry, sample.material
    if g is not None:
        msg += f"\ngeometry: {g.describe()}"
        if g.kind == "parallel-plate" and args.cmd != "flow-curve":
            msg += (" (the sample is taken homogeneous at the rim rate: the radial integration "
                    "is done for steady flow curves)")
        if g.kind == "parallel-plate" and args.cmd == "flow-curve":
            base = Path(args.out)
            csv = base.with_name(base.stem + "_parallel_plate.csv")
            pp = pd.concat([geo.parallel_plate_flow_curve(m, float(ph), g) for ph in sample.phi],
                           ignore_index=True)
            atomic_write_csv(csv, geo.normalise_columns(pp, m))
            msg += f"\nwrote {csv} ({len(pp)} rows: true, apparent and corrected rim stress)"
            if plot is not None:
                png = base.with_name(base.stem + "_parallel_plate.png")
                plots.save(plots.parallel_plate_figure(pp, df, f"{m.name}: {g.describe()}"), png)
                msg += f" and {png}"
    return msg


def write_record(args, ends, rows: int, **extra) -> str:
    """Write the run record ``<out>.json`` of a command (:func:`rheology.run_end.run_record`:
    its status and ``ends``, the CSV and its ``rows``, ``extra`` counts); returns its path."""
    path = Path(args.out).with_suffix(".json")
    atomic_write_json(path, run_record(ends, command=f"rheometer {args.cmd}",
                                       csv=Path(args.out).name, rows=rows, **extra))
    return str(path)


def materials_note() -> str:
    """The default-fraction rule and each material's defaults (for ``rheometer materials``)."""
    lines = [f"Defaults ({RULE}):"]
    for name in rheology.materials.material_names():
        m = rheology.get_material(name)
        phis = default_fractions(m)
        lines.append(f"  {name:15s} phi = {' '.join(f'{p:g}' for p in phis)} "
                     f"({'DST' if has_dst(m) else 'no DST'}; phi_c = {m.phi_c:g}, phi_j = "
                     f"{m.phi_j:g}{'; normalised units' if m.units == 'normalised' else ''})")
    return "\n".join(lines)


# ------------------------------------------------------------------ rheometer oscillation
#: The default strain amplitudes, 10 log-spaced over 1e-3..0.1: on the default material
#: (hermes2016, phi = 0.50, G = 1e4 Pa) at 1 Hz every point stays below the small-elastic-strain
#: limit 0.1 (taubar/G <= 1.5e-4; I3/I1 up to 2e-3). From about 0.18 the sample shear-jams in
#: each cycle and answers elastically (taubar/G 0.14 at 0.18, 0.99 at 1): the hypoelastic law
#: outside its range, flagged and drawn hollow; given explicitly, such amplitudes still run.
STRAIN_AMPLITUDES = (1e-3, 0.1, 10)


def add_subcommands(sub) -> dict:
    """Add ``oscillation`` to the ``rheometer`` subparsers; return its command function."""
    p = sub.add_parser(
        "oscillation", help="oscillatory shear: amplitude and frequency sweeps (G', G'', I3/I1, "
                            "Lissajous curves)",
        description="Imposed strain gamma0 sin(omega t) (or mixture stress sigma0 sin(omega t)) "
                    "run to the periodic steady state (cycles until the cycle-to-cycle change "
                    "of the first and third harmonics is below --tol, reported per point); per "
                    "point G', G'' of the first harmonic, |eta*|, I3/I1 and the linearised "
                    "model's G*; the last cycle of every point in <out>_waveforms.csv "
                    "(Lissajous-Bowditch curves, <out>_lissajous.png). Default: an amplitude "
                    f"sweep {_sweep_text()} at 1 Hz, within the small-elastic-strain limit "
                    f"{ELASTIC_STRAIN_LIMIT:g} at the default material (larger amplitudes "
                    "shear-jam it past the limit: flagged, drawn hollow).")
    common_options(p, 1, "oscillation")
    p.add_argument("--control", choices=("strain", "stress"), default="strain",
                   help="imposed strain (default) or imposed mixture shear stress")
    # read here, checked once by rheometer.oscillation (named by their options: _LABELS)
    p.add_argument("--strain-amplitude", type=Quantity("--strain-amplitude", limits.STRAIN,
                                                       later=True),
                   nargs="+", default=None, metavar="A",
                   help="strain amplitude(s) [-] (several: an amplitude sweep; default "
                        f"{STRAIN_AMPLITUDES[2]} values {_sweep_text()})")
    p.add_argument("--stress-amplitude", type=Quantity(
                       "--stress-amplitude", limits.POSITIVE_STRESS, later=True),
                   nargs="+", default=None, metavar="S",
                   help="mixture-stress amplitude(s) [Pa] for --control stress (default 10 "
                        "values 0.01..10 tau*)")
    p.add_argument("--frequency", type=Quantity("--frequency", limits.FREQUENCY, later=True),
                   nargs="+", default=[1.0], metavar="F",
                   help="frequency(ies) [Hz] (several: a frequency sweep; 1)")
    number_options(p, ("--cycles", limits.MAX_CYCLES, osc.DEFAULT_MAX_CYCLES,
                       f"most cycles per point ({osc.DEFAULT_MAX_CYCLES}); a point not periodic "
                       f"by then is flagged converged = False"),
                   ("--tol", limits.TOL, osc.DEFAULT_TOL, f"periodic-state tolerance on the "
                    f"cycle-to-cycle change ({osc.DEFAULT_TOL:g})"),
                   ("--samples", limits.SAMPLES, osc.DEFAULT_SAMPLES,
                    f"samples per cycle ({osc.DEFAULT_SAMPLES})"), later=True)
    p.add_argument("--start", choices=("rest", "previous"), default="rest",
                   help="each point from rest (default), or from the previous point's state")
    skeleton_options(p)
    number_options(p, ("--rtol", limits.OSCILLATION_RTOL, osc.DEFAULT_RTOL,
                       f"IDA relative tolerance ({osc.DEFAULT_RTOL:g})"), later=True)
    return {"oscillation": _cmd_oscillation}


def _sweep_text() -> str:
    lo, hi, _ = STRAIN_AMPLITUDES
    return f"{lo:g}..{hi:g}"


#: the options of rheometer.oscillation's parameters
_LABELS = {"frequency": "--frequency", "strain amplitude": "--strain-amplitude",
           "stress amplitude": "--stress-amplitude", "max_cycles": "--cycles", "tol": "--tol",
           "samples": "--samples", "rtol": "--rtol"}


def _cmd_oscillation(args) -> str:
    plot = plot_path(args)
    base = Path(args.out)
    waves_csv = base.with_name(base.stem + "_waveforms.csv")
    liss_png = base.with_name(base.stem + "_lissajous.png")
    check_output_path("--out", str(waves_csv), ["csv"])
    sample = sample_material(args)
    m = sample.material
    if args.control == "strain":
        if args.stress_amplitude is not None:
            raise ValueError("--stress-amplitude needs --control stress")
        lo, hi, n = STRAIN_AMPLITUDES
        amps = args.strain_amplitude or list(np.geomspace(lo, hi, n))
    else:
        if args.strain_amplitude is not None:
            raise ValueError("--strain-amplitude needs --control strain (the default)")
        amps = args.stress_amplitude or list(m.tau_star * np.logspace(-2, 1, 10))
    points, waves = osc.oscillation_sweep(
        m, sample.phi, frequency=args.frequency, amplitude=amps, control=args.control,
        start=args.start, G=args.G, K0=args.K0, max_cycles=args.cycles, tol=args.tol,
        samples=args.samples, rtol=args.rtol, label=lambda k: _LABELS.get(k, k))
    ends = points.attrs["ends"]
    failed = points["reason"] != ""
    if not (~failed).any():
        first = ends[0].line() if ends else points["reason"].iloc[0]
        raise RuntimeError(f"every point failed; the first: {first}")
    g = sample.geometry
    if g is not None:
        points = points.copy()
        points["torque_amplitude_N_m"] = g.torque(points["stress_amplitude_Pa"])
        points["angle_amplitude_rad"] = points["strain_amplitude"] / g.rate_factor()
        waves = geo.instrument_columns(waves, g)
    table, _ = finish_table(sample, points, cmd=args.cmd)
    wtable, _ = finish_table(sample, waves, cmd=args.cmd)
    unit = geo.normalised_name if m.units == "normalised" else (lambda c: c)
    empty = tuple(map(unit, ("elastic_stress_Pa", "viscous_stress_Pa") if args.control == "stress"
                      else ()))
    # empty where undefined: tan_delta if G' <= 0, cycle_change if fewer than two cycles
    # compared; a failed point's results (its row says why), checked finite in the others
    ok = ("tan_delta", "cycle_change", "not_periodic_why")
    check_finite(table[~failed.to_numpy()], Path(args.out).name, ok)
    empty_failed = tuple(map(unit, osc.FAILED_EMPTY)) + (
        ("torque_amplitude_N_m", "angle_amplitude_rad") if g is not None else ())
    atomic_write_csv(args.out, table, empty_ok=ok + (empty_failed if failed.any() else ()))
    atomic_write_csv(waves_csv, wtable, empty_ok=empty)
    written = [args.out, str(waves_csv)]
    msg = f"wrote {args.out} ({len(table)} points) and {waves_csv} ({len(wtable)} rows)"
    past = points[points["max_elastic_strain"] > ELASTIC_STRAIN_LIMIT]
    if plot is not None:
        try:
            dst = osc.dst_onset_stress(m, sample.phi[0]) if len(sample.phi) == 1 else None
        except ValueError:                                  # no DST at this phi
            dst = None
        what = (f"{args.control} control, G = {points.attrs['G_Pa']:g} Pa, K0 = "
                f"{points.attrs['K0']:g}")
        plots.save(plots.oscillation_figure(points, f"{m.name}: oscillation ({what})", dst), plot)
        plots.save(plots.lissajous_figure(waves, f"{m.name}: Lissajous-Bowditch curves ({what})",
                                          points=points, dst_stress=dst), liss_png)
        msg += f", {plot} and {liss_png}"
        written += [plot, str(liss_png)]
    written.append(write_record(args, ends, len(table), failed_points=int(failed.sum()),
                                past_elastic_limit_points=len(past)))
    msg += f" and {written[-1]}"
    ran = points[~failed]
    cyc = ran["cycles"].astype(int)
    msg += (f"\nperiodic steady state: cycle-to-cycle change < {args.tol:g} of |first "
            f"harmonic| (and of mean f) in {int(ran['converged'].sum())}/{len(ran)} points that "
            f"ran; cycles used {int(cyc.min())}..{int(cyc.max())} (median "
            f"{int(np.median(cyc))})")
    bad = ran[~ran["converged"].astype(bool)]
    if len(bad):
        msg += ("\nWARNING: not periodic within --cycles " f"{args.cycles}: " + ", ".join(
            f"phi {r.phi:g} {r.frequency_Hz:g} Hz amplitude {r.strain_amplitude:.3g} "
            f"({r.not_periodic_why})" for r in bad.itertuples())
                + " (column not_periodic_why)")
    if len(past):
        msg += (f"\nWARNING: {len(past)}/{len(points)} points strain the skeleton elastically "
                f"past {ELASTIC_STRAIN_LIMIT:g} (taubar/G up to "
                f"{float(past['max_elastic_strain'].max()):.3g}, column max_elastic_strain; "
                f"first at amplitude {float(past.iloc[0]['strain_amplitude']):.3g}): the "
                f"hypoelastic law is used there outside its small-strain range (the jammed "
                f"sample answers elastically; drawn hollow on the figure)")
    msg += extra_outputs(args, sample, points)
    # the failed points are in the table with their reason: status 3
    return msg, (EndedEarly(ends, partial=points, written=written) if ends else None)
