"""``rheometer read``, ``rheometer fit`` and ``rheometer fit-relaxation``: measured curves in, a
fitted Material out.

Examples::

    rheometer read export_*.csv --phi 0.38 0.41 0.44 --out curves.csv
    rheometer read table.csv --columns stress="Shear Stress" rate="Shear Rate" phi=phi
    rheometer fit rheometer/examples/rheocompass_phi_*.csv --phi 0.40 0.42 0.45 0.48 0.51 --out fit
    rheometer fit-relaxation rheometer/examples/trios_relaxation_phi_0.52.txt \\
        --material fit/material.json --phi 0.52 --stress0 100 30 --out relaxation
    rheometer flow-curve --material fit/material.json

``fit`` writes DIR/material.json (the fitted Material with the data's provenance; every
``--material`` accepts it), DIR/parameters.csv (value, interval, stage, flags), DIR/fit.csv (data,
model and residual_log10 per point), DIR/correlation.csv, DIR/curves.csv (what was read, with the
dropped points and why), and the figures DIR/fit_curves.png, DIR/residuals.png,
DIR/stage1_low_plateau.png, DIR/stage2_high_plateau.png, DIR/stage3_dst.png (Figs. 11-13).
``fit-relaxation`` writes DIR/material.json (the steady material with G and K0 added),
DIR/parameters.csv, DIR/fit.csv (every point read, model where kept) and DIR/relaxation.png.

A fit whose result is unphysical (:func:`rheology.fit.assess`, a search bound reached, the
evaluation limit hit) exits with status 1 and one paragraph naming the parameters, why and what
to do; its outputs are written, the material as DIR/material_rejected.json instead of
material.json, unless ``--accept``. The --out folder holds only the run's files: the files of a
previous fit there are replaced or removed, a folder holding any other file is refused.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
from pathlib import Path

from runkit.plotting import plt
import numpy as np
import pandas as pd

import rheology
from rheology.data import (EMPTY_OK, READERS, describe, detect_format, drop_counts,
                           read_flow_curves, read_relaxation_curves, read_text,
                           table_to_csv_frame)
from rheology.fit import (PARAMETER_EMPTY_OK, FlowData, fit_flow_curves, mixture_steady_state,
                          parameter_table, plateau_viscosity)
from rheology.materials import (FIELD_UNITS, MATERIAL_FILE_FORMAT, check_set_override,
                                material_to_dict, set_overrides, split_set_item)
from rheology.steady import gdot_dst
from rheology.sample import BETA, DENSITY, LAMBDA, PORE, RHO_WATER, SWELLING
from runkit.io import (atomic_write_csv, atomic_write_json, check_finite,
                       check_output_dir, check_output_path, strict_json)
from runkit import limits as physical
from runkit.limits import ge, gt, le, lt
from runkit.params import Param
from runkit.run import HeldWarnings

from . import limits, plots
from .limits import Quantity
from .options import PHI, SET_PHI_J, about_set, once as _once
from .relaxation_fit import SCALE, RelaxationCurve, fit_relaxation
from .transient import check_phi

#: a torque floor [mN m]: between the finest resolution and the largest torque of a rheometer
TORQUE_FLOOR = Param(ge(1e-8, "the finest torque resolution of rotational rheometers (~0.05 nN m "
                              "= 5e-8 mN m): a lower floor drops nothing the instrument read"),
                     le(1e3, "1 N m, above the largest torque of rotational rheometers (~0.2-0.3 "
                             "N m): every reading would be dropped"), unit="mN m")
#: a cessation time on a curve's clock [s]: within the longest duration either side of 0
TIME_OFFSET = Param(ge(-physical.TIME_MAX.value, physical.TIME_MAX.why), physical.TIME_MAX,
                    unit="s")
CONFIDENCE = Param(gt(0.5, "an interval that holds the value less often than not is no "
                           "confidence interval"),
                   lt(1.0, "a 100% interval is unbounded"))
ETAB_TERMS = Param(ge(1, "Eq. (34) has one or two terms"), le(2, "Eq. (34) has one or two terms"),
                   kind="integer")
F_SCALE = Param(ge(1e-6, "a millionth of a decade: below the scatter of any measured viscosity "
                         "(every point an outlier)"),
                le(10.0, "ten decades, wider than any flow curve (no point an outlier)"),
                unit="decades")
#: What steady flow curves cannot determine (copied by --transient-from).
TRANSIENT_FIELDS = ("G", "K", "K0", "rho_s", "rho_f", "d", "K3", "kappa", "phi0")

#: Every file the fit commands write in their --out folder (with their temporary ``.NAME.*``).
OUTPUTS = ("material.json", "material_rejected.json", "parameters.csv", "fit.csv",
           "correlation.csv", "curves.csv", "fit_curves.png", "residuals.png",
           "stage1_low_plateau.png", "stage2_high_plateau.png", "stage3_dst.png",
           "relaxation.png")


def _columns(text: str):
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"--columns expects QUANTITY=NAME, got {text!r}")
    k, v = (s.strip() for s in text.split("=", 1))
    if not k or not v:
        raise argparse.ArgumentTypeError(f"--columns {text!r}: empty quantity or column name; "
                                         "expects QUANTITY=NAME")
    return k.lower(), v


def _text(option: str):
    """argparse ``type`` of a text option: refuses an empty or blank value."""

    def check(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"{option} = {text!r} is empty; valid: a "
                                             "non-empty value")
        return text.strip()

    check.__name__ = "text"
    return check


def _set_value(text: str):
    """``NAME=VALUE`` of ``fit --set`` (the value checked in cmd_fit)."""
    try:
        return split_set_item(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _file_options(p, *, relaxation: bool = False):
    p.add_argument("files", nargs="+", metavar="FILE",
                   help="rheometer exports (RheoCompass, TRIOS text or CSV, rSpace CSV) or tables")
    p.add_argument("--format", default="auto", choices=("auto", *READERS),
                   help="file layout (default: detected from the content)")
    p.add_argument("--columns", nargs="+", type=_columns, default=None, metavar="QUANTITY=NAME",
                   help="column names of a table: " + (
                       "time=NAME stress=NAME (or torque=NAME) [s, Pa, mN m]" if relaxation else
                       "stress=NAME rate=NAME viscosity=NAME phi=NAME (any two of stress [Pa], "
                       "rate [1/s], viscosity [Pa s])") + "; a unit in brackets is converted")
    p.add_argument("--interval", action="append", type=_text("--interval"), default=None,
                   metavar="NAME",
                   help="names of the intervals, steps or actions to read (substring, "
                        "repeatable; default: every " + ("stress relaxation" if relaxation else
                                                         "flow-curve") + " block)")
    p.add_argument("--torque-floor", type=Quantity("--torque-floor", TORQUE_FLOOR), default=None,
                   metavar="MNM",
                   help="drop readings with |torque| below this [mN m] (instrument-flagged "
                        "ME- readings are always dropped)")


def _read_options(p):
    _file_options(p)
    p.add_argument("--phi", nargs="+", type=PHI, default=None, metavar="PHI",
                   help="volume fraction of each file, in order (files without a phi column)")
    p.add_argument("--mass-fraction", action="store_true",
                   help="the phi values are mass fractions: convert with Eq. (20) (needs "
                        "--rho-cs and --rho-l)")
    # Eq. (20)'s inputs with rheology.sample's physical limits and defaults (its --grain-density,
    # --liquid-density, ... under the names the fit commands have always had)
    for name, text, default, kind in (
            ("--rho-cs", "grain density [kg/m^3]", None, DENSITY),
            ("--rho-l", "suspending-liquid density [kg/m^3]", None, DENSITY),
            ("--rho-w", f"water density [kg/m^3] ({RHO_WATER:g})", RHO_WATER, DENSITY),
            ("--swelling", f"lambda ({LAMBDA:g})", LAMBDA, SWELLING),
            ("--pore", f"beta ({BETA:g})", BETA, PORE)):
        p.add_argument(name, type=Quantity(name, kind), default=default,
                       help=f"{text} of Eq. (20)")


def _result_options(p, what: str):
    p.add_argument("--out", default=what, metavar="DIR", help=f"output folder (default {what}); "
                   "a previous fit's files there are replaced, other files refuse it")
    p.add_argument("--confidence", type=Quantity("--confidence", CONFIDENCE), default=0.95,
                   help="confidence level of the intervals (0.95)")
    p.add_argument("--accept", action="store_true",
                   help="write material.json even when the result is unphysical (a parameter at "
                        "a search bound, ...; without it such a fit exits 1 and writes "
                        "material_rejected.json)")
    p.add_argument("--transient-from", type=_text("--transient-from"), default=None,
                   metavar="NAME|FILE.json",
                   help="copy the parameters the data cannot give (" + (
                       "rho_s, rho_f, d, K3, kappa, phi0" if what == "relaxation" else
                       "G, K, K0, rho_s, rho_f, d, K3, kappa, phi0") + ") from this set into the "
                       "fitted material, so that shear1d and mpm2d scenes take it as it is "
                       "(e.g. annular_shear)")
    p.add_argument("--name", default=None, help="name of the fitted material (default: the "
                                                "--out folder's name)")
    p.add_argument("--no-plots", action="store_true", help="no PNG figures")


def add_subcommands(sub) -> dict:
    """Add ``read``, ``fit`` and ``fit-relaxation`` to the ``rheometer`` subparsers; return their
    command functions."""
    p = sub.add_parser("read", help="read rheometer exports into one tidy CSV (no fitting)",
                       description="Read measured flow curves (RheoCompass, TRIOS text or CSV and "
                                   "rSpace CSV exports, CSV/TSV tables) into one tidy CSV: "
                                   "source_file, interval, phi, point, time_s, shear_rate_per_s, "
                                   "shear_stress_Pa, viscosity_Pa_s, kept, dropped_reason. "
                                   "Blocks that are not flow curves are listed with the reason.")
    _read_options(p)
    p.add_argument("--out", default="curves.csv", metavar="FILE.csv",
                   help="output CSV (default curves.csv)")

    p = sub.add_parser("fit", help="fit the model to measured flow curves (Supplement, Figs. "
                                   "11-13, then a global fit)",
                       description="Fit Baumgarten & Kamrin's model to measured steady flow "
                                   "curves: stages 1-3 of the Supplement (Figs. 11-13: low "
                                   "plateau -> a0, phi_j and eta0; high plateau -> a_inf, phi_c; "
                                   "DST rates -> eta_B), then all parameters at once (robust, log "
                                   "viscosity). Writes DIR/material.json (accepted by every "
                                   "--material), parameters.csv, fit.csv, correlation.csv, "
                                   "curves.csv and PNG figures.")
    _read_options(p)
    _result_options(p, "fit")
    p.add_argument("--material", default="hermes2016", metavar="NAME|FILE.json",
                   help="starting point and held parameters (default hermes2016; its eta0 is not "
                        "used: eta0 is estimated from the curves unless --set eta0=VALUE)")
    p.add_argument("--set", action="append", type=_set_value, default=None,
                   metavar="NAME=VALUE", help="fix a parameter at a value (repeatable), e.g. "
                                              "eta0=1.2 (the liquid's measured viscosity, Pa s)")
    p.add_argument("--free", nargs="+", default=None, metavar="NAME",
                   help="also fit parameters normally held: mu_c, Delta, varphi2, alpha2")
    p.add_argument("--etaB-terms", type=Quantity("--etaB-terms", ETAB_TERMS), default=None,
                   help="terms of Eq. (34) (default: as many as --material has)")
    p.add_argument("--f-scale", type=Quantity("--f-scale", F_SCALE),
                   default=None, help="robust-loss scale in log10 viscosity, in [1e-6, 10] "
                                      "decades (default: 3 robust standard deviations of a first "
                                      "pass)")
    p.add_argument("--no-profile", action="store_true",
                   help="skip the profile-likelihood intervals of phi_j and phi_c")


    p = sub.add_parser(
        "fit-relaxation", help="fit G and K0 to stress relaxation after cessation of steady "
                               "shear (Supplement, Eqs. 35-37)",
        description="Fit the granular shear modulus G and the structure-rate scale K0 (and each "
                    "curve's cessation time on its clock) to measured stress relaxations after "
                    "steady shear at --stress0, the steady parameters held at --material (a "
                    "steady fit): least squares on log stress against rheometer relax's model. "
                    "Several curves (several --stress0 or --phi) are fitted jointly with one G "
                    "and K0. Writes DIR/material.json (--material with G and K0), "
                    "parameters.csv, fit.csv and relaxation.png.")
    _file_options(p, relaxation=True)
    _result_options(p, "relaxation")
    p.add_argument("--material", required=True, metavar="NAME|FILE.json",
                   help="the steady fit (e.g. fit/material.json from rheometer fit)")
    p.add_argument("--phi", nargs="+", type=PHI, required=True, metavar="PHI",
                   help="volume fraction: one for every curve, or one per curve in order")
    p.add_argument("--stress0", nargs="+", required=True, metavar="TAU0",
                   type=Quantity("--stress0", limits.POSITIVE_STRESS),
                   help="steady granular shear stress before cessation [Pa] (the measured "
                        "stress less eta0 (1 + 5/2 phi) gdot, negligible when dense): one for "
                        "every curve, or one per curve in order")
    p.add_argument("--K0", type=Quantity("--K0", limits.K0), default=None,
                   help="hold K0 at this value (fit G only)")
    p.add_argument("--time-offset", type=Quantity("--time-offset", TIME_OFFSET),
                   default=None, metavar="SECONDS",
                   help="hold each curve's cessation time at this time on its clock (default: "
                        "fitted per curve)")
    p.add_argument("--stress-floor", type=Quantity("--stress-floor", limits.POSITIVE_STRESS),
                   default=None, metavar="PA",
                   help="drop readings below this stress [Pa] (the instrument's noise)")
    return {"read": cmd_read, "fit": cmd_fit, "fit-relaxation": cmd_fit_relaxation}


# ------------------------------------------------------------------ files and folders
def check_files(args) -> None:
    """Refuse, before anything is read or written, a data file given twice (the same resolved
    path: it would be merged into the fit as two curves) and an option that would be ignored for
    the files given: ``--columns`` maps the columns of CSV/TSV tables, an instrument export's
    columns are fixed by the export; ``--interval`` selects an export's named intervals, steps
    or actions, tables have none. One line naming the file(s) and the option."""
    _once("--columns", [k for k, _ in args.columns or []])       # a quantity mapped twice
    _once("--interval", args.interval)
    seen: dict = {}
    for f in args.files:
        key = Path(f).resolve()
        if key in seen:
            both = "" if seen[key] == f else f" (as {seen[key]!r} and {f!r})"
            raise ValueError(f"data file {f!r} is given twice{both}: it would be read as two "
                             "curves; give each file once")
        seen[key] = f
    if not (args.columns or args.interval):
        return
    kinds = {}
    for f in args.files:
        if not Path(f).is_file():
            return                           # the reader names the missing file
        kinds[f] = args.format if args.format != "auto" else detect_format(read_text(f), f)
    export = [f for f, k in kinds.items() if k != "csv"]
    if args.columns and export:
        raise ValueError(f"--columns applies to CSV/TSV tables only: data file {export[0]!r} is a "
                         f"{kinds[export[0]]} export, whose columns are fixed by the export "
                         "(read by name); remove --columns or give tables only")
    if args.interval and not export:
        raise ValueError("--interval selects an export's intervals, steps or actions by name: "
                         "none of the data files is an instrument export (a table's curves are "
                         "split by its phi or interval column); remove --interval")


def prepare_out(option: str, path) -> Path:
    """The --out folder, checked before any work: writable, and holding no file but a previous
    fit's (:data:`OUTPUTS` and their temporaries), which this run replaces or removes. ValueError
    naming the foreign files otherwise."""
    out = check_output_dir(option, path)
    if out.is_dir():
        other = sorted(p.name for p in out.iterdir() if not _ours(p.name))
        if other:
            shown = ", ".join(other[:4]) + (f" and {len(other) - 4} more" if len(other) > 4 else "")
            raise ValueError(f"{option} = {str(path)!r} holds files no fit writes ({shown}): the "
                             "folder must hold only this run's files; give a new or empty folder")
    return out


def _ours(name: str) -> bool:
    return name in OUTPUTS or any(name.startswith(f".{o}.") for o in OUTPUTS)


def remove_stale(out: Path, written) -> None:
    """Remove the previous fits' files this run did not write (and stale temporaries)."""
    for p in out.iterdir():
        if _ours(p.name) and p.name not in written:
            p.unlink()


def _read(args):
    check_files(args)
    mass = None
    if args.mass_fraction:
        if args.rho_cs is None or args.rho_l is None:
            raise ValueError("--mass-fraction needs --rho-cs and --rho-l (Eq. 20); the paper "
                             "gives no default densities")
        mass = dict(rho_cs=args.rho_cs, rho_l=args.rho_l, rho_w=args.rho_w, lam=args.swelling,
                    beta=args.pore)          # rheology.data's keys of Eq. (20)
    cols = dict(args.columns) if args.columns else None
    return read_flow_curves(args.files, fmt=args.format, columns=cols, phi=args.phi,
                            intervals=args.interval, torque_floor=args.torque_floor,
                            mass_fraction=mass, require_phi=args.cmd == "fit")


def cmd_read(args) -> str:
    """``rheometer read``: write the tidy table; print the drop counts and skipped blocks."""
    check_output_path("--out", args.out, ["csv"])
    table = _read(args)
    atomic_write_csv(args.out, table_to_csv_frame(table), empty_ok=EMPTY_OK)
    return f"{describe(table)}\nwrote {args.out} ({len(table)} rows)"


def _out_and_name(args) -> tuple[Path, str]:
    """The --out folder (:func:`prepare_out`) and the fitted material's name (--name, else the
    folder's name); ValueError for an empty --name."""
    out = prepare_out("--out", args.out)
    if args.name is not None and not args.name.strip():
        raise ValueError(f"--name = {args.name!r} is empty; valid: a non-empty name (default: "
                         "the --out folder's name)")
    return out, (args.name.strip() if args.name is not None else out.resolve().name)


def _provenance(command: str, args, table, donor, **fields) -> dict:
    """The provenance of a fit: when, the command, the files read (sha256, format), the blocks
    skipped, the material of --transient-from, and ``fields``."""
    formats = table.attrs.get("formats", {})
    created = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    return {"created": created, "command": command,
            "transient_from": donor.name if donor else None,
            "files": [{"file": str(f), "sha256": hashlib.sha256(Path(f).read_bytes()).hexdigest(),
                       "format": formats.get(str(Path(f)), "?")} for f in args.files],
            "skipped_blocks": [list(x) for x in table.attrs.get("skipped", [])], **fields}


def _fit_doc(provenance: dict, res, accept: bool) -> dict:
    """What material.json holds besides the material: provenance and the fit's verdict."""
    names, corr = res.correlation
    return {"provenance": provenance,
            "fit": {"confidence": res.confidence, "converged": res.converged,
                    "problems": res.problems, "accepted": not res.problems or accept,
                    "parameters": _params_json(res.parameters),
                    "correlation": {"names": names, "matrix": corr}}}


def _params_json(params) -> dict:
    return {p.name: {("interval" if k == "method" else k): getattr(p, k) for k in (
        "value", "lower", "upper", "std_error", "method", "stage", "status", "at_bound",
        "unidentifiable", "converged", "note")} for p in params}


def _summary(params) -> list[str]:
    def g(x):
        return "null" if not np.isfinite(x) else f"{x:.5g}"

    return [f"  {p.name:9s} = {p.value:<11.5g} [{g(p.lower)}, {g(p.upper)}] ({p.method}, "
            f"stage {p.stage}{', ' + p.status if p.status != 'fitted' else ''})"
            for p in params if p.status != "fixed"]


def _write_results(out: Path, tables: dict, material, doc: dict, problems, accept: bool,
                   figures) -> list[str]:
    """Check every output, write them, the material as material.json (or material_rejected.json
    for an unphysical result without --accept), remove a previous fit's other files. Returns the
    names written."""
    nullable = ("lower", "upper", "std_error")
    for name, (frame, empty) in tables.items():
        check_finite(frame, name, empty)
    strict_json({"material": material_to_dict(material), **doc}, "material.json", nullable)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, (frame, empty) in tables.items():
        atomic_write_csv(out / name, frame, empty_ok=empty)
        written.append(name)
    mat = "material.json" if (accept or not problems) else "material_rejected.json"
    atomic_write_json(out / mat, {"format": MATERIAL_FILE_FORMAT, "version": 1,
                                  "material": material_to_dict(material), **doc},
                      nullable=nullable)
    written.append(mat)
    written += figures()
    remove_stale(out, written)
    return written


def _verdict(problems, out: Path, accept: bool) -> str:
    """The paragraph of an unphysical result (empty when there is none)."""
    if not problems:
        return ""
    what = "; ".join(f"({i + 1}) {p}" for i, p in enumerate(problems))
    if accept:
        return f"WARNING: the result is unphysical (--accept: material.json written): {what}"
    return (f"the result is unphysical: {what}. Its outputs are in {out}, the material as "
            "material_rejected.json (not material.json); act on the above and fit again, or "
            "rerun with --accept to write material.json as it is")


# ------------------------------------------------------------------ rheometer fit
def cmd_fit(args) -> str:
    """``rheometer fit``: read, fit, write DIR/material.json, CSVs and figures."""
    out, name = _out_and_name(args)
    start = rheology.get_material(args.material)
    pairs = []
    for k, v in args.set or []:
        if v is None:
            raise ValueError(f"--set {k} = none: fit --set holds a parameter at a number")
        pairs.append(check_set_override(k, v))    # not ``name``: the fitted material's
    fixed = set_overrides(pairs)
    try:                                     # refused as the parameter set, with its range
        given = start.replace(**fixed)
    except ValueError as exc:
        raise about_set(start, fixed, exc, "--set", FIELD_UNITS) from None
    _once("--free", args.free)
    if "eta0" in (args.free or []):
        raise ValueError("--free eta0: eta0 is estimated from the curves by default; hold it "
                         "with --set eta0=VALUE instead")
    donor = rheology.get_material(args.transient_from) if args.transient_from else None
    # a held phi_j (--set) bounds every measured fraction: no steady flow at or above it; a free
    # phi_j is fitted above the data (the material's bound phi_j < 1 then bounds them)
    held_phi_j = "phi_j" in fixed
    if held_phi_j and args.phi is not None and not args.mass_fraction:
        for p in args.phi:
            check_phi("--phi", p, given, source=SET_PHI_J)
    table = _read(args)
    data = FlowData.from_table(table)
    for label, p in zip(data.labels, data.curve_phi()) if held_phi_j else ():   # phi column, Eq. 20
        check_phi("phi", p, given, where=f"{label}: ", source=SET_PHI_J)
    print(describe(table))
    # numpy's warnings of the fit (a singular covariance at an extreme held value) are held: a
    # failed fit cites the first in its one line, a finished one lists them as notes
    with HeldWarnings() as held:
        try:
            res = fit_flow_curves(
                data, start, fixed=fixed, free=args.free, etaB_terms=args.etaB_terms,
                confidence=args.confidence, profile=not args.no_profile, f_scale=args.f_scale,
                name=name, citation=f"fitted by 'rheometer fit' to {data.n_curves} flow curves "
                                    f"({', '.join(sorted(set(table['source_file'])))}) "
                                    f"starting from {start.name}")
        except (RuntimeError, ArithmeticError, ValueError) as exc:
            if not held.after():
                raise
            raise type(exc)(f"{exc} ({held.after().strip()})") from None
    numpy_notes = sorted({f"numpy: {w.message}" for w in held.held
                          if issubclass(w.category, RuntimeWarning)})
    m = res.material
    if args.transient_from:
        m = m.replace(**{k: getattr(donor, k) for k in TRANSIENT_FIELDS})
    kept = table[table["kept"]].reset_index(drop=True)
    fit_df = kept[["source_file", "interval", "phi", "point", "shear_stress_Pa",
                   "shear_rate_per_s", "viscosity_Pa_s"]].assign(
        model_shear_rate_per_s=res.model_rate, model_viscosity_Pa_s=res.model_viscosity,
        residual_log10=res.residual_log10, outlier=res.outlier)
    names, corr = res.correlation
    corr_df = pd.DataFrame(corr, columns=names)
    corr_df.insert(0, "parameter", names)
    provenance = _provenance(
        "rheometer fit", args, table, donor, start_material=start.name, fixed=fixed,
        freed=args.free or [],
        eta0="given (--set)" if "eta0" in fixed else "estimated from the curves",
        curves=[{"label": lab, "phi": float(p), "points_kept": int(np.sum(data.curve == c))}
                for c, (lab, p) in enumerate(zip(data.labels, data.curve_phi()))],
        points_kept=int(len(kept)), points_dropped=int((~table["kept"]).sum()),
        dropped_by_reason=drop_counts(table), outliers=int(res.outlier.sum()),
        sigma_log10=res.sigma_log10, model_evaluations=res.n_evaluations,
        fit_seconds=res.seconds, messages=res.messages)
    doc = _fit_doc(provenance, res, args.accept)
    tables = {"curves.csv": (table_to_csv_frame(table), EMPTY_OK), "fit.csv": (fit_df, ()),
              "parameters.csv": (res.table(), PARAMETER_EMPTY_OK),
              "correlation.csv": (corr_df, ())}
    try:
        written = _write_results(out, tables, m, doc, res.problems, args.accept,
                                 lambda: [] if args.no_plots else write_figures(out, data, res))
    except RuntimeError as exc:
        text = str(exc).replace("was not written", "and every other output were not written")
        cause = f" (numpy during the fit: {numpy_notes[0][7:]})" if numpy_notes else ""
        raise RuntimeError(f"{text}{cause}") from None
    lines = [f"fitted {m.name} in {res.seconds:.2f} s ({res.n_evaluations} model evaluations; "
             f"residual sd {res.sigma_log10:.3g} in log10 viscosity; {int(res.outlier.sum())} "
             f"outlier(s); {'converged' if res.converged else 'NOT converged'})"]
    return _finish_message(lines, res, numpy_notes, out, written, args.accept)


def _finish_message(lines, res, notes, out, written, accept) -> str:
    """The fit's message: ``lines``, the parameters, the notes, the files written and the
    verdict; an unphysical result without --accept prints it and raises the verdict."""
    lines = [*lines, *_summary(res.parameters),
             *(f"  note: {msg}" for msg in [*res.messages, *notes]),
             f"wrote {', '.join(str(out / w) for w in written)}"]
    problems = res.problems
    verdict = _verdict(problems, out, accept)
    if problems and not accept:
        print("\n".join(lines))
        raise RuntimeError(verdict)
    return "\n".join(lines + ([verdict] if verdict else []))


# ------------------------------------------------------------------ figures
def _legend(ax, **kw):
    """A legend beside the axes (never over the data)."""
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **kw)


def _figure(*shape, figsize=(12, 4.2), **kw):
    return plt.subplots(*shape, figsize=figsize, constrained_layout=True, **kw)


def write_figures(out: Path, data, res) -> list[str]:
    """The fit's figures (data vs model per phi, residuals, stages 1-3 as Figs. 11-13). The
    stage figures show each stage's own values and, dashed, the final (stage 4) ones."""
    m, phis = res.material, data.curve_phi()
    colours = plt.cm.viridis(np.linspace(0, 0.9, data.n_curves))
    curves = [(c, *data.sorted_curve(c), colours[c], f"phi = {phis[c]:.4g}")
              for c in range(data.n_curves)]
    names = []

    def save(fig, name):
        names.append(Path(plots.save(fig, out / name)).name)

    fig, ax = _figure(1, 2)
    for c, s, v, r, col, lab in curves:
        sel = (data.curve == c) & res.outlier
        ax[0].loglog(s, v, "o", ms=3.5, color=col, label=lab)
        ax[0].loglog(data.stress[sel], data.viscosity[sel], "x", color="r", ms=7)
        ax[1].loglog(r, s, "o", ms=3.5, color=col, label=lab)
        if phis[c] < m.phi_j:
            grid = np.logspace(np.log10(s.min()), np.log10(s.max()), 200)
            st = mixture_steady_state(grid, phis[c], m)
            near = st["viscosity"] < 1e3 * v.max()      # not the ~1e300 of a jammed state
            ax[0].loglog(grid[near], st["viscosity"][near], "-", color=col)
            ax[1].loglog(st["shear_rate"][near], grid[near], "-", color=col)
    ax[0].set(xlabel="shear stress [Pa]", ylabel="viscosity [Pa s]",
              title="data (markers) and fitted model (lines); x: outliers")
    ax[1].set(xlabel="shear rate [1/s]", ylabel="shear stress [Pa]", title=m.name)
    _legend(ax[1])
    save(fig, "fit_curves.png")

    fig, ax = _figure(figsize=(7, 3.8))
    for c, *_, col, lab in curves:
        sel = data.curve == c
        ax.semilogx(data.stress[sel], res.residual_log10[sel], "o-", ms=3, color=col, label=lab)
    for k, style in ((0, dict(lw=0.8)), (-2, dict(ls=":", lw=0.8)), (2, dict(ls=":", lw=0.8))):
        ax.axhline(k * res.sigma_log10, color="k", **style)
    ax.set(xlabel="shear stress [Pa]", ylabel="log10(measured / model viscosity)",
           title=f"residuals (sd {res.sigma_log10:.3g}; dotted: +-2 sd)")
    _legend(ax)
    save(fig, "residuals.png")

    st1, st2, st3 = res.stages["1"], res.stages["2"], res.stages["3"]
    eta0 = st1["eta0"]

    for stage, st, key, where, sym, fin, title in (
            ("1", st1, "eta_min", "minimum", ("phi_j", "a0", "24"), (m.phi_j, m.a0),
             "Stage 1 (Fig. 11, Eq. 24): low-stress plateau -> a0, phi_j"),
            ("2", st2, "eta_max", "maximum", ("phi_c", "a_inf", "25"), (m.phi_c, m.a_inf),
             "Stage 2 (Fig. 12, Eq. 25): high-stress plateau -> a_inf, phi_c")):
        fig, ax = _figure(1, 2)
        for c, s, v, r, col, lab in curves:
            ax[0].loglog(s, v / eta0, "-", color=col, lw=1, label=lab)
        ys = np.asarray(st[key]) / eta0
        ax[0].loglog(st["stress_" + key[4:]], ys, "ko", ms=6)
        ax[0].set(xlabel="shear stress [Pa]", ylabel=f"eta / eta0 (eta0 = {eta0:.4g} Pa s, "
                  "stage 1)", title=f"curves; black: {where} viscosity")
        _legend(ax[0])
        ph, pm, a = np.asarray(st["phi"]), st[sym[0]], st[sym[1]]
        if ph.size:
            ax[1].semilogy(ph, ys, "o", color="C0", label="plateaus")
            grid = np.linspace(min(ph.min(), 0.9 * pm) * 0.98, pm - 1e-3 * pm, 200)
            grid = grid[grid > 0]
            ax[1].semilogy(grid, plateau_viscosity(grid, pm, a, m.mu_c), "r-",
                           label=f"Eq. ({sym[2]}), stage {stage}: {sym[0]} = {pm:.4g}, "
                                 f"{sym[1]} = {a:.4g}")
            ax[1].axvline(pm, color="r", ls="--", lw=0.8)
            g2 = grid[grid < fin[0] * (1 - 1e-3)]
            ax[1].semilogy(g2, plateau_viscosity(g2, *fin, m.mu_c) * m.eta0 / eta0, "k--",
                           label=f"final (stage 4): {sym[0]} = {fin[0]:.4g}, {sym[1]} = "
                                 f"{fin[1]:.4g}" + (f", eta0 = {m.eta0:.4g}" if stage == "1"
                                                    else ""))
            _legend(ax[1])
        else:
            ax[1].text(0.5, 0.5, "no curve with a high-stress plateau", ha="center",
                       transform=ax[1].transAxes)
        ax[1].set(xlabel="phi", ylabel="eta_r", title=title)
        save(fig, f"stage{stage}_{'low' if stage == '1' else 'high'}_plateau.png")

    fig, ax = _figure(1, 2)
    for c, s, v, r, col, lab in curves:
        ax[0].loglog(r, s, "-", color=col, lw=1, label=lab)
    for g, (lo, hi) in zip(st3["gdot_dst"], st3["stress_range"]):
        ax[0].loglog([g, g], [lo, hi], "ko-", ms=5)
    ax[0].set(xlabel="shear rate [1/s]", ylabel="shear stress [Pa]",
              title="curves; black: DST region and rate")
    _legend(ax[0])
    if len(st3["phi"]) and min(m.phi_star, m.phi_j) - 1e-4 * m.phi_j > m.phi_c:
        ax[1].semilogy(st3["phi"], st3["gdot_dst"], "o", label="DST rates (stage 3)")
        for mm, style, what in ((st3["material"], "r-", "stage 3"), (m, "k--", "final")):
            hi = min(mm.phi_star, mm.phi_j) - 1e-4 * mm.phi_j
            if hi > mm.phi_c:
                grid = np.linspace(max(mm.phi_c, min(st3["phi"]) - 0.02), hi, 200)
                ax[1].semilogy(grid, gdot_dst(grid, mm), style,
                               label=f"Eq. (33), {what}: varphi1 = {mm.varphi1:.3g}, alpha1 = "
                                     f"{mm.alpha1:.3g}, tau* = {mm.tau_star:.3g}")
        ax[1].axvline(m.phi_j, color="k", ls=":", label=f"phi_j = {m.phi_j:.4g} (final)")
        _legend(ax[1])
    else:
        ax[1].text(0.5, 0.5, "no DST curve", ha="center", transform=ax[1].transAxes)
    ax[1].set(xlabel="phi", ylabel="gdot_DST [1/s]",
              title="Stage 3 (Fig. 13, Eq. 33): DST rates -> eta_B(phi)")
    save(fig, "stage3_dst.png")
    return names


# ------------------------------------------------------------------ rheometer fit-relaxation
def _per_curve(option: str, values, n: int) -> list[float]:
    if len(values) == 1:
        return list(values) * n
    if len(values) != n:
        raise ValueError(f"{option} has {len(values)} values for {n} relaxation curve(s): give one "
                         "for every curve, or one per curve in order")
    return list(values)


def cmd_fit_relaxation(args) -> str:
    """``rheometer fit-relaxation``: read relaxations, fit G and K0, write DIR/material.json,
    parameters.csv, fit.csv and relaxation.png."""
    out, name = _out_and_name(args)
    m = rheology.get_material(args.material)
    donor = rheology.get_material(args.transient_from) if args.transient_from else None
    check_files(args)
    table = read_relaxation_curves(args.files, fmt=args.format,
                                   columns=dict(args.columns) if args.columns else None,
                                   intervals=args.interval, torque_floor=args.torque_floor,
                                   stress_floor=args.stress_floor)
    print(describe(table))
    n = int(table["curve"].max()) + 1
    phis = _per_curve("--phi", args.phi, n)
    tau0 = _per_curve("--stress0", args.stress0, n)
    curves = []
    several = table["source_file"].nunique() > 1
    for i, (c, d) in enumerate(table[table["kept"]].groupby("curve", sort=True)):
        label = (f"{d['source_file'].iloc[0]} " if several else "") + str(d["interval"].iloc[0])
        curves.append(RelaxationCurve(label, d["time_s"].to_numpy(float),
                                      d["shear_stress_Pa"].to_numpy(float), phis[i], tau0[i]))
    res = fit_relaxation(curves, m, K0=args.K0, t0=args.time_offset,
                         confidence=args.confidence, name=name)
    fitted = res.material
    if donor is not None:
        fitted = fitted.replace(**{k: getattr(donor, k) for k in TRANSIENT_FIELDS
                                   if k not in ("G", "K", "K0")})
    fit_df = table.reset_index(drop=True)
    fit_df.insert(3, "phi", [phis[int(k)] for k in fit_df["curve"]])
    fit_df.insert(4, "stress0_Pa", [tau0[int(k)] for k in fit_df["curve"]])
    extra = ("time_after_cessation_s", "model_shear_stress_Pa", "residual_log10")
    for col in extra:
        fit_df[col] = np.nan
    for i, c in enumerate(curves):             # kept rows of curve i, in the order read
        rows = fit_df.index[(fit_df["curve"] == i) & fit_df["kept"]]
        fit_df.loc[rows, list(extra)] = np.column_stack(
            [c.time - res.t0[i], res.model_stress[i], res.residual_log10[i]])
    cols = ["point", "time_s", "shear_stress_Pa"]
    fit_df[cols] = fit_df[cols].astype(float).replace([np.inf, -np.inf], np.nan)
    provenance = _provenance(
        "rheometer fit-relaxation", args, table, donor, steady_material=m.name,
        curves=[{"label": c.label, "phi": c.phi, "stress0_Pa": c.stress0,
                 "points_kept": int(c.time.size), "t0_s": float(res.t0[i]),
                 "delta_f": float(res.delta_f[i])} for i, c in enumerate(curves)],
        K=f"K = {fitted.K:.6g} Pa keeps K/G of " + (m.name if m.K is not None and m.G else
                                                     "the paper's Tables 4-7"),
        sigma_log10=res.sigma_log10, model_runs=res.n_runs, fit_seconds=res.seconds,
        messages=res.messages)
    doc = _fit_doc(provenance, res, args.accept)
    units = {**FIELD_UNITS, **{p.name: "s" for p in res.parameters if p.name.startswith("t0")}}
    tables = {"fit.csv": (fit_df, (*EMPTY_OK, *extra)),
              "parameters.csv": (parameter_table(res.parameters, SCALE, units),
                                 PARAMETER_EMPTY_OK)}
    written = _write_results(out, tables, fitted, doc, res.problems, args.accept,
                             lambda: [] if args.no_plots else [relaxation_figure(out, res)])
    lines = [f"fitted G and K0 of {fitted.name} to {len(curves)} relaxation curve(s) in "
             f"{res.seconds:.2f} s ({res.n_runs} model runs; residual sd {res.sigma_log10:.3g} "
             f"in log10 stress; {'converged' if res.converged else 'NOT converged'})"]
    return _finish_message(lines, res, [], out, written, args.accept)


def relaxation_figure(out: Path, res) -> str:
    """relaxation.png: data and model against the time after cessation (log-log), residuals."""
    fig, ax = _figure(2, 1, figsize=(10, 6.5), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    colours = plt.cm.viridis(np.linspace(0, 0.85, len(res.curves)))
    for i, (c, col) in enumerate(zip(res.curves, colours)):
        t = c.time - res.t0[i]
        pos = t > 0
        o = np.argsort(t[pos])
        ax[0].loglog(t[pos], c.stress[pos], "o", ms=3, color=col,
                     label=f"{c.label}: taubar0 = {c.stress0:g} Pa, phi = {c.phi:g}")
        ax[0].loglog(t[pos][o], res.model_stress[i][pos][o], "-", color=col, lw=1.5)
        ax[1].semilogx(t[pos], res.residual_log10[i][pos], "o", ms=3, color=col)
    G, K0 = res.parameter("G").value, res.parameter("K0").value
    ax[0].set(ylabel="shear stress [Pa]",
              title=f"relaxation after cessation: data (markers), model (lines): G = {G:.4g} Pa, "
                    f"K0 = {K0:.4g}")
    _legend(ax[0])
    ax[1].axhline(0.0, color="k", lw=0.8)
    ax[1].set(xlabel="time after cessation t - t0 [s]", ylabel="log10(data/model)")
    return Path(plots.save(fig, out / "relaxation.png")).name
