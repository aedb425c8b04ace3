"""Linear design and analysis with python-control (docs/DESIGN.md).

The package, in the order of docs/DESIGN.md (every public name is importable
from here, ``sc_rt.studies.design.<name>``):

1. :mod:`~sc_rt.studies.design.linear`: the error dynamics linearised about
   ``sigma_BD = 0, omega_BD_B = 0``, analytically (:func:`error_model`) and
   numerically (:func:`error_system`, :func:`linearize_error`); the input
   matrices (:func:`input_matrices`).
2. :mod:`~sc_rt.studies.design.pd`: the PD baseline (:func:`design_pd`,
   :func:`default_pd_design`).
3. :mod:`~sc_rt.studies.design.margins`: margins of the PD loop, one axis at
   a time (:func:`pd_margins`, :func:`loop_margins`,
   :func:`closed_form_pd_margins`, :func:`coupling`).
4. :mod:`~sc_rt.studies.design.sampled`: the linearised sampled-data loop of
   DSC+PPC and DSC (:func:`sampled_closed_loop`, :func:`controller_step`,
   :func:`spectral_radius`); :mod:`~sc_rt.studies.design.stability`: the
   predicted loss of stability, the smallest stable chiinf
   (:func:`stability_limit`) and the simulated one
   (:func:`simulated_loss_of_stability`, :func:`compare_loss_of_stability`).
5. :mod:`~sc_rt.studies.design.noise`: the sensor noise floor
   (:func:`noise_floor`, :func:`predicted_tightest_chiinf`; docs/DESIGN.md
   section 5), printed by the report;
   :mod:`~sc_rt.studies.design.report`: :func:`design_report`, the text
   tables, :func:`write_design` (``sc-rt design``);
   :mod:`~sc_rt.studies.design.figures`: its figures.

Units: SI (rad, rad/s, rad/s^2, s, Hz). Angles of margins in degrees.
"""

from __future__ import annotations

from sc_rt.studies.design.linear import (
    AXES, INERTIAS, InputMatrices, error_model, error_state_space, error_system, inertia_matrix,
    input_matrices, linearize_error, mrp_add, wheel_effectiveness)
from sc_rt.studies.design.pd import (
    SETTLING_TOL, PdDesign, default_pd_design, design_pd, settling_time_factor)
from sc_rt.studies.design.margins import (
    CASES, DEFAULT_LATENCY_S, Margins, axis_loop, closed_form_pd_margins, coupling,
    frequency_response, loop_margins, pd_margins)
from sc_rt.studies.design.sampled import (
    CONTROLLER_OUTPUTS, SAMPLED_STATES, SampledLoop, controller_step, observer_gains, observer_map,
    ppc_gain, sampled_closed_loop, spectral_radius)
from sc_rt.studies.design.stability import (
    StabilityLimit, compare_loss_of_stability, critical_r_estimate, simulated_loss_of_stability,
    stability_limit, without_wheel_limits)
from sc_rt.studies.design.noise import NoiseFloor, noise_floor, predicted_tightest_chiinf
from sc_rt.studies.design.report import (
    MARGINS_LOOP, chiinf_check, design_report, format_chiinf_check, format_design_text, format_loss_of_stability,
    format_margins_table, format_sampled_table, write_design)
from sc_rt.studies.design.figures import plot_loops, plot_spectral

__all__ = [
    "NoiseFloor",
    "noise_floor",
    "predicted_tightest_chiinf",
    "CASES",
    "INERTIAS",
    "DEFAULT_LATENCY_S",
    "SAMPLED_STATES",
    "InputMatrices",
    "input_matrices",
    "error_model",
    "error_system",
    "linearize_error",
    "mrp_add",
    "PdDesign",
    "settling_time_factor",
    "design_pd",
    "default_pd_design",
    "axis_loop",
    "Margins",
    "loop_margins",
    "closed_form_pd_margins",
    "pd_margins",
    "coupling",
    "ppc_gain",
    "sampled_closed_loop",
    "spectral_radius",
    "StabilityLimit",
    "stability_limit",
    "critical_r_estimate",
    "simulated_loss_of_stability",
    "design_report",
    "format_margins_table",
    "format_sampled_table",
    "write_design",
    # added with the split into modules
    "AXES",
    "SETTLING_TOL",
    "CONTROLLER_OUTPUTS",
    "inertia_matrix",
    "wheel_effectiveness",
    "error_state_space",
    "frequency_response",
    "observer_gains",
    "observer_map",
    "SampledLoop",
    "controller_step",
    "without_wheel_limits",
    "compare_loss_of_stability",
    "MARGINS_LOOP",
    "chiinf_check",
    "format_chiinf_check",
    "format_loss_of_stability",
    "format_design_text",
    "plot_loops",
    "plot_spectral",
]
