"""Measured flow curves from rheometer files: readers, cleaning, and one tidy table.

One entry point, :func:`read_flow_curves`, reads any number of files into one tidy table (one
row per measured point) with the columns of :data:`COLUMNS`::

    source_file, interval, phi, point, time_s, shear_rate_per_s, shear_stress_Pa,
    viscosity_Pa_s, kept, dropped_reason

Every point is kept in the table; the bad ones have ``kept = False`` and a ``dropped_reason``
(:data:`DROP_REASONS`), so nothing is dropped silently (:func:`drop_counts` counts them).

Formats are one reader function each, registered in :data:`READERS` with a content detector, so a
TRIOS or Malvern reader is one more function and one more line:

- ``rheocompass``: Anton Paar RheoCompass text export (UTF-16 or UTF-8, tab separated, several
  ``Result:`` / ``Interval data:`` blocks per file, a units row, status flags, blank cells,
  exponent notation, decimal commas). The viscosity-curve intervals are selected by name
  (default: names containing "viscosity curve" or "flow curve"); pre-shear and the rest are
  kept out.
- ``csv``: a plain delimited table (comma, semicolon or tab; sniffed) with a header of any column
  names, mapped with ``columns={"stress": NAME, "rate": NAME, "viscosity": NAME, "phi": NAME}``
  (any two of stress [Pa], rate [1/s] and viscosity [Pa s]; a phi column optional). Without a
  mapping, common names are recognised (``shear_stress_Pa``, ``Shear Stress``, ``stress``, ...).

Volume fractions: from a phi column, else ``phi=[...]`` one per file in order; mass fractions are
converted with Eq. (20) of the Supplement (:func:`rheology.steady.phi_from_mass_fraction`) when
``mass_fraction`` densities are given.
"""

from __future__ import annotations

import csv
import io
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

#: Columns of the tidy table, in order (units in the names).
COLUMNS: tuple[str, ...] = ("source_file", "interval", "phi", "point", "time_s",
                            "shear_rate_per_s", "shear_stress_Pa", "viscosity_Pa_s", "kept",
                            "dropped_reason")

#: Why a point is dropped (checked in this order; the first that applies is recorded).
DROP_REASONS: dict[str, str] = {
    "missing_value": "a blank or non-numeric stress, rate or viscosity",
    "below_torque_floor": "flagged by the instrument (status ME-) or torque below --torque-floor",
    "nonpositive_rate": "shear rate <= 0",
    "nonpositive_stress": "shear stress <= 0",
    "nonpositive_viscosity": "viscosity <= 0",
    "duplicate": "the same stress as an earlier point of the curve (repeated reading)",
    "non_monotone": "breaks the curve's stress ramp (a step against the ramp's direction)",
}

#: Names of the two RheoCompass results kept by default (matched case-insensitively in the
#: ``Result:`` name).
DEFAULT_INTERVALS: tuple[str, ...] = ("viscosity curve", "flow curve")

_UNITS = {  # unit text (lower case, no spaces, '·' and '*' removed) -> factor to SI
    "stress": {"pa": 1.0, "mpa": 1e-3, "kpa": 1e3, "": 1.0},
    "viscosity": {"pas": 1.0, "mpas": 1e-3, "cp": 1e-3, "p": 0.1, "": 1.0},
    "rate": {"1/s": 1.0, "s-1": 1.0, "s^-1": 1.0, "1/min": 1 / 60.0, "": 1.0},
    "time": {"s": 1.0, "min": 60.0, "h": 3600.0, "ms": 1e-3, "": 1.0},
    "torque": {"mnm": 1.0, "µnm": 1e-3, "unm": 1e-3, "nm": 1e3, "": 1.0},   # to mN m
}

_ALIASES = {  # recognised header names (lower case, units stripped) for the csv reader
    "stress": ("shear_stress_pa", "shear stress", "shear_stress", "stress", "tau", "sigma"),
    "rate": ("shear_rate_per_s", "shear rate", "shear_rate", "rate", "gdot", "gamma_dot"),
    "viscosity": ("viscosity_pa_s", "viscosity", "eta", "apparent viscosity"),
    "phi": ("phi", "volume_fraction", "volume fraction"),
    "time": ("time_s", "time", "t"),
    "point": ("point", "point no.", "point no", "index"),
    "torque": ("torque", "torque_mnm"),
    "interval": ("interval",),
}


@dataclass
class Curve:
    """One measured curve as read from a file, before cleaning.

    Arrays are float (NaN for blank or non-numeric cells), SI units; ``flagged`` marks points the
    instrument flagged as below its torque range; ``phi`` is None when the file carries none.
    """

    source_file: str
    interval: str
    point: np.ndarray
    time_s: np.ndarray
    shear_rate: np.ndarray
    shear_stress: np.ndarray
    viscosity: np.ndarray
    torque_mNm: np.ndarray | None = None
    flagged: np.ndarray | None = None
    phi: np.ndarray | None = None


# ------------------------------------------------------------------ text helpers
def read_text(path) -> str:
    """Decode a text file: UTF-16 (with BOM or by its NUL bytes), UTF-8 (with or without BOM),
    else Latin-1. Raises ValueError naming the file when it cannot be read."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"data file {str(path)!r} cannot be read ({exc.strerror or exc})") from None
    if not raw.strip():
        raise ValueError(f"data file {str(path)!r} is empty")
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        return raw.decode("utf-16")
    if len(raw) > 3 and raw[1:2] == b"\x00" and raw[3:4] == b"\x00":
        return raw.decode("utf-16-le")
    if len(raw) > 3 and raw[0:1] == b"\x00" and raw[2:3] == b"\x00":
        return raw.decode("utf-16-be")
    for enc in ("utf-8-sig", "latin-1"):
        try:
            return raw.decode(enc)
        except UnicodeDecodeError:
            continue
    raise ValueError(f"data file {str(path)!r} is not text")  # pragma: no cover (latin-1 decodes all)


_NUM = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?$")


def to_number(cell) -> float:
    """A cell as float: exponent notation and a decimal comma accepted; blank or text -> NaN."""
    s = str(cell).strip().replace("\u2212", "-")
    if not s or not _NUM.match(s):
        return float("nan")
    return float(s.replace(",", "."))


def _unit_key(text: str) -> str:
    return (text.strip().strip("[]").lower().replace("·", "").replace("*", "").replace(" ", "")
            .replace("\u00b7", "").replace("⁻¹", "^-1"))


def _factor(kind: str, unit: str, where: str) -> float:
    key = _unit_key(unit)
    table = _UNITS[kind]
    if key not in table:
        raise ValueError(f"{where}: unit [{unit.strip('[]')}] of the {kind} column is not "
                         f"understood; known: {', '.join(k for k in table if k)}")
    return table[key]


# ------------------------------------------------------------------ RheoCompass
def is_rheocompass(text: str) -> bool:
    """Whether decoded text looks like a RheoCompass export (``Interval data:`` headers)."""
    return "Interval data:" in text


def read_rheocompass(path, text: str | None = None, *,
                     intervals: Sequence[str] | None = None) -> list[Curve]:
    """Read the selected intervals of an Anton Paar RheoCompass text export.

    Parameters
    ----------
    path : path-like
        The export (UTF-16 as written by RheoCompass, or UTF-8).
    text : str, optional
        Its decoded content (read from ``path`` if None).
    intervals : sequence of str, optional
        Substrings (case-insensitive) of the ``Result:`` names to keep; default
        :data:`DEFAULT_INTERVALS`. Every other block (pre-shear, ...) is kept out.

    Returns
    -------
    list of Curve
        One per selected block, in file order (interval = the result name and its interval
        number, e.g. ``"Viscosity curve 1 (interval 2)"``).

    Raises
    ------
    ValueError
        No block matches (the message lists the blocks found), a block without its columns or
        with a unit not understood.
    """
    path = Path(path)
    text = read_text(path) if text is None else text
    wanted = [w.lower() for w in (intervals or DEFAULT_INTERVALS)]
    lines = text.splitlines()
    blocks, result, number = [], "", ""
    i = 0
    while i < len(lines):
        cells = lines[i].split("\t")
        head = cells[0].strip()
        if head == "Result:":
            result = cells[1].strip() if len(cells) > 1 else ""
            number = ""
        elif head == "Interval and data points:":
            number = cells[1].strip() if len(cells) > 1 else ""
        elif head == "Interval data:":
            names = [c.strip() for c in cells[1:]]
            units, rows, j = None, [], i + 1
            while j < len(lines):
                c = lines[j].split("\t")
                first = c[0].strip()
                if first in ("Result:", "Interval data:", "Interval and data points:", "Test:",
                             "Project:"):
                    break
                body = [x.strip() for x in c[1:]]
                if units is None and any(x.startswith("[") for x in body):
                    units = body
                elif any(body) and units is not None:
                    rows.append(body)
                elif not any(x.strip() for x in c) and rows:
                    j += 1
                    break
                j += 1
            name = result + (f" (interval {number})" if number else "")
            blocks.append((result, name, names, units or [""] * len(names), rows))
            i = j
            continue
        i += 1
    if not blocks:
        raise ValueError(f"data file {path.name!r}: no 'Interval data:' block found "
                         "(not a RheoCompass export?)")
    chosen = [b for b in blocks if any(w in b[0].lower() for w in wanted)]
    if not chosen:
        found = "; ".join(repr(b[1]) for b in blocks)
        raise ValueError(f"data file {path.name!r}: no interval named like "
                         f"{' or '.join(map(repr, wanted))}; found {found} (choose with "
                         "--interval NAME)")
    curves = []
    for result, name, names, units, rows in chosen:
        where = f"data file {path.name!r}, {name}"
        low = [n.lower() for n in names]

        def col(label, kind=None, required=True):
            if label not in low:
                if required:
                    raise ValueError(f"{where}: no '{label}' column (columns: {', '.join(names)})")
                return None
            k = low.index(label)
            vals = np.array([to_number(r[k]) if k < len(r) else np.nan for r in rows])
            if kind is not None:
                vals = vals * _factor(kind, units[k] if k < len(units) else "", where)
            return vals

        n = len(rows)
        stress = col("shear stress", "stress", required=False)
        rate = col("shear rate", "rate", required=False)
        visc = col("viscosity", "viscosity", required=False)
        stress, rate, visc = _complete(stress, rate, visc, where)
        point = col("point no.", required=False)
        time = col("time", "time", required=False)
        torque = col("torque", "torque", required=False)
        status = (np.array([r[low.index("status")] if low.index("status") < len(r) else ""
                            for r in rows]) if "status" in low else np.array([""] * n))
        flagged = np.array([any(s.strip().upper().startswith("ME") for s in str(st).split(","))
                            for st in status], dtype=bool)
        curves.append(Curve(str(path), name,
                            point if point is not None else np.arange(1.0, n + 1),
                            time if time is not None else np.full(n, np.nan), rate, stress, visc,
                            torque, flagged))
    return curves


def _complete(stress, rate, visc, where):
    """Fill the third of (stress, rate, viscosity) from the other two; require two."""
    have = [x is not None for x in (stress, rate, visc)]
    if sum(have) < 2:
        raise ValueError(f"{where}: needs two of shear stress, shear rate and viscosity "
                         "(map them with --columns stress=NAME rate=NAME viscosity=NAME)")
    with np.errstate(divide="ignore", invalid="ignore"):
        if stress is None:
            stress = visc * rate
        elif rate is None:
            rate = np.where(visc != 0, stress / np.where(visc != 0, visc, 1.0), np.nan)
        elif visc is None:
            visc = np.where(rate != 0, stress / np.where(rate != 0, rate, 1.0), np.nan)
    return stress, rate, visc


# ------------------------------------------------------------------ plain tables
def read_table(path, text: str | None = None, *, columns: dict[str, str] | None = None,
               intervals: Sequence[str] | None = None) -> list[Curve]:
    """Read a delimited table (comma, semicolon or tab) with a header row.

    Parameters
    ----------
    columns : dict, optional
        ``{"stress": NAME, "rate": NAME, "viscosity": NAME, "phi": NAME}`` (also ``time``,
        ``point``, ``torque``, ``interval``): the file's column for each quantity, in SI units
        (Pa, 1/s, Pa s, s, mN m). Unmapped quantities are looked up among common names; a unit in
        brackets or parentheses after a name (``Shear Stress [mPa]``) is converted.
    intervals : ignored (tables have no named intervals; an ``interval`` column splits curves).

    Returns
    -------
    list of Curve
        One per (interval, phi) group, in order of appearance.

    Raises
    ------
    ValueError
        A mapped column missing (the message lists the columns), fewer than two of stress, rate
        and viscosity, no rows.
    """
    path = Path(path)
    text = read_text(path) if text is None else text
    body = "\n".join(ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#"))
    if not body:
        raise ValueError(f"data file {path.name!r} has no rows")
    first = body.splitlines()[0]
    delim = max(("\t", ";", ","), key=first.count)
    if first.count(delim) == 0:
        raise ValueError(f"data file {path.name!r}: the header {first[:60]!r} has no comma, "
                         "semicolon or tab")
    reader = csv.reader(io.StringIO(body), delimiter=delim)
    rows = list(reader)
    header = [h.strip() for h in rows[0]]
    data = rows[1:]
    if not data:
        raise ValueError(f"data file {path.name!r} has a header but no rows")

    def split(h):
        m = re.match(r"^(.*?)\s*[\[(]([^\])]*)[\])]\s*$", h)
        return (m.group(1), m.group(2)) if m else (h, "")

    bare = [split(h)[0].strip().lower() for h in header]
    units = [split(h)[1] for h in header]
    full = [h.lower() for h in header]
    columns = dict(columns or {})
    unknown = set(columns) - set(_ALIASES)
    if unknown:
        raise ValueError(f"--columns: unknown quantity {sorted(unknown)}; valid: "
                         f"{', '.join(_ALIASES)}")
    where = f"data file {path.name!r}"

    def find(q):
        if q in columns:
            name = columns[q].strip().lower()
            for cand in (full, bare):
                if name in cand:
                    return cand.index(name)
            raise ValueError(f"{where}: --columns {q}={columns[q]!r} is not a column; columns: "
                             f"{', '.join(header)}")
        for alias in _ALIASES[q]:
            for cand in (full, bare):
                if alias in cand:
                    return cand.index(alias)
        return None

    def values(q, kind=None):
        k = find(q)
        if k is None:
            return None
        v = np.array([to_number(r[k]) if k < len(r) else np.nan for r in data])
        if kind is not None:
            unit = units[k]
            if not unit and header[k].lower().endswith(("_pa", "_pa_s", "_per_s", "_s")):
                unit = ""           # our own tidy names are SI
            v = v * _factor(kind, unit, where)
        return v

    stress, rate, visc = _complete(values("stress", "stress"), values("rate", "rate"),
                                   values("viscosity", "viscosity"), where)
    n = len(data)
    phi = values("phi")
    time = values("time", "time")
    point = values("point")
    torque = values("torque", "torque")
    k_int = find("interval")
    labels = np.array([r[k_int].strip() if k_int is not None and k_int < len(r) else ""
                       for r in data])
    keys = list(zip(labels, phi if phi is not None else [None] * n))
    order: list = []
    for key in keys:
        if key not in order and not (key[1] is not None and np.isnan(key[1])):
            order.append(key)
    curves = []
    for lab, ph in order:
        sel = np.array([k == (lab, ph) for k in keys])
        curves.append(Curve(str(path), lab or "table",
                            point[sel] if point is not None else np.arange(1.0, sel.sum() + 1),
                            time[sel] if time is not None else np.full(sel.sum(), np.nan),
                            rate[sel], stress[sel], visc[sel],
                            torque[sel] if torque is not None else None, None,
                            None if ph is None else np.full(sel.sum(), float(ph))))
    if phi is not None and np.isnan(phi).any():
        bad = int(np.isnan(phi).sum())
        raise ValueError(f"{where}: the phi column has {bad} blank or non-numeric cell(s)")
    return curves


# ------------------------------------------------------------------ registry and entry point
#: format name -> (detector on decoded text, reader); detectors are tried in order, the last is
#: the fallback.
READERS: dict[str, tuple[Callable[[str], bool], Callable[..., list[Curve]]]] = {
    "rheocompass": (is_rheocompass, read_rheocompass),
    "csv": (lambda text: True, read_table),
}


def detect_format(text: str) -> str:
    """The first format of :data:`READERS` whose detector accepts the decoded text."""
    for name, (detect, _) in READERS.items():
        if detect(text):
            return name
    return "csv"  # pragma: no cover


def clean(curve: Curve, torque_floor: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Flag the bad points of one curve.

    Returns
    -------
    kept : bool array
    reason : object array of str ('' where kept), one of :data:`DROP_REASONS`.

    The ramp direction is the sign of the median stress step of the kept points; a point that
    repeats a previous stress (to 1e-9 relative) is a ``duplicate``, one that steps against the
    ramp past the running extreme is ``non_monotone``.
    """
    n = curve.shear_stress.size
    reason = np.array([""] * n, dtype=object)

    def mark(mask, why):
        sel = mask & (reason == "")
        reason[sel] = why

    s, r, v = curve.shear_stress, curve.shear_rate, curve.viscosity
    mark(~(np.isfinite(s) & np.isfinite(r) & np.isfinite(v)), "missing_value")
    floor = np.zeros(n, dtype=bool)
    if curve.flagged is not None:
        floor |= curve.flagged
    if torque_floor is not None and curve.torque_mNm is not None:
        floor |= np.abs(np.nan_to_num(curve.torque_mNm, nan=np.inf)) < torque_floor
    mark(floor, "below_torque_floor")
    with np.errstate(invalid="ignore"):
        mark(r <= 0, "nonpositive_rate")
        mark(s <= 0, "nonpositive_stress")
        mark(v <= 0, "nonpositive_viscosity")
    ok = np.flatnonzero(reason == "")
    if ok.size >= 2:
        steps = np.diff(np.log(s[ok]))
        direction = 1.0 if np.median(steps) >= 0 else -1.0
        seen: list[float] = []
        extreme = None
        for k in ok:
            x = direction * np.log(s[k])
            if any(abs(x - y) <= 1e-9 for y in seen):
                reason[k] = "duplicate"
                continue
            if extreme is not None and x < extreme:
                reason[k] = "non_monotone"
                continue
            seen.append(x)
            extreme = x
    return reason == "", reason


def read_flow_curves(paths: Sequence, *, fmt: str = "auto", columns: dict[str, str] | None = None,
                     phi: Sequence[float] | None = None, intervals: Sequence[str] | None = None,
                     torque_floor: float | None = None, mass_fraction: dict | None = None,
                     require_phi: bool = True) -> pd.DataFrame:
    """Read measured flow curves from files into one tidy table (:data:`COLUMNS`).

    Parameters
    ----------
    paths : sequence of path-like
        Data files (any mix of formats).
    fmt : str
        ``"auto"`` (detect from the content) or a key of :data:`READERS`.
    columns : dict, optional
        Column mapping for the csv reader (see :func:`read_table`).
    phi : sequence of float, optional
        One volume fraction per file, in order, for files that carry none (a phi column wins
        where present; giving both for such a file is an error).
    intervals : sequence of str, optional
        RheoCompass result names to keep (substrings; default :data:`DEFAULT_INTERVALS`).
    torque_floor : float, optional
        Readings with |torque| below this [mN m] are dropped as ``below_torque_floor``
        (instrument-flagged ME- readings are always dropped).
    mass_fraction : dict, optional
        If given, the phi values are mass fractions phi_W, converted to volume fractions with
        Eq. (20): keys ``rho_cs``, ``rho_l`` [kg/m^3] (required), ``rho_w`` (1000), ``lam``
        (0.3), ``beta`` (0.1).
    require_phi : bool
        Raise if a file's volume fraction is unknown (else phi is NaN there).

    Returns
    -------
    pandas.DataFrame
        The tidy table; ``attrs["formats"]`` maps each file to the format read.

    Raises
    ------
    ValueError
        A file missing, unreadable or with no usable curve (named), a --phi count that does not
        match the files, a phi outside (0, 1).
    """
    from .checks import check_range
    from .steady import phi_from_mass_fraction

    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("no data files given")
    if fmt != "auto" and fmt not in READERS:
        raise ValueError(f"--format = {fmt!r} must be auto or one of {', '.join(READERS)}")
    if phi is not None and len(phi) != len(paths):
        raise ValueError(f"--phi has {len(phi)} value(s) for {len(paths)} file(s): give one per "
                         "file, in order")
    for p in paths:
        if not p.is_file():
            raise ValueError(f"data file {str(p)!r} not found")
    frames, formats = [], {}
    for i, p in enumerate(paths):
        text = read_text(p)
        kind = detect_format(text) if fmt == "auto" else fmt
        formats[str(p)] = kind
        reader = READERS[kind][1]
        kwargs = dict(intervals=intervals)
        if kind == "csv":
            kwargs["columns"] = columns
        curves = reader(p, text, **kwargs)
        usable = 0
        for c in curves:
            if c.phi is not None and phi is not None:
                raise ValueError(f"data file {p.name!r} has a phi column and --phi was given too: "
                                 "use one")
            if c.phi is not None:
                ph = c.phi
            elif phi is not None:
                ph = np.full(c.shear_stress.size, float(phi[i]))
            else:
                if require_phi:
                    raise ValueError(f"data file {p.name!r} carries no volume fraction: give "
                                     "--phi, one per file in order (or map a phi column with "
                                     "--columns phi=NAME)")
                ph = np.full(c.shear_stress.size, np.nan)
            if mass_fraction is not None and np.isfinite(ph).all():
                ph = phi_from_mass_fraction(ph, **mass_fraction) * np.ones_like(ph)
            if np.isfinite(ph).all():
                check_range("phi", ph, 0.0, 1.0, lo_closed=False, hi_closed=False,
                            note=f"data file {p.name}")
            kept, why = clean(c, torque_floor)
            usable += int(kept.sum() >= 3)
            frames.append(pd.DataFrame({
                "source_file": p.name, "interval": c.interval, "phi": np.asarray(ph, float),
                "point": c.point, "time_s": c.time_s, "shear_rate_per_s": c.shear_rate,
                "shear_stress_Pa": c.shear_stress, "viscosity_Pa_s": c.viscosity,
                "kept": kept, "dropped_reason": why}))
        if usable == 0:
            raise ValueError(f"data file {p.name!r} has no usable flow curve (fewer than 3 good "
                             "points in every interval read)")
    out = pd.concat(frames, ignore_index=True)[list(COLUMNS)]
    out.attrs["formats"] = formats
    return out


def drop_counts(table: pd.DataFrame) -> dict[str, int]:
    """Number of dropped points per reason (only reasons that occur), in :data:`DROP_REASONS`
    order."""
    counts = table.loc[~table["kept"], "dropped_reason"].value_counts()
    return {k: int(counts[k]) for k in DROP_REASONS if k in counts}


def describe(table: pd.DataFrame) -> str:
    """A short text: curves read, points kept, dropped per reason."""
    groups = table.groupby(["source_file", "interval", "phi"], sort=False, dropna=False)
    kept = int(table["kept"].sum())
    counts = drop_counts(table)
    text = (f"read {groups.ngroups} curve(s) from {table['source_file'].nunique()} file(s): "
            f"{kept} point(s) kept, {len(table) - kept} dropped")
    if counts:
        text += " (" + ", ".join(f"{k}: {v}" for k, v in counts.items()) + ")"
    return text


def table_to_csv_frame(table: pd.DataFrame) -> pd.DataFrame:
    """The tidy table ready for :func:`rheology.io.atomic_write_csv` (non-finite numbers of
    dropped points blanked; empty-ok columns listed in :data:`EMPTY_OK`)."""
    out = table.copy()
    for c in ("phi", "point", "time_s", "shear_rate_per_s", "shear_stress_Pa", "viscosity_Pa_s"):
        v = out[c].to_numpy(dtype=float)
        out[c] = np.where(np.isfinite(v), v, np.nan)
    return out


#: Columns of the tidy table that may be empty (unknown phi or time, a blank cell of a dropped
#: point).
EMPTY_OK: tuple[str, ...] = ("phi", "point", "time_s", "shear_rate_per_s", "shear_stress_Pa",
                             "viscosity_Pa_s")


# ------------------------------------------------------------------ writing (examples, tests)
def write_rheocompass(path, curves: Iterable[dict], *, project: str = "synthetic",
                      test: str = "flow curve") -> Path:
    """Write curves in the layout of a RheoCompass text export (UTF-16 LE with BOM, CRLF).

    Each dict has ``name`` (the ``Result:`` name), ``stress`` [Pa], ``rate`` [1/s] and optional
    ``status`` (list of str, e.g. ``"Dy_auto,ME-"``), ``time`` [s]. Used for the shipped example
    exports and the tests of the reader. Written atomically.
    """
    lines = [f"Project:\t{project}", "", f"Test:\t{test}", ""]
    head = ("Interval data:\tPoint No.\tTime\tShear Rate\tShear Stress\tViscosity\tTorque\t"
            "Normal Force\tGap\tTemperature\tStatus")
    for k, c in enumerate(curves, start=1):
        s, r = np.asarray(c["stress"], float), np.asarray(c["rate"], float)
        status = c.get("status") or ["Dy_auto"] * s.size
        t = c.get("time")
        t = np.arange(1, s.size + 1) * 6.0 if t is None else np.asarray(t, float)
        lines += [f"Result:\t{c['name']}", "", f"Interval and data points:\t{k}\t{s.size}", head,
                  "\t" * 10, "\t\t[s]\t[1/s]\t[Pa]\t[Pa·s]\t[mN·m]\t[N]\t[mm]\t[°C]\t"]
        for i in range(s.size):
            def g(x):
                return "" if not np.isfinite(x) else f"{x:.5g}"
            lines.append(f"\t{i + 1}\t{g(t[i])}\t{g(r[i])}\t{g(s[i])}\t"
                         f"{g(s[i] / r[i] if r[i] != 0 else np.nan)}\t{g(s[i] * 0.0368)}\t-0.03\t"
                         f"1.000\t20\t{status[i]}")
        lines.append("")
    path = Path(path)
    text = "\r\n".join(lines) + "\r\n"
    from .io import atomic_write_bytes

    return atomic_write_bytes(path, b"\xff\xfe" + text.encode("utf-16-le"))
