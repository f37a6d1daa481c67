"""Hypothesis strategies: random valid parameter sets and states of the model."""

from __future__ import annotations

from hypothesis import strategies as st

import rheology as r


def _log(lo, hi):
    return st.floats(lo, hi).map(lambda e: 10.0 ** e)


@st.composite
def materials(draw, buckling=True, transient=True, inertia=None):
    """A random valid Material (SI units): any structure, optional buckling and grain inertia."""
    phi_j = draw(st.floats(0.45, 0.70))
    phi_c = phi_j - draw(st.floats(0.01, 0.15))
    a0 = draw(st.floats(0.3, 2.0))
    kw = dict(name="random", citation="hypothesis", phi_c=phi_c, phi_j=phi_j, a0=a0,
              a_inf=a0 * draw(st.floats(1.0, 2.0)), mu_c=draw(st.floats(0.1, 1.5)),
              tau_star=draw(_log(-2, 3)), eta0=draw(_log(-3, 0)), Delta=draw(st.floats(0, 1)))
    if buckling and draw(st.booleans()) or buckling == "always":
        kw.update(varphi1=draw(_log(0, 8)), alpha1=draw(st.floats(0.5, 8.0)))
        if draw(st.booleans()):
            kw.update(varphi2=draw(_log(-3, 1)), alpha2=draw(st.floats(0.0, 1.0)))
    use_inertia = draw(st.booleans()) if inertia is None else inertia
    if use_inertia:
        kw.update(d=draw(_log(-6.5, -4)), rho_s=draw(st.floats(1000, 3000)))
    if transient:
        G = draw(_log(4, 8))
        kw.update(G=G, K=G * draw(st.floats(1.0, 3.0)), K0=draw(_log(-2, 0.5)))
    return r.Material(**kw)


@st.composite
def material_and_phi(draw, lo=0.2, **kw):
    """A material and a volume fraction in [lo phi_j, phi_j) (steady flow possible)."""
    m = draw(materials(**kw))
    phi = draw(st.floats(lo, 0.999)) * m.phi_j
    return m, min(phi, m.phi_j * (1 - 1e-9))
