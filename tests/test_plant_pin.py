"""The pin of issue #28: the flight-like wheel model (``[wheels]``) and its
faults change nothing while they are off. Every shipped scenario's run
(sc_rt.simulate, both engines) hashes to the value main gave before the
model landed (the hashes below were taken from that code, not from this).

A change that means to alter a shipped run (a new scenario value, a fixed
model) updates its hash here, in the same commit, and says so.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from sc_rt import load_scenario, simulate
from sc_rt.scenario.shipped import shipped

#: the plant's state and what it applied, the controller's command and state
_FIELDS = ("sigma_BN", "omega_BN_B", "wheel_speed", "u_cmd", "u_sat", "wheel_accel", "delta2", "z2",
           "sigma_BD")

#: name -> (sha256 of the cpp engine's whole run, of the python engine's first 20 s), first 16 hex
PINS = {
    "mrp_feedback_requirements": ("26fc2129df481d39", "2012468fec51604a"),
    "paper_fault_free": ("9e28d71913a3412c", "3b96e7ffaba6fa47"),
    "paper_faults": ("d9bd6c36afa8466c", "97a1f3812739b31a"),
    "paper_faults_sensors": ("714562ed4b92c85d", "9f1a30737cbe2f30"),
    "ppc_feasible_100hz": ("9248b07955d0fd73", "75f595758d1f7efd"),
    "ppc_feasible_100hz_sensors": ("f564b5ada1d5752b", "ed76dfd1d80bcc34"),
    "ppc_feasible_10hz": ("ffc0492b35215caa", "34a6bcba9728407c"),
    "ppc_feasible_10hz_sensors": ("69d93dd674a747af", "91c002ed3f86700c"),
    "ppc_feasible_1khz": ("057ce232eed5a162", "8762a09c220c3aa2"),
    "ppc_feasible_1khz_sensors": ("8fecdc301c437c51", "212dff36d471f92b"),
    "slew_rest_to_rest": ("e0e8c6403d9f39ca", "b102cefb9a4c30b2"),
}


def _digest(run) -> str:
    h = hashlib.sha256()
    for name in _FIELDS:
        h.update(np.ascontiguousarray(run[name]).tobytes())
    return h.hexdigest()[:16]


def test_every_shipped_scenario_without_wheels_is_pinned():
    """Every shipped scenario with the paper's wheels is pinned (the
    flight-like ones, ``[wheels]``, are new: nothing to stay equal to)."""
    paper = [n for n, (path, _) in shipped().items() if load_scenario(path).actuators.wheels is None]
    assert sorted(PINS) == sorted(paper)
    assert "flight_wheels" in shipped() and "flight_wheels" not in paper


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if "1khz" in n else n
                                  for n in sorted(PINS)])  # the 1 kHz runs: 3 s each
def test_shipped_run_is_bitwise_unchanged(name):
    scn = load_scenario(shipped()[name][0])
    cpp_pin, py_pin = PINS[name]
    assert _digest(simulate(scn, engine="cpp")) == cpp_pin
    assert _digest(simulate(scn, engine="python", duration=min(scn.run.duration, 20.0))) == py_pin
