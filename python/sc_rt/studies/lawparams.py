"""The built-in laws' parameters as the studies read them: a law's table
resolved with its defaults (``ControllerParams.resolved``), as attributes,
for the analyses that are about one law (the DSC's Theorem 1 and observer
conditions, the sampled-data design). The values are the ones the C++ law
runs with; their names are that law's (cpp/src/law_dsc.cpp, law_pd.cpp)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from sc_rt import _core

__all__ = ["dsc_gains", "neso_params", "neso_core", "pd_gains"]


def dsc_gains(scn, law: str = "dsc-ppc") -> SimpleNamespace:
    """k1, k2, k3, k4, k6, tau of a DSC law (dsc-ppc or dsc) of ``scn``."""
    p = scn.controller.resolved(law)
    return SimpleNamespace(**{k: float(p[k]) for k in ("k1", "k2", "k3", "k4", "k6", "tau")})


def neso_params(scn, law: str = "dsc-ppc") -> SimpleNamespace:
    """The observer's k1..k4 (3-vectors), alpha, substeps and
    init_from_measurement of a DSC law of ``scn``."""
    p = scn.controller.resolved(law)
    vec = {k: np.broadcast_to(np.asarray(p[f"neso_{k}"], float), (3,)).copy() for k in ("k1", "k2", "k3", "k4")}
    return SimpleNamespace(**vec, alpha=float(p["neso_alpha"]), substeps=int(p["neso_substeps"]),
                           init_from_measurement=bool(p["neso_init_from_measurement"]))


def neso_core(scn, law: str = "dsc-ppc") -> _core.NesoParams:
    """The same as the core's ``NesoParams`` (for ``neso_condition_26``, ``Neso``)."""
    n, out = neso_params(scn, law), _core.NesoParams()
    out.k1, out.k2, out.k3, out.k4 = n.k1, n.k2, n.k3, n.k4
    out.alpha, out.substeps, out.init_from_measurement = n.alpha, n.substeps, n.init_from_measurement
    return out


def pd_gains(scn) -> SimpleNamespace:
    """beta1, beta2 of the PD law of ``scn``."""
    p = scn.controller.resolved("pd")
    return SimpleNamespace(beta1=float(p["beta1"]), beta2=float(p["beta2"]))
