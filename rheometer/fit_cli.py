"""``rheometer read`` and ``rheometer fit``: measured flow curves in, a fitted Material out.

Examples::

    rheometer read export_*.csv --phi 0.38 0.41 0.44 --out curves.csv
    rheometer read table.csv --columns stress="Shear Stress" rate="Shear Rate" phi=phi
    rheometer fit rheometer/examples/rheocompass_phi_*.csv --phi 0.40 0.42 0.45 0.48 0.51 --out fit
    rheometer flow-curve --material fit/material.json

``fit`` writes DIR/material.json (the fitted Material with the data's provenance; every
``--material`` accepts it), DIR/parameters.csv (value, interval, stage, status), DIR/fit.csv (data,
model and residual_log10 per point), DIR/correlation.csv, DIR/curves.csv (what was read, with the
dropped points and why), and the figures DIR/fit_curves.png, DIR/residuals.png,
DIR/stage1_low_plateau.png, DIR/stage2_high_plateau.png, DIR/stage3_dst.png (Figs. 11-13).
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
from pathlib import Path

import numpy as np
import pandas as pd

from rheology.cli_common import Number

_PHI = Number("--phi", 0.0, 1.0, lo_closed=False, hi_closed=False)

#: What steady flow curves cannot determine (copied by --transient-from).
TRANSIENT_FIELDS = ("G", "K", "K0", "rho_s", "rho_f", "d", "K3", "kappa", "phi0")


def _columns(text: str):
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"--columns expects QUANTITY=NAME, got {text!r}")
    k, v = (s.strip() for s in text.split("=", 1))
    if not k or not v:
        raise argparse.ArgumentTypeError(f"--columns {text!r}: empty quantity or column name; "
                                         "expects QUANTITY=NAME")
    return k.lower(), v


def _text(option: str):
    """argparse ``type`` of a text option: refuses an empty or blank value (``--interval ''``
    matched every RheoCompass result, ``--transient-from ''`` was ignored)."""

    def check(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"{option} = {text!r} is empty; valid: a "
                                             "non-empty value")
        return text.strip()

    check.__name__ = "text"
    return check


def _once(option: str, values) -> None:
    """Refuse a value given twice to a list option (one line naming the option and value)."""
    seen = []
    for v in values or []:
        if v in seen:
            raise ValueError(f"{option} {v} is given twice; give each once")
        seen.append(v)


def _set_value(text: str):
    """``NAME=VALUE`` of ``fit --set`` (checked in cmd_fit by rheology.materials.
    check_set_override: a numeric parameter, not a text field, held at a finite number)."""
    from rheology.materials import split_set_item

    try:
        return split_set_item(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _read_options(p):
    p.add_argument("files", nargs="+", metavar="FILE", help="rheometer exports or tables")
    p.add_argument("--format", default="auto", choices=("auto", "rheocompass", "csv"),
                   help="file format (default: detected from the content)")
    p.add_argument("--columns", nargs="+", type=_columns, default=None, metavar="QUANTITY=NAME",
                   help="column names of a table: stress=NAME rate=NAME viscosity=NAME "
                        "phi=NAME (any two of stress [Pa], rate [1/s], viscosity [Pa s])")
    p.add_argument("--phi", nargs="+", type=_PHI, default=None, metavar="PHI",
                   help="volume fraction of each file, in order (files without a phi column)")
    p.add_argument("--interval", action="append", type=_text("--interval"), default=None,
                   metavar="NAME",
                   help="RheoCompass result names to keep (substring, repeatable; default "
                        "'viscosity curve', 'flow curve')")
    p.add_argument("--torque-floor", type=Number("--torque-floor", 0.0, None, lo_closed=False,
                                                 unit="mN m"), default=None, metavar="MNM",
                   help="drop readings with |torque| below this [mN m] (instrument-flagged "
                        "ME- readings are always dropped)")
    p.add_argument("--mass-fraction", action="store_true",
                   help="the phi values are mass fractions: convert with Eq. (20) (needs "
                        "--rho-cs and --rho-l)")
    for name, text in (("--rho-cs", "grain density [kg/m^3]"),
                       ("--rho-l", "suspending-liquid density [kg/m^3]")):
        p.add_argument(name, type=Number(name, 0.0, None, lo_closed=False, unit="kg/m^3"),
                       default=None, help=text + " (Eq. 20)")
    p.add_argument("--rho-w", type=Number("--rho-w", 0.0, None, lo_closed=False,
                                          unit="kg/m^3"), default=1000.0,
                   help="water density [kg/m^3] (Eq. 20; 1000)")
    p.add_argument("--swelling", type=Number("--swelling", 0.0, None), default=0.3,
                   help="lambda of Eq. (20) (0.3)")
    p.add_argument("--pore", type=Number("--pore", 0.0, 1.0, hi_closed=False), default=0.1,
                   help="beta of Eq. (20) (0.1)")


def add_subcommands(sub) -> dict:
    """Add ``read`` and ``fit`` to the ``rheometer`` subparsers; return their command functions."""
    p = sub.add_parser("read", help="read rheometer exports into one tidy CSV (no fitting)",
                       description="Read measured flow curves (RheoCompass exports, CSV/TSV "
                                   "tables) into one tidy CSV: source_file, interval, phi, "
                                   "point, time_s, shear_rate_per_s, shear_stress_Pa, "
                                   "viscosity_Pa_s, kept, dropped_reason.")
    _read_options(p)
    p.add_argument("--out", default="curves.csv", metavar="FILE.csv",
                   help="output CSV (default curves.csv)")

    p = sub.add_parser("fit", help="fit the model to measured flow curves (Supplement, Figs. "
                                   "11-13, then a global fit)",
                       description="Fit Baumgarten & Kamrin's model to measured steady flow "
                                   "curves: stages 1-3 of the Supplement (Figs. 11-13: low "
                                   "plateau -> a0, phi_j; high plateau -> a_inf, phi_c; DST "
                                   "rates -> eta_B), then all parameters at once (robust, log "
                                   "viscosity). Writes DIR/material.json (accepted by every "
                                   "--material), parameters.csv, fit.csv, correlation.csv, "
                                   "curves.csv and PNG figures.")
    _read_options(p)
    p.add_argument("--out", default="fit", metavar="DIR", help="output folder (default fit)")
    p.add_argument("--material", default="hermes2016", metavar="NAME|FILE.json",
                   help="starting point and held parameters (default hermes2016)")
    p.add_argument("--set", action="append", type=_set_value, default=None,
                   metavar="NAME=VALUE", help="fix a parameter at a value (repeatable)")
    p.add_argument("--free", nargs="+", default=None, metavar="NAME",
                   help="also fit parameters normally held: eta0, mu_c, Delta, varphi2, alpha2")
    p.add_argument("--etaB-terms", type=Number("--etaB-terms", 1, 2, integer=True), default=None,
                   help="terms of Eq. (34) (default: as many as --material has)")
    p.add_argument("--confidence", type=Number("--confidence", 0.5, 1.0, lo_closed=False,
                                               hi_closed=False), default=0.95,
                   help="confidence level of the intervals (0.95)")
    p.add_argument("--f-scale", type=Number("--f-scale", 1e-6, 10.0, unit="decades"),
                   default=None, help="robust-loss scale in log10 viscosity, in [1e-6, 10] "
                                      "decades (default: 3 robust standard deviations of a first "
                                      "pass)")
    p.add_argument("--no-profile", action="store_true",
                   help="skip the profile-likelihood intervals of phi_j and phi_c")
    p.add_argument("--transient-from", type=_text("--transient-from"), default=None,
                   metavar="NAME|FILE.json",
                   help="copy the parameters steady flow curves cannot give (G, K, K0, rho_s, "
                        "rho_f, d, K3, kappa, phi0) from this set into the fitted material, so "
                        "that shear1d and mpm2d scenes accept it (e.g. annular_shear)")
    p.add_argument("--name", default=None, help="name of the fitted material (default: the "
                                                "--out folder's name)")
    p.add_argument("--no-plots", action="store_true", help="no PNG figures")
    return {"read": cmd_read, "fit": cmd_fit}


def check_files(args) -> None:
    """Refuse, before anything is read or written, a data file given twice (the same resolved
    path: it would be merged into the fit as two curves) and an option that would be ignored for
    the files given: ``--columns`` maps the columns of CSV/TSV tables, a RheoCompass export's
    columns are fixed by the export; ``--interval`` selects RheoCompass results, tables have
    none. One line naming the file(s) and the option."""
    from rheology.data import detect_format, read_text

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
        kinds[f] = args.format if args.format != "auto" else detect_format(read_text(f))
    rheo = [f for f, k in kinds.items() if k == "rheocompass"]
    if args.columns and rheo:
        raise ValueError(f"--columns applies to CSV/TSV tables only: data file {rheo[0]!r} is a "
                         "RheoCompass export, whose columns are fixed by the export (read by "
                         "name); remove --columns or give tables only")
    if args.interval and not rheo:
        raise ValueError("--interval selects RheoCompass results by name: none of the data "
                         "files is a RheoCompass export (a table's curves are split by its phi "
                         "or interval column); remove --interval")


def _read(args):
    from rheology.data import read_flow_curves

    check_files(args)

    mass = None
    if args.mass_fraction:
        if args.rho_cs is None or args.rho_l is None:
            raise ValueError("--mass-fraction needs --rho-cs and --rho-l (Eq. 20); the paper "
                             "gives no default densities")
        mass = dict(rho_cs=args.rho_cs, rho_l=args.rho_l, rho_w=args.rho_w, lam=args.swelling,
                    beta=args.pore)
    cols = dict(args.columns) if args.columns else None
    return read_flow_curves(args.files, fmt=args.format, columns=cols, phi=args.phi,
                            intervals=args.interval, torque_floor=args.torque_floor,
                            mass_fraction=mass, require_phi=args.cmd == "fit")


def cmd_read(args) -> str:
    """``rheometer read``: write the tidy table; print the drop counts."""
    from rheology.data import EMPTY_OK, describe, table_to_csv_frame
    from rheology.io import atomic_write_csv, check_output_path

    check_output_path("--out", args.out, ["csv"])
    table = _read(args)
    atomic_write_csv(args.out, table_to_csv_frame(table), empty_ok=EMPTY_OK)
    return f"{describe(table)}\nwrote {args.out} ({len(table)} rows)"


def _sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def cmd_fit(args) -> str:
    """``rheometer fit``: read, fit, write DIR/material.json, CSVs and figures."""
    import rheology
    from rheology.data import EMPTY_OK, describe, drop_counts, table_to_csv_frame
    from rheology.fit import SCALE, FlowData, fit_flow_curves
    from rheology.io import atomic_write_csv
    from rheology.materials import save_material

    from rheology.io import check_output_dir

    out = check_output_dir("--out", args.out)
    if args.name is not None and not args.name.strip():
        raise ValueError(f"--name = {args.name!r} is empty; valid: a non-empty name (default: "
                         "the --out folder's name)")
    start = rheology.get_material(args.material)
    from rheology.materials import check_set_override

    fixed = {}
    for k, v in args.set or []:
        if v is None:
            raise ValueError(f"--set {k} = none: fit --set holds a parameter at a number")
        name, x = check_set_override(k, v)
        if name in fixed:
            raise ValueError(f"--set {name} given twice; give each parameter once")
        fixed[name] = x
    from .limits import check_set

    check_set(fixed)                         # the scales' ranges (rheometer.limits.SET_RANGES)
    if fixed:                                # refused as the parameter set, with its range
        from rheology.materials import FIELD_UNITS

        from .cli import _about_set

        try:
            start.replace(**fixed)
        except ValueError as exc:
            raise _about_set(start, fixed, exc, "--set", FIELD_UNITS) from None
    _once("--free", args.free)
    donor = rheology.get_material(args.transient_from) if args.transient_from else None
    table = _read(args)
    print(describe(table))
    data = FlowData.from_table(table)
    name = args.name.strip() if args.name is not None else out.resolve().name
    # numpy's warnings of the fit (a singular covariance at an extreme held value) are held: a
    # failed fit cites the first in its one line, a finished one lists them as notes
    import warnings

    try:
        with warnings.catch_warnings(record=True) as held:
            warnings.simplefilter("always", RuntimeWarning)
            res = fit_flow_curves(
                data, start, fixed=fixed, free=args.free, etaB_terms=args.etaB_terms,
                confidence=args.confidence, profile=not args.no_profile, f_scale=args.f_scale,
                name=name, citation=f"fitted by 'rheometer fit' to {data.n_curves} flow curves "
                                    f"({', '.join(sorted(set(table['source_file'])))}) "
                                    f"starting from {start.name}")
    except (RuntimeError, ArithmeticError, ValueError) as exc:
        first = next((w for w in held if issubclass(w.category, RuntimeWarning)), None)
        if first is None:
            raise
        raise type(exc)(f"{exc} (after numpy's '{first.message}')") from None
    numpy_notes = sorted({f"numpy: {w.message}" for w in held
                          if issubclass(w.category, RuntimeWarning)})
    m = res.material
    if args.transient_from:
        m = m.replace(**{k: getattr(donor, k) for k in TRANSIENT_FIELDS})
    kept = table[table["kept"]].reset_index(drop=True)
    fit_df = pd.DataFrame({
        "source_file": kept["source_file"], "interval": kept["interval"], "phi": kept["phi"],
        "point": kept["point"], "shear_stress_Pa": kept["shear_stress_Pa"],
        "shear_rate_per_s": kept["shear_rate_per_s"], "viscosity_Pa_s": kept["viscosity_Pa_s"],
        "model_shear_rate_per_s": res.model_rate, "model_viscosity_Pa_s": res.model_viscosity,
        "residual_log10": res.residual_log10, "outlier": res.outlier})
    ptable = res.table()
    names, corr = res.correlation
    corr_df = pd.DataFrame(corr, columns=names)
    corr_df.insert(0, "parameter", names)
    provenance = {
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "command": "rheometer fit",
        "start_material": start.name, "fixed": fixed, "freed": args.free or [],
        "transient_from": donor.name if donor else None,
        "files": [{"file": str(f), "sha256": _sha256(f),
                   "format": table.attrs.get("formats", {}).get(str(Path(f)), "?")}
                  for f in args.files],
        "curves": [{"label": lab, "phi": float(p), "points_kept": int(np.sum(data.curve == c))}
                   for c, (lab, p) in enumerate(zip(data.labels, data.curve_phi()))],
        "points_kept": int(len(kept)), "points_dropped": int((~table["kept"]).sum()),
        "dropped_by_reason": drop_counts(table), "outliers": int(res.outlier.sum()),
        "sigma_log10": res.sigma_log10, "model_evaluations": res.n_evaluations,
        "fit_seconds": res.seconds, "messages": res.messages}
    params_json = {p.name: {"value": p.value, "lower": p.lower, "upper": p.upper,
                            "interval": p.method, "stage": p.stage, "status": p.status}
                   for p in res.parameters}
    # every output checked before the first is written (a non-finite value in the last one
    # left the first four behind, with a message saying nothing was written)
    from rheology.io import check_finite, strict_json
    from rheology.materials import material_to_dict

    try:
        check_finite(table_to_csv_frame(table), "curves.csv", EMPTY_OK)
        check_finite(fit_df, "fit.csv")
        check_finite(ptable, "parameters.csv", ("lower", "upper", "std_error_reporting_coord"))
        check_finite(corr_df, "correlation.csv")
        strict_json({"material": material_to_dict(m), "provenance": provenance,
                     "fit": {"confidence": res.confidence, "parameters": params_json,
                             "correlation": {"names": names, "matrix": corr}}}, "material.json")
    except RuntimeError as exc:
        text = str(exc).replace("was not written", "and every other output were not written")
        cause = f" (numpy during the fit: {numpy_notes[0][7:]})" if numpy_notes else ""
        raise RuntimeError(f"{text}{cause}") from None
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_csv(out / "curves.csv", table_to_csv_frame(table), empty_ok=EMPTY_OK)
    atomic_write_csv(out / "fit.csv", fit_df)
    atomic_write_csv(out / "parameters.csv", ptable, empty_ok=("lower", "upper",
                                                                "std_error_reporting_coord"))
    atomic_write_csv(out / "correlation.csv", corr_df)
    save_material(out / "material.json", m, provenance=provenance,
                  fit={"confidence": res.confidence, "parameters": params_json,
                       "correlation": {"names": names, "matrix": corr}})
    written = ["material.json", "parameters.csv", "fit.csv", "correlation.csv", "curves.csv"]
    if not args.no_plots:
        written += write_figures(out, data, res)
    lines = [f"fitted {m.name} in {res.seconds:.2f} s ({res.n_evaluations} model evaluations; "
             f"residual sd {res.sigma_log10:.3g} in log10 viscosity; {int(res.outlier.sum())} "
             f"outlier(s))"]
    for p in res.parameters:
        if p.status == "fixed":
            continue
        lines.append(f"  {p.name:9s} = {p.value:<11.5g} [{p.lower:.5g}, {p.upper:.5g}] "
                     f"({p.method}, stage {p.stage}{', ' + p.status if p.status != 'fitted' else ''})")
    lines += [f"  note: {msg}" for msg in [*res.messages, *numpy_notes]]
    lines.append(f"wrote {', '.join(str(out / w) for w in written)}")
    return "\n".join(lines)


# ------------------------------------------------------------------ figures
def write_figures(out: Path, data, res) -> list[str]:
    """The fit's figures (data vs model per phi, residuals, stages 1-3 as Figs. 11-13)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rheology.fit import mixture_steady_state
    from rheology.io import atomic_savefig

    m = res.material
    phis = data.curve_phi()
    colours = plt.cm.viridis(np.linspace(0, 0.9, data.n_curves))
    names = []

    def save(fig, name):
        atomic_savefig(fig, out / name)
        plt.close(fig)
        names.append(name)

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for c in range(data.n_curves):
        s, v, r = data.sorted_curve(c)
        sel = data.curve == c
        ax[0].loglog(s, v, "o", ms=3.5, color=colours[c], label=f"phi = {phis[c]:.4g}")
        ax[0].loglog(data.stress[sel & res.outlier], data.viscosity[sel & res.outlier], "x",
                     color="r", ms=7)
        ax[1].loglog(r, s, "o", ms=3.5, color=colours[c])
        grid = np.logspace(np.log10(s.min()), np.log10(s.max()), 200)
        if phis[c] < m.phi_j:
            st = mixture_steady_state(grid, phis[c], m)
            ax[0].loglog(grid, st["viscosity"], "-", color=colours[c])
            ax[1].loglog(st["shear_rate"], grid, "-", color=colours[c])
    ax[0].set(xlabel="shear stress [Pa]", ylabel="viscosity [Pa s]",
              title=f"data (markers) and fitted model (lines); x: outliers")
    ax[1].set(xlabel="shear rate [1/s]", ylabel="shear stress [Pa]", title=m.name)
    ax[0].legend(fontsize=7)
    save(fig, "fit_curves.png")

    fig, ax = plt.subplots(figsize=(6, 3.8))
    for c in range(data.n_curves):
        sel = data.curve == c
        ax.semilogx(data.stress[sel], res.residual_log10[sel], "o-", ms=3, color=colours[c],
                    label=f"phi = {phis[c]:.4g}")
    ax.axhline(0, color="k", lw=0.8)
    for k in (-2, 2):
        ax.axhline(k * res.sigma_log10, color="k", ls=":", lw=0.8)
    ax.set(xlabel="shear stress [Pa]", ylabel="log10(measured / model viscosity)",
           title=f"residuals (sd {res.sigma_log10:.3g}; dotted: +-2 sd)")
    ax.legend(fontsize=7)
    save(fig, "residuals.png")

    st1, st2, st3 = res.stages["1"], res.stages["2"], res.stages["3"]
    eta0, mu_c = m.eta0, m.mu_c

    def eq(phi, pm, a):
        return 1 + 2.5 * phi * pm / (pm - phi) + 2 * mu_c * (a * phi / (pm - phi)) ** 2

    for stage, key, pm, a, title, fname, sel in (
            ("1", "eta_min", st1["phi_j"], st1["a0"], "Stage 1 (Fig. 11, Eq. 24): low-stress "
             "plateau -> a0, phi_j", "stage1_low_plateau.png", range(data.n_curves)),
            ("2", "eta_max", st2["phi_c"], st2["a_inf"], "Stage 2 (Fig. 12, Eq. 25): high-stress "
             "plateau -> a_inf, phi_c", "stage2_high_plateau.png", st2["curves"])):
        fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
        st = res.stages[stage]
        for c in range(data.n_curves):
            s, v, _ = data.sorted_curve(c)
            ax[0].loglog(s, v / eta0, "-", color=colours[c], lw=1, label=f"phi = {phis[c]:.4g}")
        xs = st1["stress_min"] if stage == "1" else st2["stress_max"]
        ys = np.asarray(st[key]) / eta0
        ax[0].loglog(xs, ys, "ko", ms=6)
        ax[0].set(xlabel="shear stress [Pa]", ylabel="eta / eta0",
                  title="curves; black: " + ("minimum" if stage == "1" else "maximum") +
                        " viscosity")
        ax[0].legend(fontsize=7)
        ph = np.asarray(st["phi"]) if stage == "2" else np.asarray(st1["phi"])
        if ph.size:
            ax[1].semilogy(ph, ys, "o", color="C0", label="plateaus")
            grid = np.linspace(min(ph.min(), 0.9 * pm) * 0.98, pm - 1e-3 * pm, 200)
            grid = grid[grid > 0]
            ax[1].semilogy(grid, eq(grid, pm, a), "r-", label=f"Eq. ({'24' if stage == '1' else '25'})")
            ax[1].axvline(pm, color="k", ls="--", label=f"{'phi_j' if stage == '1' else 'phi_c'}"
                                                         f" = {pm:.4g}")
            ax[1].legend(fontsize=8)
        else:
            ax[1].text(0.5, 0.5, "no curve with a high-stress plateau", ha="center",
                       transform=ax[1].transAxes)
        ax[1].set(xlabel="phi", ylabel="eta_r", title=title)
        save(fig, fname)

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for c in range(data.n_curves):
        s, v, r = data.sorted_curve(c)
        ax[0].loglog(r, s, "-", color=colours[c], lw=1, label=f"phi = {phis[c]:.4g}")
    for c, g, (lo, hi) in zip(st3["curves"], st3["gdot_dst"], st3["stress_range"]):
        ax[0].loglog([g, g], [lo, hi], "ko-", ms=5)
    ax[0].set(xlabel="shear rate [1/s]", ylabel="shear stress [Pa]",
              title="curves; black: DST region and rate")
    ax[0].legend(fontsize=7)
    top = min(m.phi_star, m.phi_j) - 1e-4 * m.phi_j
    if len(st3["phi"]) and top > m.phi_c:
        from rheology.steady import gdot_dst

        ax[1].semilogy(st3["phi"], st3["gdot_dst"], "o", label="DST rates (stage 3)")
        grid = np.linspace(max(m.phi_c, min(st3["phi"]) - 0.02), top, 200)
        ax[1].semilogy(grid, gdot_dst(grid, m), "r-", label="Eq. (33), fitted material")
        ax[1].axvline(m.phi_j, color="k", ls="--", label=f"phi_j = {m.phi_j:.4g}")
        ax[1].legend(fontsize=8)
    else:
        ax[1].text(0.5, 0.5, "no DST curve", ha="center", transform=ax[1].transAxes)
    ax[1].set(xlabel="phi", ylabel="gdot_DST [1/s]",
              title="Stage 3 (Fig. 13, Eq. 33): DST rates -> eta_B(phi)")
    save(fig, "stage3_dst.png")
    return names
