"""Measured curves from rheometer files: readers, cleaning, and one tidy table.

:func:`read_flow_curves` (columns :data:`COLUMNS`) and :func:`read_relaxation_curves` (stress
relaxation after cessation of shear, :data:`RELAXATION_COLUMNS`) read any mix of files into one
table, one row per measured point; a dropped point keeps its row with ``kept`` false and a
``dropped_reason`` (:data:`DROP_REASONS`, counted by :func:`drop_counts`).

Each format of :data:`READERS` parses a file into *blocks* (an interval, procedure step or action:
name, column names, units, rows), detected from the content, never the extension. A block's
columns are found by name (:data:`ALIASES`; units by :func:`unit_factor`: Pa, mPa, kPa, MPa; Pa s,
mPa s, cP; 1/s, s-1; s, min, ms; mN m, uN m, N m; %) and its name says whether it is a flow curve
or a relaxation (:func:`step_kind`); the others are listed in ``table.attrs["skipped"]`` with the
reason. The vendors publish no specification; the layouts as assumed here (blank lines, extra
columns and missing units tolerated):

- ``rheocompass``: Anton Paar RheoCompass text (UTF-16 or UTF-8, tabs): ``Result:`` names,
  ``Interval and data points:``, ``Interval data:`` column names, a units row (``[Pa]``), the
  points (first cell empty); ``ME-`` in the ``Status`` column marks readings below torque range.
- ``trios``: TA Instruments TRIOS "Export to LIMS" text (tabs, any 8-bit or Unicode encoding):
  ``key<TAB>value`` header lines in bracketed sections (the geometry's ``Stress constant``, e.g.
  ``59683.1 Pa/N.m``, converts torque to stress), then per ``[step]``: its name (``Flow sweep -
  3``), optionally ``Number of points<TAB>N``, column names, units (``Pa``, ``1/s``, ``Pa.s``,
  ``s``, ``µN.m``) and the points, up to a blank or bracketed line.
- ``trios-csv``: the same comma separated, each step introduced by a row holding only its name
  (or a ``[step]`` row, then its name); known by a TRIOS header key (``Filename``, ``Geometry
  name``, ``Stress constant``, ...) as a ``key,value`` row and a ``Shear rate`` or ``Step time``
  column.
- ``rspace``: Malvern rSpace (Kinexus) CSV: ``key,value`` preamble rows, then one table whose
  column names carry units in parentheses (``Shear stress(Pa)``, ``Shear rate(s-¹)``) and whose
  ``Action Name`` column names each row's action (consecutive rows of one action are a block);
  comma or semicolon separated; known by such a name with an ``Action Name`` or ``Shear
  viscosity`` column or an ``s-¹`` unit (or rSpace/Kinexus in the preamble).
- ``csv``: a plain delimited table (comma, semicolon or tab) with a header row, mapped with
  ``columns={"stress": NAME, ...}`` (keys of :data:`ALIASES`) or by common names; an
  ``interval`` or ``phi`` column splits it into curves. Tried last; a file in none of these
  layouts is refused in one line naming them.

Cells may use a decimal comma. Volume fractions: from a phi column, else ``phi=[...]`` one per
file; mass fractions are converted with Eq. (20) of the Supplement
(:func:`rheology.steady.phi_from_mass_fraction`).
"""

from __future__ import annotations

import bisect
import csv
import io
import re
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from itertools import groupby
from pathlib import Path

import numpy as np
import pandas as pd

from runkit.io import atomic_write_bytes, check_input_file
from runkit.params import check_range

from .steady import phi_from_mass_fraction

#: Columns of the tidy flow-curve table, in order (units in the names).
COLUMNS: tuple[str, ...] = ("source_file", "interval", "phi", "point", "time_s",
                            "shear_rate_per_s", "shear_stress_Pa", "viscosity_Pa_s", "kept",
                            "dropped_reason")

#: Columns of the tidy relaxation table (``interval``: the block's name; ``curve``: 0, 1, ... in
#: order of reading; ``time_s``: the block's own clock).
RELAXATION_COLUMNS: tuple[str, ...] = ("source_file", "interval", "curve", "point", "time_s",
                                       "shear_stress_Pa", "kept", "dropped_reason")

#: Columns of the tidy tables that may be empty (unknown phi or time, a blank cell of a dropped
#: point).
EMPTY_OK: tuple[str, ...] = ("phi", "point", "time_s", "shear_rate_per_s", "shear_stress_Pa",
                             "viscosity_Pa_s")

#: Why a point is dropped (checked in this order; the first that applies is recorded).
DROP_REASONS: dict[str, str] = {
    "missing_value": "a blank or non-numeric stress, rate, viscosity or time",
    "below_torque_floor": "flagged by the instrument (status ME-) or torque below --torque-floor",
    "nonpositive_rate": "shear rate <= 0",
    "nonpositive_stress": "shear stress <= 0",
    "nonpositive_viscosity": "viscosity <= 0",
    "below_stress_floor": "stress below --stress-floor (relaxation: the instrument's noise)",
    "duplicate": "the same stress (flow curve) or time (relaxation) as an earlier point",
    "non_monotone": "breaks the curve's stress ramp or clock (a step against its direction)",
}

#: Names of the RheoCompass results read by default as flow curves (case-insensitive
#: substrings); every name :func:`step_kind` calls a flow curve is read too.
DEFAULT_INTERVALS: tuple[str, ...] = ("viscosity curve", "flow curve")

#: Unit text (spaces, dots, '·' removed; superscripts as digits) -> factor to SI, per quantity.
#: Exact case first ("MPa" is mega, "mPa" milli), then case-insensitively (lower case: milli).
_UNITS = {
    "stress": {"Pa": 1.0, "mPa": 1e-3, "kPa": 1e3, "MPa": 1e6, "": 1.0},
    "viscosity": {"Pas": 1.0, "mPas": 1e-3, "cP": 1e-3, "P": 0.1, "": 1.0},
    "rate": {"1/s": 1.0, "s-1": 1.0, "1/min": 1 / 60.0, "": 1.0},
    "time": {"s": 1.0, "min": 60.0, "h": 3600.0, "ms": 1e-3, "": 1.0},
    "torque": {"mNm": 1.0, "µNm": 1e-3, "uNm": 1e-3, "Nm": 1e3, "nNm": 1e-6, "": 1.0},  # mN m
    "fraction": {"": 1.0, "-": 1.0, "%": 1e-2},
    "stress_constant": {"Pa/Nm": 1.0, "Pa/(Nm)": 1.0, "1/m3": 1.0, "m-3": 1.0,      # Pa/(N m)
                        "Pa/mNm": 1e3, "Pa/µNm": 1e6, "Pa/uNm": 1e6},
}

#: Recognised column names (lower case, unit stripped), per quantity, in order of preference.
ALIASES: dict[str, tuple[str, ...]] = {
    "stress": ("shear stress", "stress", "shear_stress_pa", "shear_stress", "tau", "sigma"),
    "rate": ("shear rate", "shear_rate_per_s", "shear_rate", "rate", "gdot", "gamma_dot"),
    "viscosity": ("viscosity", "shear viscosity", "viscosity_pa_s", "apparent viscosity", "eta"),
    "phi": ("phi", "volume_fraction", "volume fraction"),
    "time": ("step time", "time", "time_s", "t", "interval time", "test time"),
    "point": ("point no.", "point", "point no", "index"),
    "torque": ("torque", "torque_mnm"),
    "interval": ("interval",),
    "status": ("status",),
}
_KIND = {"stress": "stress", "rate": "rate", "viscosity": "viscosity", "time": "time",
         "torque": "torque", "phi": "fraction"}
_KNOWN = {a for q in ("stress", "rate", "viscosity", "time", "torque") for a in ALIASES[q]}

#: How a block's name decides what it is: (kind, words, reason); the first match decides.
_STEP_KINDS = (
    ("skip", ("amplitude", "frequency", "oscillat", "time sweep"),
     "an oscillatory test (moduli, not a steady flow curve)"),
    ("relaxation", ("relaxation",), "a stress relaxation (read by rheometer fit-relaxation)"),
    ("skip", ("temperature",), "a temperature ramp at one rate, not a flow curve"),
    ("flow", ("flow sweep", "flow ramp", "flow curve", "viscosity curve", "steady state flow",
              "stepped flow", "shear rate ramp", "shear stress ramp", "shear rate table",
              "shear stress table", "viscometry", "ramp"), ""),
    ("skip", ("peak hold", "constant", "creep", "recovery", "start-up", "startup"),
     "a transient at one rate or stress, not a flow curve"),
    ("skip", ("pre-shear", "preshear", "conditioning", "equilibrat", "soak"),
     "conditioning or pre-shear"),
)


def step_kind(name: str) -> tuple[str, str]:
    """``(kind, reason)`` of a block from its name: kind ``"flow"`` (flow sweep or ramp, viscosity
    curve, shear rate/stress ramp or table), ``"relaxation"`` or ``"skip"`` with the reason."""
    low = name.lower()
    return next(((k, why) for k, words, why in _STEP_KINDS if any(w in low for w in words)),
                ("skip", "not recognised as a flow curve (flow sweep or ramp, viscosity curve, "
                         "shear rate or stress ramp); --interval NAME reads it as one"))


@dataclass
class Block:
    """One block of a file (an interval, procedure step or action) as read: the column names
    (units stripped) and units as in the file, the rows as text cells, and the file's header
    (lower-case keys) for constants such as TRIOS's stress constant."""

    name: str
    header: list[str]
    units: list[str]
    rows: list[list[str]]
    meta: dict = field(default_factory=dict)


@dataclass
class Curve:
    """One measured flow curve as read from a file, before cleaning.

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
    for nul, enc in ((1, "utf-16-le"), (0, "utf-16-be")):
        if len(raw) > 3 and raw[nul:nul + 1] == raw[nul + 2:nul + 3] == b"\x00":
            return raw.decode(enc)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")              # decodes every byte


_NUM = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?$")


def to_number(cell) -> float:
    """A cell as float: exponent notation and a decimal comma accepted; blank or text -> NaN."""
    s = str(cell).strip().replace("\u2212", "-")
    return float(s.replace(",", ".")) if _NUM.match(s) else float("nan")


def unit_factor(kind: str, unit: str, where: str) -> float:
    """Factor from ``unit`` to SI for a quantity kind of ``_UNITS`` (torque: to mN m; a stress
    constant: to Pa/(N m)). Raises ValueError naming ``where`` and the known units."""
    key = unit.strip()
    key = key[1:-1] if re.match(r"^(\[.*\]|\(.*\))$", key) else key
    for a, b in (("μ", "µ"), ("⁻", "-"), ("¹", "1"), ("³", "3"), ("^", "")):
        key = key.replace(a, b)
    key, table = re.sub(r"[\s·*.\u00b7]", "", key), _UNITS[kind]
    low = {k.lower(): v for k, v in reversed(list(table.items()))}   # 'mpa' -> milli
    if key in table or key.lower() in low:
        return table.get(key, low.get(key.lower()))
    raise ValueError(f"{where}: unit [{unit.strip('[]()')}] of the {kind.replace('_', ' ')} "
                     f"column is not understood; known: {', '.join(k for k in table if k)}")


def _cells(text: str, delim: str) -> list[list[str]]:
    return [[c.strip() for c in row] for row in csv.reader(io.StringIO(text), delimiter=delim)]


def _numeric(row) -> bool:
    return any(np.isfinite(to_number(c)) for c in row)


# ------------------------------------------------------------------ RheoCompass
_RC_HEADS = ("Result:", "Interval data:", "Interval and data points:", "Test:", "Project:")


def rheocompass_blocks(text: str, columns=None) -> list[Block]:
    """The ``Interval data:`` blocks of a RheoCompass export, named ``"<Result> (interval N)"``."""
    rows = [[c.strip() for c in line.split("\t")] for line in text.splitlines()]
    blocks, result, number = [], "", ""
    for i, (head, *rest) in enumerate(rows):
        if head == "Result:":
            result, number = (rest[0] if rest else ""), ""
        elif head == "Interval and data points:":
            number = rest[0] if rest else ""
        elif head == "Interval data:":
            units, data = None, []
            for cells in rows[i + 1:]:            # a units row ([Pa]), then the points
                body = cells[1:]
                if cells[0] in _RC_HEADS or (data and not any(cells)):
                    break
                if units is None and any(x.startswith("[") for x in body):
                    units = body
                elif any(body) and units is not None:
                    data.append(body)
            name = result + (f" (interval {number})" if number else "")
            blocks.append(Block(name, rest, units or [""] * len(rest), data))
    return blocks


# ------------------------------------------------------------------ TRIOS (text and CSV)
def _is_header(row) -> bool:
    """A row of column names: no number, and three names or more, or two of which one is a
    known quantity (a ``key,value`` header row has two cells)."""
    names = [c.lower() for c in row if c]
    return (not _numeric(row) and len(names) >= 2
            and (len(names) >= 3 or any(n in _KNOWN for n in names)))


def trios_blocks(text: str, columns=None, delim: str = "\t") -> list[Block]:
    """The procedure steps of a TRIOS export (``[step]`` blocks, or in a CSV a row holding only
    the step's name followed by column names and units); the header's ``key value`` rows are
    each block's ``meta`` (a value and its unit in two cells are joined)."""
    rows = _cells(text.replace("\ufeff", ""), delim)
    meta: dict[str, str] = {}
    blocks: list[Block] = []
    i, n = 0, len(rows)

    def skip(k):                  # the next row that is not blank
        while k < n and not any(rows[k]):
            k += 1
        return k

    def body(k):                  # the step's column names, past an optional point count
        k = skip(k)
        return skip(k + 1) if k < n and rows[k][:1] == ["Number of points"] else k

    while i < n:
        full = [c for c in rows[i] if c]
        one = len(full) == 1 and not full[0].startswith("[")
        if len(full) == 1 and full[0].lower() == "[step]":
            k = skip(i + 1)
            name, i = (rows[k][0] if k < n else ""), k + 1
        elif one and body(i + 1) < n and _is_header(rows[body(i + 1)]):
            name, i = full[0], i + 1
        else:
            if len(full) >= 2 and not full[0].startswith("["):
                meta[full[0].lower()] = " ".join(full[1:])
            i += 1
            continue
        i = body(i)
        header = rows[i] if i < n else []
        i += 1
        units = [""] * len(header)
        if i < n and any(rows[i]) and not _numeric(rows[i]):
            units, i = rows[i], i + 1
        start = i                 # the points: up to a blank, bracketed or text row
        while i < n and any(rows[i]) and not rows[i][0].startswith("[") and _numeric(rows[i]):
            i += 1
        blocks.append(Block(name, header, units, rows[start:i], meta))
    return blocks


def stress_constant(meta: dict, where: str) -> float:
    """TRIOS's geometry stress constant [Pa/(N m)] from the header (``Stress constant``, value
    and unit). Raises ValueError saying why torque cannot be converted when it is absent."""
    text = meta.get("stress constant")
    if not text:
        raise ValueError(f"{where} records torque but no stress: the file's header gives no "
                         "'Stress constant' (TRIOS geometry section) to convert it; export the "
                         "Stress column, or give a table of time and stress")
    m = re.match(r"^\s*(\S+)\s*(.*)$", text)
    value = to_number(m.group(1)) if m else float("nan")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{where}: the header's stress constant {text!r} is not a positive "
                         "number")
    return value * unit_factor("stress_constant", m.group(2) or "Pa/N.m", where)


# ------------------------------------------------------------------ rSpace and plain tables
_UNIT_IN_NAME = re.compile(r"^(.*?)\s*[\[(]([^\])]*)[\])]\s*$")


def _split_units(row: list[str]) -> tuple[list[str], list[str]]:
    """Column names with their units (``Shear stress(Pa)``, ``Time [s]``) as (names, units)."""
    split = [_UNIT_IN_NAME.match(c) for c in row]
    return ([m.group(1).strip() if m else c for m, c in zip(split, row)],
            [m.group(2).strip() if m else "" for m in split])


def rspace_blocks(text: str, columns=None) -> list[Block]:
    """The actions of an rSpace table (consecutive rows of one ``Action Name``; the whole table
    when it has no such column), the preamble's ``key,value`` rows as ``meta``."""
    best = None                   # (rows, index of the header): the widest of , and ;
    for delim in (",", ";"):
        rows = _cells(text.replace("\ufeff", ""), delim)
        k = next((i for i, r in enumerate(rows)
                  if sum(bool(_UNIT_IN_NAME.match(c)) for c in r) >= 2), None)
        if k is not None and (best is None or len(rows[k]) > len(best[0][best[1]])):
            best = (rows, k)
    if best is None:
        return []
    rows, k = best
    meta = {r[0].lower(): " ".join(c for c in r[1:] if c) for r in rows[:k] if len(r) >= 2 and r[0]}
    header, units = _split_units(rows[k])
    low = [h.lower() for h in header]
    act = next((low.index(a) for a in ("action name", "action", "step name") if a in low), None)

    def action(r):
        return (r[act] if act is not None and act < len(r) else "") or meta.get("sequence", "table")

    blocks, seen = [], Counter()
    for name, data in groupby((r for r in rows[k + 1:] if any(r)), key=action):
        seen[name] += 1
        label = name if seen[name] == 1 else f"{name} ({seen[name]})"
        blocks.append(Block(label, header, units, list(data), meta))
    return blocks


def _table_lines(text: str) -> tuple[list[str], str]:
    """The lines that are neither blank nor ``#`` comments, and the delimiter of the first (the
    most frequent of tab, semicolon and comma)."""
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    return lines, (max(("\t", ";", ","), key=lines[0].count) if lines else ",")


def _is_table(text: str) -> bool:
    lines, delim = _table_lines(text)
    return (len(lines) >= 2 and lines[0].count(delim) > 0
            and any(_numeric(ln.split(delim)) for ln in lines[1:6]))


def table_blocks(text: str, columns: dict[str, str] | None = None) -> list[Block]:
    """A delimited table as blocks: one per (interval, phi) group when it has such columns
    (located as :func:`column_index` does, with the same ``columns`` mapping)."""
    lines, delim = _table_lines(text)
    rows = _cells("\n".join(lines), delim)
    header, units = _split_units(rows[0])
    probe = Block("table", header, units, rows[1:], {"_full": rows[0]})
    keys = [column_index(probe, q, columns) for q in ("interval", "phi")]
    groups: dict[tuple, list] = {}
    for r in rows[1:]:
        groups.setdefault(tuple(r[k] if k is not None and k < len(r) else "" for k in keys),
                          []).append(r)
    return [Block(key[0] or "table", header, units, g, {"_full": rows[0]})
            for key, g in groups.items()]


# ------------------------------------------------------------------ the formats
_TRIOS_KEYS = ("filename", "instrument serial number", "instrument name", "instrument type",
               "geometry name", "stress constant", "proceduresegments")


def _matches(*patterns: str, head: int | None = None):
    """A detector: every pattern found in the decoded text (its first ``head`` characters)."""
    return lambda text: all(re.search(p, text[:head]) for p in patterns)


#: format -> (detector on the decoded text, block parser(text, columns), the layout as named in
#: a refusal), tried in order (the layouts: the module's docstring).
READERS: dict[str, tuple] = {
    "rheocompass": (_matches("Interval data:"), rheocompass_blocks, "RheoCompass text export"),
    "trios": (_matches(r"(?im)^\s*\[step\]\s*$", "\t"), trios_blocks,
              "TRIOS 'Export to LIMS' text"),
    "trios-csv": (_matches(r"(?im)^\ufeff?\"?(" + "|".join(_TRIOS_KEYS) + r")\"?\s*,",
                           r"(?im)(^|,)\"?(shear rate|step time)\"?(,|$)"),
                  lambda text, columns=None: trios_blocks(text, delim=","), "TRIOS CSV export"),
    "rspace": (_matches(r"(?i)shear (stress|rate|viscosity)\s*\(",
                        r"(?i)action name|shear viscosity|s-¹|s⁻¹|rspace|kinexus", head=20000),
               rspace_blocks, "rSpace CSV export"),
    "csv": (_is_table, table_blocks, "plain table (a header row, then rows of numbers)"),
}


def detect_format(text: str, name: str = "") -> str:
    """The first format of :data:`READERS` whose detector accepts the decoded text; ValueError
    (one line naming the layouts tried) when none does."""
    fmt = next((f for f, (detect, *_) in READERS.items() if detect(text)), None)
    if fmt is None:
        raise ValueError(f"data file {name!r} is in none of the known layouts (tried: "
                         f"{'; '.join(r[2] for r in READERS.values())})")
    return fmt


def read_blocks(path, *, fmt: str = "auto", columns: dict[str, str] | None = None,
                text: str | None = None) -> tuple[str, list[Block]]:
    """``(format, blocks)`` of one file (format detected from the content unless given)."""
    text = read_text(path) if text is None else text
    kind = detect_format(text, Path(path).name) if fmt == "auto" else fmt
    blocks = READERS[kind][1](text, columns=columns)
    if not blocks:
        raise ValueError(f"data file {Path(path).name!r}: no data block found in its {kind} "
                         "layout")
    return kind, blocks


def select_blocks(blocks: list[Block], kind: str, intervals: Sequence[str] | None, fmt: str,
                  name: str) -> tuple[list[Block], list[tuple[str, str]]]:
    """The blocks to read as ``kind`` ("flow" or "relaxation") and ``(name, reason)`` of the
    others: chosen by ``intervals`` (substrings of the name) if given, else by
    :func:`step_kind` (RheoCompass flow curves also by :data:`DEFAULT_INTERVALS`); every block of
    a plain table. ValueError listing the blocks and reasons when none is chosen."""
    if fmt == "csv":
        return blocks, []
    chosen, skipped = [], []
    wanted = [w.lower() for w in intervals or []]
    for b in blocks:
        k, why = step_kind(b.name)
        low = b.name.lower()
        if wanted:
            ok = any(w in low for w in wanted)
            why = f"not named like {' or '.join(map(repr, wanted))}"
        else:
            ok = k == kind or (kind == "flow" and any(w in low for w in DEFAULT_INTERVALS))
            if k == "flow" and not ok:
                why = "a flow curve (read by rheometer read and fit)"
        if ok and not b.rows:
            ok, why = False, "no data rows"
        (chosen.append(b) if ok else skipped.append((b.name, why)))
    if not chosen:
        what = "flow curve" if kind == "flow" else "stress relaxation"
        found = "; ".join(f"{n!r} ({w})" for n, w in skipped)
        raise ValueError(f"data file {name!r} has no {what} block; found {found} (choose with "
                         "--interval NAME)")
    return chosen, skipped


# ------------------------------------------------------------------ columns of a block
def column_index(block: Block, quantity: str, columns: dict[str, str] | None = None,
                 where: str = "") -> int | None:
    """Index of a quantity's column: the mapped name (``columns``, matched with or without its
    unit) or the first of :data:`ALIASES` present; None if absent. A mapped name that is not a
    column raises ValueError listing the columns."""
    shown = block.meta.get("_full", block.header)
    cands = [[h.strip().lower() for h in hs] for hs in (shown, block.header)]
    mapped = bool(columns) and quantity in columns
    for name in ([columns[quantity].strip().lower()] if mapped else ALIASES[quantity]):
        for cand in cands:
            if name in cand:
                return cand.index(name)
    if mapped:
        raise ValueError(f"{where or 'data file'}: --columns {quantity}={columns[quantity]!r} is "
                         f"not a column; columns: {', '.join(shown)}")
    return None


def block_values(block: Block, quantity: str, where: str,
                 columns: dict[str, str] | None = None) -> np.ndarray | None:
    """A quantity's column in SI (torque in mN m; a fraction as a fraction), NaN for blank or
    text cells; None if the block has no such column."""
    k = column_index(block, quantity, columns, where)
    if k is None:
        return None
    v = np.array([to_number(r[k]) if k < len(r) else np.nan for r in block.rows], dtype=float)
    if quantity in _KIND:
        v = v * unit_factor(_KIND[quantity], block.units[k] if k < len(block.units) else "", where)
    return v


def _ratio(a, b):
    """a / b, NaN where b is 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(b != 0, a / np.where(b != 0, b, 1.0), np.nan)


def block_curve(block: Block, source: str, columns: dict[str, str] | None = None) -> Curve:
    """A block as a flow curve (SI; the third of stress, rate and viscosity from the other two);
    ValueError naming the file and block when it lacks two of them or has a unit not
    understood."""
    where = f"data file {Path(source).name!r}, {block.name}"
    n = len(block.rows)

    def get(q):
        return block_values(block, q, where, columns)

    s, r, v = get("stress"), get("rate"), get("viscosity")
    if sum(x is not None for x in (s, r, v)) < 2:
        raise ValueError(f"{where}: needs two of shear stress, shear rate and viscosity "
                         "(map them with --columns stress=NAME rate=NAME viscosity=NAME)")
    with np.errstate(divide="ignore", invalid="ignore"):
        s = v * r if s is None else s
    r, v = (_ratio(s, v) if r is None else r), (_ratio(s, r) if v is None else v)
    point, time = get("point"), get("time")
    return Curve(source, block.name, point if point is not None else np.arange(1.0, n + 1),
                 time if time is not None else np.full(n, np.nan), r, s, v,
                 get("torque"), _status_me(block), get("phi"))


def _status_me(block: Block) -> np.ndarray:
    """Rows whose status holds an ``ME`` flag (RheoCompass ``ME-``: below the torque range)."""
    k = column_index(block, "status")
    return np.array([k is not None and k < len(r) and any(
        s.strip().upper().startswith("ME") for s in r[k].split(",")) for r in block.rows], bool)


# ------------------------------------------------------------------ cleaning
def clean(curve: Curve, torque_floor: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Flag the bad points of one flow curve.

    Returns
    -------
    kept : bool array
    reason : object array of str ('' where kept), one of :data:`DROP_REASONS`.

    The ramp direction is the sign of the median stress step of the kept points; a point that
    repeats a previous stress (to 1e-9 relative) is a ``duplicate``, one that steps against the
    ramp past the running extreme is ``non_monotone``.
    """
    s, r, v = curve.shear_stress, curve.shear_rate, curve.viscosity
    reason = _reasons(s.size, [
        ("missing_value", ~(np.isfinite(s) & np.isfinite(r) & np.isfinite(v))),
        ("below_torque_floor", _below_floor(curve.flagged, curve.torque_mNm, torque_floor, s.size)),
        ("nonpositive_rate", r <= 0), ("nonpositive_stress", s <= 0),
        ("nonpositive_viscosity", v <= 0)])
    _monotone(np.log(np.where(reason == "", s, 1.0)), reason)
    return reason == "", reason


def _reasons(n: int, checks) -> np.ndarray:
    reason = np.array([""] * n, dtype=object)
    with np.errstate(invalid="ignore"):
        for why, mask in checks:
            reason[np.asarray(mask, bool) & (reason == "")] = why
    return reason


def _below_floor(flagged, torque, floor, n) -> np.ndarray:
    out = np.zeros(n, dtype=bool) if flagged is None else np.asarray(flagged, bool).copy()
    if floor is not None and torque is not None:
        out |= np.abs(np.nan_to_num(torque, nan=np.inf)) < floor
    return out


def _monotone(x: np.ndarray, reason: np.ndarray, direction: float | None = None) -> None:
    """Mark repeats (``duplicate``) and steps against the run's direction past its running
    extreme (``non_monotone``) among the points still kept; direction from the median step
    unless given."""
    ok = np.flatnonzero(reason == "")
    if ok.size < 2:
        return
    if direction is None:
        direction = 1.0 if np.median(np.diff(x[ok])) >= 0 else -1.0
    seen: list[float] = []                # accepted values, increasing
    for k in ok:
        y = direction * x[k]
        j = bisect.bisect_left(seen, y)
        if any(abs(y - seen[i]) <= 1e-9 * max(1.0, abs(y)) for i in (j - 1, j)
               if 0 <= i < len(seen)):
            reason[k] = "duplicate"
        elif seen and y < seen[-1]:
            reason[k] = "non_monotone"
        else:
            seen.append(y)


# ------------------------------------------------------------------ entry points
def _read(paths, fmt, columns, kind, intervals, per_file, label, frames_of, out_columns):
    """The tidy table of the files' blocks chosen as ``kind``: ``frames_of(index, path, blocks,
    frames so far)`` gives each file's frames; ``attrs`` record the formats and blocks skipped."""
    paths = [Path(p) for p in paths]
    if not paths:
        raise ValueError("no data files given")
    if fmt != "auto" and fmt not in READERS:
        raise ValueError(f"--format = {fmt!r} must be auto or one of {', '.join(READERS)}")
    if per_file is not None and len(per_file) != len(paths):
        raise ValueError(f"{label} has {len(per_file)} value(s) for {len(paths)} file(s): give "
                         "one per file, in order")
    for p in paths:
        check_input_file("data file", p)
    frames, formats, skipped = [], {}, []
    for i, p in enumerate(paths):
        formats[str(p)], blocks = read_blocks(p, fmt=fmt, columns=columns)
        chosen, skip = select_blocks(blocks, kind, intervals, formats[str(p)], p.name)
        skipped += [(p.name, n, why) for n, why in skip]
        frames += frames_of(i, p, chosen, len(frames))
    out = pd.concat(frames, ignore_index=True)[list(out_columns)]
    out.attrs.update(formats=formats, skipped=skipped)
    return out


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
        Column mapping for plain tables (keys of :data:`ALIASES`, values column names).
    phi : sequence of float, optional
        One volume fraction per file, in order, for files that carry none (a phi column wins
        where present; giving both for such a file is an error).
    intervals : sequence of str, optional
        Block names to read (substrings, case-insensitive); default: every flow-curve block
        (:func:`step_kind`; RheoCompass also :data:`DEFAULT_INTERVALS`).
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
        The tidy table; ``attrs["formats"]`` maps each file to the format read,
        ``attrs["skipped"]`` lists ``(file, block, reason)`` of the blocks not read.

    Raises
    ------
    ValueError
        A file missing, unreadable, in no known layout or with no usable curve (named), a --phi
        count that does not match the files, a phi outside (0, 1).
    """
    def frames_of(i, p, chosen, _):
        frames = []
        for b in chosen:
            c = block_curve(b, str(p), columns)
            if c.phi is not None and phi is not None:
                raise ValueError(f"data file {p.name!r} has a phi column and --phi was given "
                                 "too: use one")
            if c.phi is not None and np.isnan(c.phi).any():
                raise ValueError(f"data file {p.name!r}: the phi column has "
                                 f"{int(np.isnan(c.phi).sum())} blank or non-numeric cell(s)")
            if c.phi is None and phi is None and require_phi:
                raise ValueError(f"data file {p.name!r} carries no volume fraction: give --phi, "
                                 "one per file in order (or map a phi column with --columns "
                                 "phi=NAME)")
            ph = c.phi if c.phi is not None else np.full(
                c.shear_stress.size, np.nan if phi is None else float(phi[i]))
            if mass_fraction is not None and np.isfinite(ph).all():
                ph = phi_from_mass_fraction(ph, **mass_fraction) * np.ones_like(ph)
            if np.isfinite(ph).all():
                check_range("phi", ph, 0.0, 1.0, lo_closed=False, hi_closed=False,
                            note=f"data file {p.name}")
            frames.append(curve_table(c, ph, torque_floor, p.name))
        if not any(f["kept"].sum() >= 3 for f in frames):
            raise ValueError(f"data file {p.name!r} has no usable flow curve (fewer than 3 good "
                             "points in every block read)")
        return frames

    return _read(paths, fmt, columns, "flow", intervals, phi, "--phi", frames_of, COLUMNS)


def curve_table(c: Curve, phi, torque_floor: float | None = None,
                source: str | None = None) -> pd.DataFrame:
    """One curve cleaned (:func:`clean`) as rows of the tidy table (:data:`COLUMNS`); ``phi``
    a scalar or one per point, ``source`` the file name (default ``c.source_file``)."""
    kept, why = clean(c, torque_floor)
    return pd.DataFrame({
        "source_file": c.source_file if source is None else source, "interval": c.interval,
        "phi": np.asarray(phi, float), "point": c.point, "time_s": c.time_s,
        "shear_rate_per_s": c.shear_rate, "shear_stress_Pa": c.shear_stress,
        "viscosity_Pa_s": c.viscosity, "kept": kept, "dropped_reason": why})[list(COLUMNS)]


def read_relaxation_curves(paths: Sequence, *, fmt: str = "auto",
                           columns: dict[str, str] | None = None,
                           intervals: Sequence[str] | None = None,
                           torque_floor: float | None = None,
                           stress_floor: float | None = None) -> pd.DataFrame:
    """Read stress-relaxation curves (stress against time after cessation of shear) into one
    tidy table (:data:`RELAXATION_COLUMNS`).

    A block gives its stress column, else its torque converted with the file's geometry stress
    constant (TRIOS ``Stress constant``: :func:`stress_constant`), and its time column (TRIOS
    ``Step time`` first). Blocks are chosen as for flow curves (:func:`select_blocks`, kind
    "relaxation"; every block of a plain table). Dropped: blank cells, readings below the torque
    floor, stress <= 0 or below ``stress_floor`` [Pa], repeated times, times running backwards.

    Returns
    -------
    pandas.DataFrame
        ``attrs["formats"]`` and ``attrs["skipped"]`` as :func:`read_flow_curves`.

    Raises
    ------
    ValueError
        A file missing or in no known layout, a block without time, or with torque and no stress
        constant, fewer than 3 good points in a curve (each named).
    """
    def frames_of(_, p, chosen, start):
        frames = []
        for b in chosen:
            where = f"data file {p.name!r}, {b.name}"
            t, s, torque = (block_values(b, q, where, columns) for q in ("time", "stress",
                                                                          "torque"))
            if t is None or (s is None and torque is None):
                raise ValueError(f"{where}: no {'time' if t is None else 'stress or torque'} "
                                 f"column (columns: {', '.join(b.header)})")
            if s is None:
                s = torque * 1e-3 * stress_constant(b.meta, where)
            reason = _reasons(t.size, [
                ("missing_value", ~(np.isfinite(t) & np.isfinite(s))),
                ("below_torque_floor", _below_floor(_status_me(b), torque, torque_floor, t.size)),
                ("nonpositive_stress", s <= 0),
                ("below_stress_floor", s < (stress_floor or 0.0))])
            _monotone(np.where(reason == "", t, 0.0), reason, direction=1.0)
            if (reason == "").sum() < 3:
                why = ", ".join(f"{w}: {int((reason == w).sum())}" for w in DROP_REASONS
                                if (reason == w).any())
                raise ValueError(f"{where}: fewer than 3 good points ({why or 'no rows'})")
            point = block_values(b, "point", where, columns)
            frames.append(pd.DataFrame({
                "source_file": p.name, "interval": b.name, "curve": start + len(frames),
                "point": point if point is not None else np.arange(1.0, t.size + 1),
                "time_s": t, "shear_stress_Pa": s, "kept": reason == "",
                "dropped_reason": reason}))
        return frames

    return _read(paths, fmt, columns, "relaxation", intervals, None, "", frames_of,
                 RELAXATION_COLUMNS)


def drop_counts(table: pd.DataFrame) -> dict[str, int]:
    """Number of dropped points per reason (only reasons that occur), in :data:`DROP_REASONS`
    order."""
    counts = table.loc[~table["kept"], "dropped_reason"].value_counts()
    return {k: int(counts[k]) for k in DROP_REASONS if k in counts}


def describe(table: pd.DataFrame) -> str:
    """A short text: curves read, points kept, dropped per reason; then one line per block
    skipped, with the reason."""
    keys = ["source_file", "interval"] + (["phi"] if "phi" in table else [])
    kept, counts = int(table["kept"].sum()), drop_counts(table)
    text = (f"read {table.groupby(keys, sort=False, dropna=False).ngroups} curve(s) from "
            f"{table['source_file'].nunique()} file(s): {kept} point(s) kept, "
            f"{len(table) - kept} dropped")
    if counts:
        text += " (" + ", ".join(f"{k}: {v}" for k, v in counts.items()) + ")"
    return text + "".join(f"\n  skipped {f} {name!r}: {why}"
                          for f, name, why in table.attrs.get("skipped", []))


def table_to_csv_frame(table: pd.DataFrame) -> pd.DataFrame:
    """The tidy table ready for :func:`runkit.io.atomic_write_csv` (non-finite numbers of
    dropped points blanked; empty-ok columns listed in :data:`EMPTY_OK`)."""
    out = table.copy()
    for c in (c for c in EMPTY_OK if c in out):
        v = out[c].to_numpy(dtype=float)
        out[c] = np.where(np.isfinite(v), v, np.nan)
    return out


# ------------------------------------------------------------------ writing (examples, tests)
def _g(x) -> str:
    return "" if not np.isfinite(x) else f"{x:.6g}"


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
        t = np.asarray(c["time"] if c.get("time") is not None else np.arange(1, s.size + 1) * 6.0,
                       float)
        lines += [f"Result:\t{c['name']}", "", f"Interval and data points:\t{k}\t{s.size}", head,
                  "\t" * 10, "\t\t[s]\t[1/s]\t[Pa]\t[Pa·s]\t[mN·m]\t[N]\t[mm]\t[°C]\t"]
        lines += [f"\t{i + 1}\t{_g(t[i])}\t{_g(r[i])}\t{_g(s[i])}\t{_g(v)}\t{_g(s[i] * 0.0368)}"
                  f"\t-0.03\t1.000\t20\t{status[i]}" for i, v in enumerate(_ratio(s, r))]
        lines.append("")
    text = "\r\n".join(lines) + "\r\n"
    return atomic_write_bytes(path, b"\xff\xfe" + text.encode("utf-16-le"))


def write_export(path, layout: str, steps: Iterable[dict], header: dict) -> Path:
    """Write steps in one of the layouts this module reads (``"trios"``, ``"trios-csv"``,
    ``"rspace"``), for the shipped examples and the tests (written atomically).

    Parameters
    ----------
    steps : iterable of dict
        ``name`` (step or action name) and ``columns``: a list of ``(name, unit, values)``.
    header : dict
        ``{section: {key: value}}`` (section ``""`` before the first bracketed one; rSpace and
        TRIOS CSV write the keys without sections).

    The TRIOS text is Latin-1 with CRLF line ends, the CSVs UTF-8 with a BOM.
    """
    if layout not in ("trios", "trios-csv", "rspace"):
        raise ValueError(f"layout = {layout!r} must be trios, trios-csv or rspace")
    steps, bom = list(steps), b"\xef\xbb\xbf"
    if layout == "rspace":
        names = list(dict.fromkeys(f"{c[0]}({c[1]})" for st in steps for c in st["columns"]))
        out = io.StringIO()
        w = csv.writer(out, lineterminator="\r\n")
        w.writerows([[k, v] for items in header.values() for k, v in items.items()] + [[]])
        w.writerow(["Action Name", *names])
        for st in steps:
            cols = {f"{c[0]}({c[1]})": c[2] for c in st["columns"]}
            w.writerows([st["name"], *(_g(cols[k][i]) if k in cols else "" for k in names)]
                        for i in range(len(next(iter(cols.values())))))
        return atomic_write_bytes(path, bom + out.getvalue().encode())
    d = "\t" if layout == "trios" else ","
    lines = []
    for section, items in header.items():
        lines += ([f"[{section}]"] if section and layout == "trios" else [])
        lines += [f"{k}{d}{v}" for k, v in items.items()]
    for st in steps:
        cols, n = st["columns"], len(st["columns"][0][2])
        lines += ["[step]" if layout == "trios" else "", st["name"], f"Number of points{d}{n}",
                  d.join(c[0] for c in cols), d.join(c[1] for c in cols)]
        lines += [d.join(_g(c[2][i]) for c in cols) for i in range(n)]
    text = "\r\n".join(lines) + "\r\n"
    return atomic_write_bytes(path, text.encode("latin-1") if layout == "trios"
                              else bom + text.encode())
