"""Material points: one set per body or phase, structure-of-arrays storage.

Every set carries the kinematic arrays (``id, x, v, C, m, V, svol, stress, sp, L``, optional
``fext``) plus the arrays its material adds (``f``, ``rho_f``, ``pf``, ...). All per-point arrays
have the number of points as first dimension, so sorting, checkpoints and snapshots treat them
uniformly.

Units: x [m], v [m/s], C and L [1/s], m [kg], V [m^3] (per radian in axisymmetry: m and V are
the per-radian values r A rho and r A), stress [Pa] (tension positive, 3 x 3 with index 2 the
out-of-plane z or hoop theta direction).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from runkit.params import check_range
from rheology.numba_cache import guard

from .kernels import PARALLEL_MIN_POINTS, dual

guard(__file__)

#: arrays every set has (name -> trailing shape)
CORE = {"id": (), "x": (2,), "v": (2,), "C": (2, 2), "m": (), "V": (), "svol": (),
        "stress": (3, 3), "sp": (4,), "L": (5,)}


class ParticleSet:
    """A set of material points made of one material.

    Parameters
    ----------
    name : str
        Label used in outputs (``disk_left``, ``grains``, ``fluid``...).
    material : material object from :mod:`mpm2d.materials`
    x : (N, 2) array
        Positions [m] (r, z in axisymmetry).
    area : (N,) array or float
        In-plane area represented by each point [m^2]. The volume is ``area`` (plane strain, per
        unit thickness) or ``area * r`` (axisymmetry, per radian).
    v : (N, 2) array, optional
        Initial velocity [m/s].
    stress : (N, 3, 3) or (3, 3) array, optional
        Initial stress [Pa].
    phi : float or (N,) array, optional
        Granular volume fraction around the points: for a granular phase the grains' fraction
        (mass phi rho_s V), for fluid points of a two-phase run the fraction of the grains they
        flow through (mass (1 - phi) rho_f V). Defaults: 1 for an elastic body, 0 for a fluid;
        required for the suspension law.
    fext : (N, 2) array, optional
        Constant external force on each point [N] (per unit thickness or per radian), e.g. a
        surface traction times the point's face length.
    fext_offset : (N, 2) array, optional
        Where the force acts relative to the point [m]. For a surface traction give the offset
        to the point's outer face (half the point spacing along the outward normal): the
        particle quadrature of the internal force places the boundary there, so a uniformly
        stressed body is then in exact discrete equilibrium with its load.
    axisymmetric : bool
    **state
        Material state arrays (e.g. ``f`` for the suspension law).
    """

    def __init__(self, name, material, x, area, *, v=None, stress=None, phi=None, fext=None,
                 fext_offset=None, axisymmetric=False, **state):
        x = np.ascontiguousarray(np.asarray(x, dtype=float).reshape(-1, 2))
        n = x.shape[0]
        if n == 0:
            raise ValueError(f"particle set {name!r} has no points")
        check_range(f"{name}: x", x)
        area = check_range(f"{name}: area", np.broadcast_to(np.asarray(area, float), (n,)), 0.0,
                           None, lo_closed=False)
        if axisymmetric:
            check_range(f"{name}: r", x[:, 0], 0.0, None, lo_closed=False,
                        note="axisymmetric points must lie off the axis")
        self.name, self.material, self.axisymmetric = name, material, axisymmetric
        self.arrays: dict[str, np.ndarray] = {}
        self.arrays["id"] = np.arange(n, dtype=np.int64)
        self.arrays["x"] = x
        self.arrays["v"] = _as(v, (n, 2), f"{name}: v")
        self.arrays["C"] = np.zeros((n, 2, 2))
        self.arrays["V"] = np.ascontiguousarray(area * (x[:, 0] if axisymmetric else 1.0))
        self.arrays["stress"] = _as(stress, (n, 3, 3), f"{name}: stress")
        if not np.allclose(self.stress, np.swapaxes(self.stress, 1, 2)):
            raise ValueError(f"{name}: stress must be symmetric")
        self.arrays["sp"] = np.zeros((n, 4))
        self.arrays["L"] = np.zeros((n, 5))
        if fext is None:
            self.arrays["fext"] = np.zeros((0, 4))
        else:
            f4 = np.zeros((n, 4))
            f4[:, :2] = _as(fext, (n, 2), f"{name}: fext")
            if fext_offset is not None:
                f4[:, 2:] = _as(fext_offset, (n, 2), f"{name}: fext_offset")
            self.arrays["fext"] = f4
        if phi is None:
            phi = material.default_phi
            if phi is None:
                raise ValueError(f"{name}: give phi, the volume fraction of grains")
        material.initialise(self, np.array(np.broadcast_to(np.asarray(phi, float), (n,))),
                            **state)

    # array access as attributes: ps.x, ps.stress, ...
    def __getattr__(self, key):
        arrays = self.__dict__.get("arrays")
        if arrays is not None and key in arrays:
            return arrays[key]
        raise AttributeError(key)

    def __setattr__(self, key, value):
        # ``ps.v *= a`` rebinds ps.v after the in-place product: route it to the arrays, never
        # to an instance attribute that would shadow arrays["v"] (and survive a checkpoint load)
        arrays = self.__dict__.get("arrays")
        if arrays is not None and key in arrays:
            arrays[key] = value
        else:
            object.__setattr__(self, key, value)

    def __len__(self) -> int:
        return self.arrays["x"].shape[0]

    @property
    def phase(self) -> str:
        return self.material.phase

    def per_point(self) -> dict[str, np.ndarray]:
        """Every per-point array (first dimension = number of points)."""
        n = len(self)
        return {k: a for k, a in self.arrays.items() if a.ndim and a.shape[0] == n}

    def permute(self, order: np.ndarray) -> None:
        """Reorder every per-point array (used to keep points sorted by base node); the gather
        runs on numba's threads (the engine re-sorts every few steps: a serial copy of every
        array would be a serial section of the step)."""
        order = np.ascontiguousarray(order, dtype=np.int64)
        par = nb.get_num_threads() > 1 and len(order) >= PARALLEL_MIN_POINTS
        for k, a in self.per_point().items():
            a2 = np.ascontiguousarray(a).reshape(len(order), -1)
            out = np.empty_like(a2)
            _gather_rows[par](a2, order, out)
            self.arrays[k] = out.reshape(a.shape)

    # ------------------------------------------------------------------ swirl
    #: per-point arrays of the out-of-plane (azimuthal) velocity, see :meth:`enable_swirl`
    SWIRL = {"vtheta": (), "Cl": (2,), "Lw": (2,), "spw": (2,)}

    @property
    def swirl(self) -> bool:
        """Whether the set carries the azimuthal velocity v_theta (:meth:`enable_swirl`)."""
        return "vtheta" in self.arrays

    def enable_swirl(self, v_theta=0.0) -> None:
        """Give the set the azimuthal velocity of an axisymmetric run with swirl.

        Adds ``vtheta`` (N,) v_theta [m/s], ``Cl`` (N, 2) the APIC affine part of the angular
        momentum per unit mass l = r v_theta [m/s], ``Lw`` (N, 2) the swirl velocity gradient
        (L_theta_r, L_theta_z) = (dv_theta/dr - v_theta/r, dv_theta/dz) [1/s] in the basis that
        turns with the point (physical components; the basis rotation v_theta/r is taken out, so
        a rigid rotation has zero rate and zero spin) and ``spw`` (N, 2) the stress
        (sigma_r_theta, sigma_theta_z) [Pa] for the torque. No-op if already enabled (a value
        given then is refused, to keep a checkpoint's state).
        """
        if not self.axisymmetric:
            raise ValueError(f"{self.name}: swirl (v_theta) needs an axisymmetric set")
        n = len(self)
        if self.swirl:
            return
        self.arrays["vtheta"] = _as(v_theta, (n,), f"{self.name}: v_theta")
        self.arrays["Cl"] = np.zeros((n, 2))
        self.arrays["Lw"] = np.zeros((n, 2))
        st = self.stress
        self.arrays["spw"] = np.ascontiguousarray(np.stack([st[:, 0, 2], st[:, 1, 2]], axis=1))

    def kinetic_energy(self) -> float:
        """sum 1/2 m (|v|^2 + v_theta^2) [J] (per unit thickness, or per radian)."""
        ke = float(0.5 * np.sum(self.m * np.einsum("ij,ij->i", self.v, self.v)))
        if self.swirl:
            ke += float(0.5 * np.sum(self.m * self.vtheta ** 2))
        return ke

    def momentum(self) -> np.ndarray:
        return (self.m[:, None] * self.v).sum(axis=0)


@dual
def _gather_rows(a, order, out):
    """out[i] = a[order[i]] for (N, k) arrays."""
    for i in nb.prange(order.shape[0]):
        for j in range(a.shape[1]):
            out[i, j] = a[order[i], j]


def _as(value, shape, name):
    if value is None:
        return np.zeros(shape)
    arr = np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=float), shape).copy())
    check_range(name, arr)
    return arr
