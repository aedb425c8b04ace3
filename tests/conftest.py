"""Shared fixtures: paper configurations for the core and its reference."""

from __future__ import annotations

import numpy as np
import pytest

from sc_rt import _core

# The built-in laws by name (the core registers them; test_laws.py checks the registry).
LAWS = {"dsc-ppc": "dsc-ppc", "dsc": "dsc", "pd": "pd", "rft": "rft"}

# The paper's initial condition (docs/MODEL.md section 8).
SIGMA0 = np.array([0.323, -0.194, -0.388])
OMEGA0 = np.array([-0.01, 0.02, -0.03])


def core_config(law: str = "dsc-ppc", rate: float = 10.0) -> _core.ControllerConfig:
    """The C++ defaults are the paper's values (docs/MODEL.md section 8)."""
    c = _core.ControllerConfig()
    c.law = LAWS[law]
    c.control_rate_hz = rate
    return c


def reference_params(c: _core.ControllerConfig) -> dict:
    """The same parameters as plain dicts for tests/refmath.RefController."""
    sc = c.spacecraft
    g = c.guidance
    p = c.ppc
    n = c.neso
    return dict(
        sc=dict(J0=np.array(sc.J0), Cbar=np.array(sc.Cbar), Jw=np.array(sc.Jw),
                umin=np.array(sc.umin), umax=np.array(sc.umax), w0=sc.w0),
        g=dict(sigma_d0=np.array(g.sigma_d0), bias=np.array(g.omega_bias),
               cos=np.array(g.omega_cos), sin=np.array(g.omega_sin), freq=g.omega_freq),
        ppc_p=dict(chi0=np.array(p.chi0), chiinf=np.array(p.chiinf), gamma=np.array(p.gamma),
                   dmin=np.array(p.dmin), dmax=np.array(p.dmax)),
        neso=dict(k1=np.array(n.k1), k2=np.array(n.k2), k3=np.array(n.k3), k4=np.array(n.k4),
                  alpha=n.alpha, substeps=n.substeps, init_from_measurement=n.init_from_measurement),
        dsc=dict(k1=c.dsc.k1, k2=c.dsc.k2, k3=c.dsc.k3, k4=c.dsc.k4, tau=c.dsc.tau),
        pd=dict(beta1=c.pd.beta1, beta2=c.pd.beta2),
        rft=dict(c=c.rft.c, k=c.rft.k, gain=c.rft.gain, leak=c.rft.leak, phi=c.rft.phi,
                 rho0=c.rft.rho0),
        rate=c.control_rate_hz,
    )


def measurement(t, sigma, omega, wheel=None) -> _core.Measurement:
    return _core.Measurement(t, np.asarray(sigma, float), np.asarray(omega, float),
                             np.zeros(4) if wheel is None else np.asarray(wheel, float))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20191001)


def pytest_collection_modifyitems(items):
    """Tests that need the out-of-tree plugin builds (the ``plugins`` fixture of
    test_laws.py: a cmake build of every example plugin, 10-20 s once) are slow."""
    for item in items:
        if "plugins" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(autouse=True)
def _close_figures():
    """Figures a test keeps open to inspect (tests/figcheck.py, test_figures.py)
    are closed after it, as matplotlib's own suite does: otherwise they pile up
    across the session and pyplot's more-than-20-figures warning (an error
    here, filterwarnings) fails an unrelated later test."""
    yield
    import sys

    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        plt.close("all")
