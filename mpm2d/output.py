"""Run outputs: snapshots (npz + manifest), VTK XML unstructured grids, checkpoints.

Layout of a run folder ``DIR`` (every file written atomically through :mod:`rheology.io`)::

    DIR/manifest.json          scene, parameters, mode, grid, sets, fields with units, frames
    DIR/history.csv            one row per record: time_s, step, dt_s, energies [J], momentum,
                               scene columns (units in the names)
    DIR/frames/frame_NNNNN.npz snapshot N: ``time_s``, ``step``, ``dt_s`` and, per set S,
                               ``S.id, S.x, S.v, S.stress, S.V, S.m`` and the material's fields
                               (``S.phi``, ``S.f``, ``S.pressure_Pa``...); per rigid body B,
                               ``body.B.x`` (points), ``body.B.center``, ``body.B.velocity``
    DIR/vtk/S_NNNNN.vtu        the same points and fields for ParaView (VTK XML UnstructuredGrid,
                               one vertex cell per point, base64 binary, coordinates (x, y, 0) or
                               (r, z, 0)); DIR/vtk/S.pvd is the time series (open it in ParaView)
    DIR/checkpoint.npz         full state to resume bit-for-bit (``mpm2d run ... --resume``)
    DIR/*.png, DIR/*.csv       the scene's figures and result tables

Units: SI (m, s, kg, Pa, J); masses, volumes, energies and momenta are per unit thickness in
plane strain and per radian in axisymmetry.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np

from rheology.io import atomic_write_text, save_checkpoint

UNITS = {"id": "-", "x": "m", "v": "m/s", "stress": "Pa", "V": "m^3 (per m or per rad)",
         "m": "kg (per m or per rad)", "phi": "-", "f": "-", "pressure_Pa": "Pa",
         "granular_pressure_Pa": "Pa", "pore_pressure_Pa": "Pa", "taubar_Pa": "Pa",
         "shear_rate_p_per_s": "1/s", "case": "0 elastic, 1 separated, 2 shear flow, "
         "3 shear flow + compaction", "rho_f": "kg/m^3"}
_VTK_TYPES = {np.dtype(np.float64): "Float64", np.dtype(np.int64): "Int64"}


def snapshot_arrays(sim) -> dict[str, np.ndarray]:
    """Every output array of a snapshot, keyed ``set.field`` / ``body.name.field``."""
    out = {"time_s": np.array(sim.t), "step": np.array(sim.step_count),
           "dt_s": np.array(sim.last_dt)}
    for s in sim.sets:
        fields = {"id": s.id, "x": s.x, "v": s.v, "stress": s.stress, "V": s.V, "m": s.m}
        fields.update(s.material.output_fields(s))
        for k, a in fields.items():
            out[f"{s.name}.{k}"] = np.asarray(a)
    for b in sim.bodies:
        out[f"body.{b.name}.x"] = b.x
        out[f"body.{b.name}.center"] = b.center
        out[f"body.{b.name}.velocity"] = b.velocity
        out[f"body.{b.name}.omega"] = np.array(b.omega)
    return out


def write_npz(path: Path, arrays: dict) -> Path:
    """Atomic uncompressed npz."""
    return save_checkpoint(path, **arrays)


def _b64(arr: np.ndarray) -> str:
    data = np.ascontiguousarray(arr).tobytes()
    return base64.b64encode(np.array([len(data)], dtype=np.uint64).tobytes() + data).decode()


def vtu_text(points: np.ndarray, fields: dict[str, np.ndarray]) -> str:
    """VTK XML UnstructuredGrid of vertex cells with point data (base64 binary, UInt64 header).

    ``points`` (N, 2) or (N, 3); each field (N,), (N, k) or (N, 3, 3) (written as 9 components,
    ParaView's tensor layout). Integer fields are written as Int64.
    """
    n = points.shape[0]
    pts = np.zeros((n, 3))
    pts[:, :points.shape[1]] = points
    def arr_xml(name, a):
        a = np.asarray(a)
        if a.dtype not in _VTK_TYPES:
            a = a.astype(np.float64)
        comps = int(np.prod(a.shape[1:])) if a.ndim > 1 else 1
        if comps == 2:                       # ParaView vectors need 3 components
            a = np.concatenate([a.reshape(n, 2), np.zeros((n, 1))], axis=1)
            comps = 3
        return (f'<DataArray type="{_VTK_TYPES[a.dtype]}" Name="{name}" '
                f'NumberOfComponents="{comps}" format="binary">{_b64(a.reshape(n, comps))}'
                "</DataArray>")
    pd = "".join(arr_xml(k, a) for k, a in fields.items())
    conn = np.arange(n, dtype=np.int64)
    return ('<?xml version="1.0"?>\n'
            '<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" '
            'header_type="UInt64">\n<UnstructuredGrid>\n'
            f'<Piece NumberOfPoints="{n}" NumberOfCells="{n}">\n'
            f'<PointData>{pd}</PointData>\n'
            f'<Points>{arr_xml("Points", pts)}</Points>\n'
            f'<Cells>{arr_xml("connectivity", conn)}{arr_xml("offsets", conn + 1)}'
            f'<DataArray type="UInt8" Name="types" NumberOfComponents="1" format="binary">'
            f'{_b64(np.ones(n, dtype=np.uint8))}</DataArray></Cells>\n'
            '</Piece>\n</UnstructuredGrid>\n</VTKFile>\n')


def read_vtu(path) -> dict[str, np.ndarray]:
    """Read back a file written by :func:`vtu_text` (used by the tests)."""
    import xml.etree.ElementTree as ET

    root = ET.parse(path).getroot()
    types = {"Float64": np.float64, "Int64": np.int64, "UInt8": np.uint8}
    out = {}
    for el in root.iter("DataArray"):
        raw = base64.b64decode(el.text)
        nbytes = int(np.frombuffer(raw[:8], dtype=np.uint64)[0])
        a = np.frombuffer(raw[8:8 + nbytes], dtype=types[el.get("type")])
        k = int(el.get("NumberOfComponents", 1))
        out[el.get("Name")] = a.reshape(-1, k) if k > 1 else a
    return out


def write_vtu(path: Path, points, fields) -> Path:
    return atomic_write_text(path, vtu_text(points, fields))


def write_pvd(path: Path, entries: list[tuple[float, str]]) -> Path:
    """ParaView collection (time series) of .vtu files: entries (time_s, relative path)."""
    rows = "".join(f'<DataSet timestep="{t:.9g}" part="0" file="{f}"/>\n' for t, f in entries)
    return atomic_write_text(path, '<?xml version="1.0"?>\n<VTKFile type="Collection" '
                             'version="0.1"><Collection>\n' + rows + "</Collection></VTKFile>\n")


def write_frame(out: Path, index: int, sim, vtk: bool = True, tag: str = "frame") -> dict:
    """Write snapshot ``index`` (npz and, if ``vtk``, one .vtu per set); returns its entry.

    ``tag``: ``frame`` for the regular snapshots, ``event`` for those a scene asked for."""
    arrays = snapshot_arrays(sim)
    npz = Path("frames") / f"frame_{index:05d}.npz"
    write_npz(out / npz, arrays)
    entry = {"index": index, "time_s": sim.t, "step": sim.step_count, "npz": str(npz), "vtu": {},
             "tag": tag}
    if vtk:
        for s in sim.sets:
            prefix = f"{s.name}."
            fields = {k[len(prefix):]: a for k, a in arrays.items()
                      if k.startswith(prefix) and k != f"{s.name}.x"}
            vtu = Path("vtk") / f"{s.name}_{index:05d}.vtu"
            write_vtu(out / vtu, s.x, fields)
            entry["vtu"][s.name] = str(vtu)
        for b in sim.bodies:
            vtu = Path("vtk") / f"{b.name}_{index:05d}.vtu"
            write_vtu(out / vtu, b.x, {"velocity": np.tile(b.velocity, (b.x.shape[0], 1))})
            entry["vtu"][b.name] = str(vtu)
    return entry


def load_frames(out, tag: str | None = None) -> list[dict]:
    """The snapshots of a run folder (optionally only those with ``tag``), as dicts of arrays,
    read from ``out/manifest.json``'s frame list (time order)."""
    out = Path(out)
    manifest = json.loads((out / "manifest.json").read_text())
    frames = []
    for f in manifest["frames"]:
        if tag is None or f.get("tag", "frame") == tag:
            with np.load(out / f["npz"], allow_pickle=False) as data:
                frames.append({k: data[k] for k in data.files})
    return frames


def write_pvds(out: Path, frames: list[dict]) -> None:
    """One .pvd time series per set/body from the frames' vtu entries."""
    names = sorted({n for f in frames for n in f.get("vtu", {})})
    for n in names:
        entries = [(f["time_s"], Path(f["vtu"][n]).name) for f in frames if n in f.get("vtu", {})]
        write_pvd(out / "vtk" / f"{n}.pvd", entries)


def write_manifest(out: Path, manifest: dict) -> Path:
    return atomic_write_text(out / "manifest.json", json.dumps(manifest, indent=1, default=_jsonable))


def _jsonable(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    return str(o)


__all__ = ["snapshot_arrays", "write_frame", "write_pvds", "write_manifest", "vtu_text",
           "read_vtu", "load_frames", "UNITS"]
