"""Run outputs: snapshots (npz + manifest), VTK files through meshio, checkpoints.

Layout of a run folder ``DIR`` (every file written atomically through :mod:`runkit.io`)::

    DIR/manifest.json          scene, parameters, mode, grid, the sets' description, frames,
                               ``status`` (running, complete, ended_early, failed) and ``ends``
                               (where and why a run ended early, rheology.run_end)
                               (strict JSON; ``command`` is the canonical command of the run,
                               without the output folder, so a resumed run writes the same file)
    DIR/history.csv            one row per record: time_s, step (integer), dt_s, energies [J],
                               momentum, scene columns (units in the names)
    DIR/frames/frame_NNNNN.npz snapshot N: ``time_s``, ``step``, ``dt_s`` and, per set S,
                               ``S.id, S.x, S.v, S.stress, S.V, S.m`` and the material's fields
                               (``S.phi``, ``S.f``, ``S.pressure_Pa``...), the points ordered by
                               id in every frame; per rigid body B, ``body.B.x`` (points),
                               ``body.B.center``, ``body.B.velocity``
    DIR/vtk/S_NNNNN.vtu        the same points and fields for ParaView (VTK XML UnstructuredGrid
                               of vertex cells, written by meshio; coordinates (x, y, 0) or
                               (r, z, 0); vectors padded to 3 components, tensors as 9), in the
                               same order (by ``id``: point k of every frame is the same
                               material point), named with their units (:func:`vtu_name`:
                               ``velocity_m_per_s``, ``stress_Pa``, ``volume_m3_per_m`` (plane
                               strain; ``_per_rad`` axisymmetric), ``mass_kg_per_m``,
                               ``plastic_shear_rate_per_s``, ``fluid_density_kg_per_m3``...;
                               dimensionless ``phi``, ``f``), integers as integers (``id``,
                               ``case``: 0 elastic, 1 separated, 2 shear flow, 3 shear flow +
                               compaction)
    DIR/vtk/grid_NNNNN.vtu     the grid's nodal fields (the real nodes, quad cells): per velocity
                               field P (``solid``, ``fluid`` in two-phase runs)
                               ``P.velocity_m_per_s`` and ``P.mass_kg_per_m`` (or ``_per_rad``)
                               of the last step's grid update, ``phi`` (two-phase nodal volume
                               fraction), and each set's real scalar fields projected to the
                               nodes (mass-weighted B-spline average: ``S.pressure_Pa``,
                               ``S.f``, ``S.phi``...)
    DIR/vtk/NAME.pvd           the time series of each set, body and the grid (open in ParaView);
                               one entry per timestep
    DIR/checkpoint.npz         full state to resume bit-for-bit (``mpm2d run ... --resume``);
                               ``checkpoint.prev.npz`` is the one before (the fallback)
    DIR/*.png, DIR/*.csv       the scene's figures and result tables

A fresh run removes only the files a previous run of ours wrote (:meth:`RunFolder.listed`:
those its manifest lists, its checkpoints and the snapshots written after its last manifest);
a non-empty folder without our manifest is refused, nothing in it touched.

Units: SI (m, s, kg, Pa, J); masses, volumes, energies and momenta are per unit thickness in
plane strain and per radian in axisymmetry.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import meshio
import numpy as np

from runkit.io import atomic_savez, atomic_write_text, atomic_write_with
from runkit.run import Folder

from .grid import M, PAD


#: VTU names of the snapshot fields that carry no unit in their npz name ("{per}": per m in
#: plane strain, per rad in axisymmetry); the other names are kept (already ``_Pa``, or
#: dimensionless)
_VTU_NAMES = {"v": "velocity_m_per_s", "velocity": "velocity_m_per_s", "stress": "stress_Pa",
              "V": "volume_m3_{per}", "m": "mass_kg_{per}", "mass": "mass_kg_{per}",
              "rho_f": "fluid_density_kg_per_m3", "shear_rate_p_per_s": "plastic_shear_rate_per_s"}
#: integer fields (written as int32 whatever the material stores)
_INTEGER = ("id", "case")


def vtu_name(field: str, axisymmetric: bool) -> str:
    """The ParaView name of snapshot field ``field`` (``P.mass`` -> ``P.mass_kg_per_m``)."""
    head, _, last = field.rpartition(".")
    name = _VTU_NAMES.get(last, last).format(per="per_rad" if axisymmetric else "per_m")
    return f"{head}.{name}" if head else name


def snapshot_arrays(sim, fields=()) -> dict[str, np.ndarray]:
    """Every output array of a snapshot (``fields``: only those point fields besides ``id`` and
    ``x``; empty: all), keyed ``set.field`` / ``body.name.field``; the points of each set in
    the order of their ids (the engine re-sorts them in memory)."""
    out = {"time_s": np.array(sim.t), "step": np.array(sim.step_count),
           "dt_s": np.array(sim.last_dt)}
    for s in sim.sets:
        every = {"id": s.id, "x": s.x, "v": s.v, "stress": s.stress, "V": s.V, "m": s.m}
        every.update(s.material.output_fields(s))
        order = np.argsort(np.asarray(s.id), kind="stable")
        for k, a in every.items():
            if fields and k not in fields and k not in ("id", "x"):
                continue
            a = np.asarray(a)[order]
            out[f"{s.name}.{k}"] = a.astype(np.int32) if k in _INTEGER else a
    for b in sim.bodies:
        out[f"body.{b.name}.x"] = b.x
        out[f"body.{b.name}.center"] = b.center
        out[f"body.{b.name}.velocity"] = b.velocity
        out[f"body.{b.name}.omega"] = np.array(b.omega)
    return out


def write_npz(path: Path, arrays: dict) -> Path:
    """Atomic uncompressed npz (``np.savez`` stamps its members with a fixed date, so the bytes
    depend only on the arrays). Not :func:`runkit.io.save_checkpoint`: a snapshot rewritten by
    a resumed run keeps no ``.prev`` copy."""
    return atomic_savez(path, **arrays)


def _point_data(n: int, fields: dict) -> dict:
    out = {}
    for k, a in fields.items():
        a = np.asarray(a)
        if a.dtype.kind == "b":
            a = a.astype(np.int32)
        elif a.dtype.kind not in "iuf":
            a = a.astype(np.float64)
        a = a.reshape(n, -1) if a.ndim > 1 else a.reshape(n)
        if a.ndim == 2 and a.shape[1] == 2:          # ParaView vectors need 3 components
            a = np.concatenate([a, np.zeros((n, 1), dtype=a.dtype)], axis=1)
        out[k] = np.ascontiguousarray(a)
    return out


def _points3(points) -> np.ndarray:
    points = np.asarray(points, dtype=float)
    pts = np.zeros((points.shape[0], 3))
    pts[:, :points.shape[1]] = points
    return pts


def write_vtu(path: Path, points, fields: dict, cells=None) -> Path:
    """VTK XML UnstructuredGrid through meshio: ``points`` (N, 2) or (N, 3); ``fields`` point
    data, each (N,), (N, k) or (N, 3, 3) (written as 9 components, ParaView's tensor layout);
    ``cells`` a meshio cell list (default: one vertex cell per point)."""
    pts = _points3(points)
    n = pts.shape[0]
    if cells is None:
        cells = [("vertex", np.arange(n, dtype=np.int64).reshape(-1, 1))]
    mesh = meshio.Mesh(pts, cells, point_data=_point_data(n, fields))
    return atomic_write_with(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu",
                                                            binary=True), ".vtu")


def read_vtu(path) -> dict[str, np.ndarray]:
    """Point coordinates (``Points``) and point data of a .vtu file, read by meshio."""
    mesh = meshio.read(path, file_format="vtu")
    return {"Points": mesh.points, **{k: np.asarray(v) for k, v in mesh.point_data.items()}}


def write_pvd(path: Path, entries: list[tuple[float, str]]) -> Path:
    """ParaView collection (time series) of .vtu files: entries (time_s, relative path), one per
    timestep (a repeated time keeps its last file)."""
    unique: dict[str, str] = {}
    for t, f in entries:
        unique[f"{t:.17g}"] = f
    rows = "".join(f'<DataSet timestep="{t}" part="0" file="{f}"/>\n' for t, f in unique.items())
    return atomic_write_text(path, '<?xml version="1.0"?>\n<VTKFile type="Collection" '
                             'version="0.1"><Collection>\n' + rows + "</Collection></VTKFile>\n")


def bspline_weights(g):
    """Quadratic B-spline base node and the three weights at cell coordinates g (vectorised;
    the same formulas as :func:`mpm2d.shape.weights`)."""
    b = np.floor(g - 0.5)
    f = g - b
    return b.astype(np.int64), (0.5 * (1.5 - f) ** 2, 0.75 - (f - 1.0) ** 2, 0.5 * (f - 0.5) ** 2)


def project_to_nodes(grid, x, m, values: dict) -> dict:
    """Mass-weighted B-spline average of point scalars at the real nodes, shape (nx+1, ny+1)
    each: q_i = sum_p N_ip m_p q_p / sum_p N_ip m_p (NaN where no point reaches a node)."""
    shape = grid.shape
    gx = (x[:, 0] - grid.origin[0]) / grid.h
    gy = (x[:, 1] - grid.origin[1]) / grid.h
    bx, wx = bspline_weights(gx)
    by, wy = bspline_weights(gy)
    mass = np.zeros(shape)
    acc = {k: np.zeros(shape) for k in values}
    for a in range(3):
        for b in range(3):
            i = np.clip(bx + a + PAD, 0, shape[0] - 1)
            j = np.clip(by + b + PAD, 0, shape[1] - 1)
            w = wx[a] * wy[b] * m
            np.add.at(mass, (i, j), w)
            for k, q in values.items():
                np.add.at(acc[k], (i, j), w * q)
    real = (slice(PAD, PAD + grid.nx + 1), slice(PAD, PAD + grid.ny + 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return {k: np.where(mass[real] > 0, a[real] / mass[real], np.nan) for k, a in acc.items()}


def grid_fields(sim) -> dict[str, np.ndarray]:
    """The nodal fields of the real nodes, each (nx+1, ny+1[, k]): per velocity field
    ``P.velocity`` and ``P.mass``, ``phi`` (two-phase), and the sets' projected scalars."""
    g = sim.grid
    real = (slice(PAD, PAD + g.nx + 1), slice(PAD, PAD + g.ny + 1))
    out = {}
    for ph, vg in getattr(sim, "vg", {}).items():
        out[f"{ph}.velocity"] = np.asarray(vg)[real]
        if ph in getattr(sim, "G", {}):
            out[f"{ph}.mass"] = np.asarray(sim.G[ph])[real + (M,)]
    if getattr(sim, "two_phase", False) and getattr(sim, "phi_nodes", None) is not None:
        out["phi"] = np.asarray(sim.phi_nodes)[real]
    for s in sim.sets:
        scalars = {k: np.asarray(a, dtype=float) for k, a in s.material.output_fields(s).items()
                   if np.ndim(a) == 1 and np.asarray(a).dtype.kind == "f" and k not in _INTEGER}
        for k, a in project_to_nodes(g, s.x, s.m, scalars).items():
            out[f"{s.name}.{k}"] = a
    return out


def write_grid_vtu(path: Path, sim) -> Path:
    """The grid's real nodes as quad cells with :func:`grid_fields` as point data (meshio);
    nodes no point reaches hold 0 in the projected fields (VTK has no NaN-free 'missing')."""
    g = sim.grid
    nxn, nyn = g.nx + 1, g.ny + 1
    X, Y = np.meshgrid(g.origin[0] + g.h * np.arange(nxn), g.origin[1] + g.h * np.arange(nyn),
                       indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    idx = np.arange(nxn * nyn).reshape(nxn, nyn)
    quads = np.column_stack([idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(),
                             idx[:-1, 1:].ravel()]).astype(np.int64)
    fields = {}
    for k, a in grid_fields(sim).items():
        a = np.nan_to_num(np.asarray(a, dtype=float), nan=0.0)
        fields[vtu_name(k, g.axisymmetric)] = a.reshape(nxn * nyn, *a.shape[2:])
    return write_vtu(path, pts, fields, cells=[("quad", quads)])


def write_frame(out: Path, index: int, sim, vtk: bool = True, tag: str = "frame",
                fields=()) -> dict:
    """Write snapshot ``index`` (npz and, if ``vtk``, one .vtu per set); returns its entry.

    ``tag``: ``frame`` for the regular snapshots, ``event`` for those a scene asked for;
    ``fields``: the point fields kept (:func:`snapshot_arrays`)."""
    arrays = snapshot_arrays(sim, fields)
    npz = Path("frames") / f"frame_{index:05d}.npz"
    write_npz(out / npz, arrays)
    entry = {"index": index, "time_s": sim.t, "step": sim.step_count, "npz": str(npz), "vtu": {},
             "tag": tag}
    if vtk:
        axi = sim.grid.axisymmetric
        for s in sim.sets:
            prefix = f"{s.name}."
            fields = {vtu_name(k[len(prefix):], axi): a for k, a in arrays.items()
                      if k.startswith(prefix) and k != f"{s.name}.x"}
            vtu = Path("vtk") / f"{s.name}_{index:05d}.vtu"
            write_vtu(out / vtu, arrays[f"{s.name}.x"], fields)
            entry["vtu"][s.name] = str(vtu)
        for b in sim.bodies:
            vtu = Path("vtk") / f"{b.name}_{index:05d}.vtu"
            write_vtu(out / vtu, b.x, {"velocity_m_per_s": np.tile(b.velocity, (b.x.shape[0], 1))})
            entry["vtu"][b.name] = str(vtu)
        vtu = Path("vtk") / f"grid_{index:05d}.vtu"
        write_grid_vtu(out / vtu, sim)
        entry["vtu"]["grid"] = str(vtu)
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


def case_summaries(table, out):
    """(case, folder, summary dict) of each case of a sweep's ``table`` whose folder in ``out``
    holds a ``summary.json``, in the table's order (a scene's ``sweep_report`` reads them)."""
    for case in table["case"].astype(str):
        path = Path(out) / case / "summary.json"
        if path.exists():
            yield case, path.parent, json.loads(path.read_text())


def write_pvds(out: Path, frames: list[dict]) -> None:
    """One .pvd time series per set/body from the frames' vtu entries."""
    names = sorted({n for f in frames for n in f.get("vtu", {})})
    for n in names:
        entries = [(f["time_s"], Path(f["vtu"][n]).name) for f in frames if n in f.get("vtu", {})]
        write_pvd(out / "vtk" / f"{n}.pvd", entries)


__all__ = ["snapshot_arrays", "write_frame", "write_pvds", "write_vtu", "read_vtu",
           "write_grid_vtu", "grid_fields", "project_to_nodes", "load_frames", "vtu_name",
           "case_summaries", "RunFolder"]


# ---------------------------------------------------------------- the run folder
_FRAME = re.compile(r"frame_\d{5}\.npz$")
_VTU = re.compile(r"(.+)_\d{5}\.vtu")


class RunFolder(Folder):
    """The folder of an mpm2d run (the layout above, :class:`runkit.run.Folder`'s policy): a
    manifest of ours has ``scene``, ``params`` and ``frames``; a completed run keeps its
    checkpoint (``--resume`` of a report's sub-runs)."""

    subdirs = ("frames", "vtk")
    keeps_checkpoint = True

    def __init__(self, path):
        super().__init__(path, "mpm2d")

    def ours(self, manifest: dict) -> bool:
        return (isinstance(manifest.get("scene"), str) and isinstance(manifest.get("params"), dict)
                and isinstance(manifest.get("frames"), list))

    def listed(self, manifest: dict) -> list:
        """The files a previous run of ours wrote, which a fresh run removes: those its manifest
        lists (snapshots, their VTK files and .pvd series, figures and result tables), its
        checkpoints, history and manifest, and the snapshots written after its last manifest
        (``frames/frame_NNNNN.npz``, ``vtk/SET_NNNNN.vtu`` of its sets). Nothing else is
        touched."""
        files, names = [], set()
        for f in manifest["frames"]:
            if isinstance(f, dict):
                files += [f.get("npz"), *(f.get("vtu") or {}).values()]
                names.update(str(n) for n in f.get("vtu") or {})
        frames, vtk = self.path / "frames", self.path / "vtk"
        if frames.is_dir():
            files += [f"frames/{f.name}" for f in frames.iterdir() if _FRAME.match(f.name)]
        if vtk.is_dir():
            files += [f"vtk/{f.name}" for f in vtk.iterdir()
                      if (v := _VTU.fullmatch(f.name)) is not None and v.group(1) in names]
            files += [f"vtk/{n}.pvd" for n in names if "/" not in n]
        return files + ["checkpoint.npz", "checkpoint.prev.npz", "history.csv",
                        "manifest.json", *(manifest.get("figures", []) or []),
                        *(manifest.get("results", []) or [])]


def command_line(name: str, params: dict, defaults: dict, frames, vtk: bool,
                 vtk_default: bool = True) -> str:
    """The canonical command of a run (deterministic: no output folder, no --resume)."""
    sets = " ".join(f"--set {k}={v}" for k, v in params.items()
                    if k in defaults and v != defaults[k])
    return " ".join(filter(None, [f"mpm2d run {name}", sets,
                                  f"--frames {frames}" if frames is not None else "",
                                  "" if vtk == vtk_default else
                                  ("--vtk" if vtk else "--no-vtk")]))
