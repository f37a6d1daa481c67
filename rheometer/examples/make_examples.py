"""Write the synthetic TRIOS and rSpace example exports of this folder (run from the repository
root: ``python rheometer/examples/make_examples.py``; deterministic, seeded).

Flow curves: hermes2016 steady flow curves at imposed mixture stress (0.01-1000 Pa, 30 points)
with 3% log-normal noise on the rate and the artefacts of rheology.fit.synthetic_curves (two
readings below the torque floor with negative rates, one repeated reading, one blank rate cell,
wall slip on the top two points of the densest curve). Relaxation: rheometer.protocols.relax at
phi = 0.52 after steady shear at 100 and 30 Pa, G = 2000 Pa, K0 = 1, 3% noise on the stress, the
record starting 0.05 s after cessation, readings below 1e-4 taubar0 cut, written as torque only
(a 40 mm 2 degree cone: stress constant 3/(2 pi R^3)). Oscillatory blocks hold placeholder
numbers: the readers skip them.
"""

from pathlib import Path

import numpy as np

import rheology
from rheology.data import write_export
from rheology.fit import mixture_steady_state, synthetic_curves

HERE = Path(__file__).resolve().parent
M = rheology.get_material("hermes2016")
R = 0.02                                        # cone radius [m]
K_STRESS = 3.0 / (2.0 * np.pi * R ** 3)         # Pa/(N m)
HEADER = {"": {"Filename": "synthetic.tri (written by suspension-toolkit)",
               "Instrument type": "DHR", "Instrument serial number": "synthetic",
               "Instrument name": "synthetic", "operator": "suspension-toolkit",
               "rundate": "synthetic", "proceduresegments": "3"},
          "Sample": {"Sample name": "cornstarch in water (synthetic: hermes2016 model)"},
          "Geometry": {"Geometry name": "40 mm 2 deg cone", "Diameter": "40 mm",
                       "Cone angle": "2 deg", "Truncation gap": "52 um",
                       "Stress constant": f"{K_STRESS:.6g} Pa/N.m",
                       "Strain constant": "28.6479 1/rad"}}


def flow_columns(c, units):
    """The columns of a flow-curve step from a synthetic curve, in the given units."""
    s, r = np.asarray(c["stress"]), np.asarray(c["rate"])
    with np.errstate(invalid="ignore", divide="ignore"):
        v = s / r
    n = s.size
    f_s, f_v, f_t = units["stress"][1], units["viscosity"][1], units["time"][1]
    return [(units["names"][0], units["stress"][0], s / f_s),
            (units["names"][1], units["rate"], r),
            (units["names"][2], units["viscosity"][0], v / f_v),
            (units["names"][3], units["time"][0], np.arange(1, n + 1) * 6.0 / f_t),
            (units["names"][4], units["torque"], s / K_STRESS * 1e6)]


def oscillation_columns(names, n=8):
    strain = np.logspace(-1, 2, n)
    return [(names[0], "%", strain), (names[1], "Pa", 800.0 / (1 + strain / 20.0)),
            (names[2], "Pa", 150.0 * (1 + strain / 50.0))]


def hold_columns(phi, stress=5.0, n=5, names=("Step time", "Shear rate", "Stress", "Viscosity",
                                              "Torque"), units=("s", "1/s", "Pa", "Pa.s", "µN.m")):
    rate = float(mixture_steady_state(stress, phi, M)["shear_rate"])
    vals = (np.arange(1, n + 1) * 2.0, np.full(n, rate), np.full(n, stress),
            np.full(n, stress / rate), np.full(n, stress / K_STRESS * 1e6))
    return list(zip(names, units, vals))


def main():
    syn = synthetic_curves(M, [0.42, 0.45, 0.48], stress_range=(0.01, 1000.0), points=30,
                           seed=7)
    trios = {"names": ("Stress", "Shear rate", "Viscosity", "Step time", "Torque"),
             "stress": ("Pa", 1.0), "rate": "1/s", "viscosity": ("mPa.s", 1e-3),
             "time": ("s", 1.0), "torque": "µN.m"}
    write_export(HERE / "trios_phi_0.42.txt", "trios", [
        {"name": "Peak hold - 1", "columns": hold_columns(0.42)},
        {"name": "Flow sweep - 2", "columns": flow_columns(syn["curves"][0], trios)},
        {"name": "Amplitude sweep - 3", "columns": oscillation_columns(
            ("Oscillation strain", "Storage modulus", "Loss modulus"))}], HEADER)
    csv_units = {**trios, "stress": ("kPa", 1e3), "viscosity": ("Pa.s", 1.0),
                 "time": ("min", 60.0)}
    write_export(HERE / "trios_phi_0.45.csv", "trios-csv", [
        {"name": "Flow sweep - 1", "columns": flow_columns(syn["curves"][1], csv_units)},
        {"name": "Frequency sweep - 2", "columns": oscillation_columns(
            ("Angular frequency", "Storage modulus", "Loss modulus"))}], HEADER)
    rspace = {"names": ("Shear stress", "Shear rate", "Shear viscosity", "Time", "Torque"),
              "stress": ("Pa", 1.0), "rate": "s-¹", "viscosity": ("Pa s", 1.0),
              "time": ("s", 1.0), "torque": "µN m"}
    write_export(HERE / "rspace_phi_0.48.csv", "rspace", [
        {"name": "Pre-shear", "columns": hold_columns(
            0.48, names=("Time", "Shear rate", "Shear stress", "Shear viscosity", "Torque"),
            units=("s", "s-¹", "Pa", "Pa s", "µN m"))},
        {"name": "Shear stress ramp", "columns": flow_columns(syn["curves"][2], rspace)},
        {"name": "Amplitude sweep", "columns": oscillation_columns(
            ("Shear strain", "Shear modulus (elastic component)",
             "Shear modulus (viscous component)"))}],
        {"": {"Sample name": "cornstarch in water (synthetic: hermes2016 model)",
              "Sequence": "Viscometry - shear stress ramp",
              "Geometry": "CP2/40 (40 mm 2 deg cone)",
              "Software": "rSpace for Kinexus (file written by suspension-toolkit)"}})
    relaxation_example()


def relaxation_example():
    from rheometer.relaxation_fit import synthetic_relaxation

    steps, phi = [], 0.52
    for k, tau0 in enumerate((100.0, 30.0)):
        c = synthetic_relaxation(M, phi, tau0, G=2000.0, K0=1.0, offset=0.05, floor=1e-4,
                                 seed=11 + k)
        n = c.time.size
        steps.append({"name": f"Flow peak hold - {2 * k + 1}", "columns": hold_columns(
            phi, stress=tau0 + M.eta0 * (1 + 2.5 * phi) * float(rheology.steady_state_stress(
                tau0, phi, M).shear_rate))})
        steps.append({"name": f"Stress relaxation - {2 * k + 2}", "columns": [
            ("Step time", "s", c.time), ("Torque", "µN.m", c.stress / K_STRESS * 1e6),
            ("Temperature", "°C", np.full(n, 20.0))]})
    header = {**HEADER, "Sample": {"Sample name": "cornstarch in water, phi = 0.52 (synthetic: "
                                                  "hermes2016, G = 2000 Pa, K0 = 1)"},
              "Geometry": {**HEADER["Geometry"],
                           "Stress constant": f"{K_STRESS * 1e-6:.6g} Pa/µN.m"}}
    write_export(HERE / "trios_relaxation_phi_0.52.txt", "trios", steps, header)


if __name__ == "__main__":
    main()
