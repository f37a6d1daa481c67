"""Draw the four small figures of the README and the docs' front page, one per tier.

Run by hand from the repository root (not in CI; ~5-15 min on two cores, most of it the impact):

    python docs/make_figures.py              # runs the commands in a temporary folder
    python docs/make_figures.py --work DIR   # keeps the runs in DIR (rerun: reuses finished runs)
    python docs/make_figures.py --wheel      # also Figs. 8-9 (mpm2d run wheel, ~25 min more)

Every figure is drawn from the toolkit's own commands or API, at their default sizes:

- ``flow_curve.png``: :func:`rheology.steady_state_stress` for hermes2016 at phi = 0.48, 0.50,
  0.52 (the default of ``rheometer flow-curve``), with gdot_DST of Eq. (33);
- ``shear1d_front.png``: ``shear1d annular --u-inner 0.084 --mode locked`` (the fast Fig. 3 case);
- ``impact_displacement.png``: ``mpm2d run impact`` (the Fig. 4 scene at 2 mm cells), the
  z-displacement field from :func:`mpm2d.scenes.impact.displacement_field`;
- ``fit.png``: ``rheometer fit`` on the shipped RheoCompass examples (``fit.csv``);
- ``fig1.png``, ``fig2.png``, ``fig10.png``, ``fig15.png``: the figures of the validation cases
  of those paper figures (``python -m validation report --only ...``), shrunk;
- with ``--wheel``: ``fig8.png``, ``fig9.png`` from ``mpm2d run wheel`` (the paper's grid).

The PNGs go to ``docs/images/`` (each well under 150 kB).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from runkit.io import atomic_savefig
from runkit.plotting import plt

ROOT = Path(__file__).resolve().parents[1]
IMAGES = ROOT / "docs" / "images"
SIZE = (5.0, 3.4)     # inches at 100 dpi: 500 x 340 px
DPI = 100


def run(cmd: list[str], cwd: Path, done: Path) -> None:
    """Run one toolkit command in ``cwd`` unless ``done`` (its output) is already there."""
    if done.exists():
        return
    print("$", " ".join(cmd), flush=True)
    subprocess.run(cmd, cwd=cwd, check=True)


def save(fig, name: str) -> None:
    path = atomic_savefig(fig, IMAGES / name, dpi=DPI, metadata={"Software": None})
    plt.close(fig)
    print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size / 1024:.0f} kB)")


def flow_curve() -> None:
    import rheology as r

    m = r.get_material("hermes2016")
    fig, ax = plt.subplots(figsize=SIZE)
    for phi in (0.48, 0.50, 0.52):
        flow = r.steady_state_stress(np.logspace(-3, 4, 300), phi, m).to_frame()
        ax.loglog(flow["shear_rate_per_s"], flow["granular_shear_stress_Pa"], label=f"phi = {phi}")
    gd = r.gdot_dst(0.52, m)
    ax.axvline(gd, color="k", ls=":", lw=1)
    ax.text(gd * 1.15, 2e-3, "gdot_DST(0.52)\nEq. (33)", fontsize=7)
    ax.set_xlabel("shear rate [1/s]")
    ax.set_ylabel("granular shear stress [Pa]")
    ax.set_title("rheometer: hermes2016 flow curves; each folds back (DST)",
                 fontsize=9)
    ax.legend(fontsize=8, frameon=False)
    save(fig, "flow_curve.png")


def shear1d_front(work: Path) -> None:
    out = work / "fast"
    run(["shear1d", "annular", "--u-inner", "0.084", "--mode", "locked", "--out", "fast",
         "--quiet"], work, out / "u84mm_s_locked_summary.json")
    prof = pd.read_csv(out / "u84mm_s_locked_velocity_profiles.csv")
    s = json.loads((out / "u84mm_s_locked_summary.json").read_text())
    fig, ax = plt.subplots(figsize=SIZE)
    for rot, g in prof.groupby("rotation_rad"):
        ax.plot(g["r_m"] * 1e3, g["v_over_u_inner"], label=f"{rot:.2f} rad")
    ax.set_xlabel("r [mm] (bob at 12.5, cup at 36)")
    ax.set_ylabel("v / u_i")
    speed = s.get("front_speed_m_per_s")
    ax.set_title("shear1d: Fig. 3, u_i = 84 mm/s: a jammed band grows from the bob"
                 + (f"\nfront speed {speed:.3f} m/s" if speed else ""), fontsize=9)
    ax.legend(title="bob rotation", fontsize=7, title_fontsize=7, frameon=False)
    save(fig, "shear1d_front.png")


def impact_displacement(work: Path) -> None:
    from mpm2d.scenes.impact import displacement_field

    out = work / "impact"
    run(["mpm2d", "run", "impact", "--out", "impact", "--no-vtk", "--quiet"], work,
        out / "summary.json")
    s = json.loads((out / "summary.json").read_text())
    field, _, _, t = displacement_field(out, s)
    h, (nx, nz) = s["h_m"], s["grid"]
    fig, ax = plt.subplots(figsize=(4.6, 4.0))
    lim = float(np.nanmax(np.abs(field))) * 1e3
    im = ax.imshow(field.T * 1e3, origin="lower", extent=(0, nx * h * 1e2, 0, nz * h * 1e2),
                   cmap="RdBu_r", vmin=-lim, vmax=lim, interpolation="nearest")
    ax.fill_between([0, s["rod_radius_m"] * 1e2], (s["depth_m"] - s["final_rod_depth_m"]) * 1e2,
                    nz * h * 1e2, color="0.55")
    fig.colorbar(im, ax=ax, label="z-displacement [mm]", shrink=0.8)
    ax.set_xlabel("r [cm]")
    ax.set_ylabel("z [cm]")
    ax.set_title(f"mpm2d: rod impact (Fig. 4 scene), {t * 1e3:.0f} ms after impact at "
                 f"{s['v0_m_per_s']:g} m/s:\nthe plug under the rod (grey) moves with it",
                 fontsize=9)
    ax.set_aspect("equal")
    save(fig, "impact_displacement.png")


def fit(work: Path) -> None:
    out = work / "fit"
    files = sorted(str(p) for p in (ROOT / "rheometer" / "examples").glob("rheocompass_phi_*.csv"))
    run(["rheometer", "fit", *files, "--phi", "0.40", "0.42", "0.45", "0.48", "0.51", "--out",
         "fit", "--no-plots"], work, out / "fit.csv")
    pts = pd.read_csv(out / "fit.csv")
    fig, ax = plt.subplots(figsize=SIZE)
    for phi, g in pts.groupby("phi"):
        g = g.sort_values("shear_stress_Pa")
        line, = ax.loglog(g["shear_stress_Pa"], g["viscosity_Pa_s"], "o", ms=3,
                          label=f"phi = {phi:.2f}")
        ax.loglog(g["shear_stress_Pa"], g["model_viscosity_Pa_s"], "-", color=line.get_color(),
                  lw=1)
    ax.set_xlabel("shear stress [Pa]")
    ax.set_ylabel("viscosity [Pa s]")
    ax.set_title("rheometer fit: example exports (points) and the fitted model (lines)",
                 fontsize=9)
    ax.legend(fontsize=7, frameon=False, ncol=2)
    save(fig, "fit.png")


#: validation case -> (its figure, the docs' name for it)
CASE_FIGURES = {
    "fig1_singh_model_curves": ("fig1.png", "fig1.png"),
    "fig2_experimental_fits": ("fig2.png", "fig2.png"),
    "fig10_steady_structure": ("fig10.png", "fig10.png"),
    "fig15_relaxation": ("fig15_relaxation.png", "fig15.png"),
}


def shrink(src: Path, name: str, width: int = 640) -> None:
    """A run's figure as ``docs/images/NAME``: ``width`` pixels wide, 256 colours."""
    from PIL import Image

    with Image.open(src) as im:
        im = im.convert("RGB")
        im.thumbnail((width, width * 4))
        im = im.quantize(colors=256, method=Image.Quantize.MEDIANCUT)
        im.save(IMAGES / name, optimize=True)
    print(f"wrote docs/images/{name} ({(IMAGES / name).stat().st_size / 1024:.0f} kB)")


def case_figures(work: Path) -> None:
    """The cheap paper-figure cases of the validation report, their figures shrunk."""
    out = work / "report"
    run([sys.executable, "-m", "validation", "report", "--only", *CASE_FIGURES, "--out",
         "report"], work, out / "results.json")
    for case, (src, name) in CASE_FIGURES.items():
        shrink(out / case / src, name)


def wheel_figures(work: Path) -> None:
    """Figs. 8-9 from ``mpm2d run wheel`` (the paper's grid, both omegas: ~25 min on two
    cores; only with ``--wheel``)."""
    out = work / "wheel"
    run(["mpm2d", "run", "wheel", "--out", "wheel", "--quiet"], work, out / "summary.json")
    shrink(out / "fig8.png", "fig8.png", width=720)
    shrink(out / "fig9.png", "fig9.png", width=720)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, help="folder for the runs (default: a temporary one)")
    ap.add_argument("--wheel", action="store_true",
                    help="also Figs. 8-9 from mpm2d run wheel (~25 min on two cores)")
    args = ap.parse_args(argv)
    IMAGES.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        work = (args.work or Path(tmp)).resolve()
        work.mkdir(parents=True, exist_ok=True)
        flow_curve()
        fit(work)
        shear1d_front(work)
        impact_displacement(work)
        case_figures(work)
        if args.wheel:
            wheel_figures(work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
