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

    from sc_rt.scenario.tables.laws import resolved

    # each law's declared defaults, overlaid with the config's table where it is that law's
    tables = ((c.law, tuple((k, tuple(v)) for k, v in c.law_params)),)
    dsc_law = c.law if c.law in ("dsc-ppc", "dsc") else "dsc-ppc"
    d, pd, rft = (resolved(tables, name) for name in (dsc_law, "pd", "rft"))
    return dict(
        sc=dict(J0=np.array(sc.J0), Cbar=np.array(sc.Cbar), Jw=np.array(sc.Jw),
                umin=np.array(sc.umin), umax=np.array(sc.umax), w0=sc.w0),
        g=dict(sigma_d0=np.array(g.sigma_d0), bias=np.array(g.omega_bias),
               cos=np.array(g.omega_cos), sin=np.array(g.omega_sin), freq=g.omega_freq),
        ppc_p=dict(chi0=np.array(p.chi0), chiinf=np.array(p.chiinf), gamma=np.array(p.gamma),
                   dmin=np.array(p.dmin), dmax=np.array(p.dmax)),
        neso=dict(k1=np.broadcast_to(d["neso_k1"], (3,)), k2=np.broadcast_to(d["neso_k2"], (3,)),
                  k3=np.broadcast_to(d["neso_k3"], (3,)), k4=np.broadcast_to(d["neso_k4"], (3,)),
                  alpha=d["neso_alpha"], substeps=int(d["neso_substeps"]),
                  init_from_measurement=bool(d["neso_init_from_measurement"])),
        dsc=dict(k1=d["k1"], k2=d["k2"], k3=d["k3"], k4=d["k4"], tau=d["tau"]),
        pd=dict(beta1=pd["beta1"], beta2=pd["beta2"]),
        rft=dict(c=rft["c"], k=rft["k"], gain=rft["gain"], leak=rft["leak"], phi=rft["phi"], rho0=rft["rho0"]),
        rate=c.control_rate_hz,
    )


def measurement(t, sigma, omega, wheel=None) -> _core.Measurement:
    return _core.Measurement(t, np.asarray(sigma, float), np.asarray(omega, float),
                             np.zeros(4) if wheel is None else np.asarray(wheel, float))


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20191001)


#: Tests of 0.7 s or more each (measured here with --durations on 2 shared
#: cores), left out of the fast loop (`pytest -m "not slow"`, under a minute)
#: and run by `make test` like every other: whole LCM runs, CLI round trips.
SLOW_TESTS = (
    # the rods' applied dipole in the record: day_hold 30 s in lockstep with two rod faults, the C++ engine, its report
    "tests/test_rod_applied.py::test_a_lockstep_run_with_rod_faults_records_the_applied_dipole_as_the_cpp_engine",
    # issue 43 item 3: day_hold 60 s in lockstep with three rod faults sent live (its sc-rt fault processes,
    # the run, the C++ engine twice), its report and MCAP
    "tests/test_rod_fault.py::test_rod_faults_sent_live_in_lockstep_equal_the_cpp_engine_with_them_scheduled",
    "tests/test_rod_fault.py::test_the_log_holds_the_rod_fault_commands_for_the_report_and_the_mcap",
    # issue 43 item 8: the live run's and its log's report.html and the log's figures with its rod faults
    "tests/test_rod_fault.py::test_the_reports_of_the_live_run_and_of_its_log_show_its_rod_faults",
    "tests/test_rod_fault.py::test_the_logged_truth_of_the_rods_is_the_scheduled_faults_applied_by_hand",
    # issue 43: the rods' echo against two real-time emulator processes and five sc-rt fault processes
    "tests/test_rod_echo.py::test_a_rod_fault_is_echoed_by_an_emulator_that_applies_it",
    # a sc-rt fault process waiting 0.3 s for an echo (0.65 s measured, near the line)
    "tests/test_rod_echo.py::test_a_rod_fault_no_emulator_echoes_exits_1_naming_why",
    # issue 43: WMM2025's epoch window refused by `sc-rt sim` and `sc-rt check` (two processes, ~1.2 s)
    "tests/test_wmm2025.py::test_sc_rt_refuses_an_epoch_outside_wmm2025_with_exit_2_and_one_line",
    # issue 43: a lockstep run over LCM in WMM2025 against the C++ engine
    "tests/test_wmm2025.py::test_lockstep_hil_in_wmm2025_is_bitwise_sim",
    # issue 43: day_hold's first 4 h with a realistic magnetometer in the loop (~3 s, 350 MB of rows)
    "tests/test_mag_sensed.py::test_day_hold_with_a_realistic_magnetometer_still_unloads",
    # issue 43, the bus side: lockstep runs with magnetic control over LCM (day_hold 10 min with its MCAP
    # and report ~8 s, detumble, a Python law and a forger ~2.5 s each) and a 5 s real-time run (~6.6 s)
    "tests/test_mag_bus.py::test_day_hold_in_lockstep_is_bitwise_the_cpp_engine_rods_and_field_included",
    "tests/test_mag_bus.py::test_the_log_reports_the_run_with_its_rods_and_field",
    "tests/test_mag_bus.py::test_the_mcap_has_the_magnetic_fields_with_their_units",
    "tests/test_mag_bus.py::test_detumble_in_lockstep_is_bitwise_the_cpp_engine_through_its_mode_switch",
    "tests/test_mag_bus.py::test_one_forged_rod_command_far_ahead_is_dropped_and_the_run_stays_bitwise",
    "tests/test_mag_bus.py::test_hostile_rod_commands_and_rod_faults_during_a_lockstep_run_change_nothing",
    "tests/test_mag_bus.py::test_a_short_real_time_day_hold_commands_the_rods",
    "tests/test_mag_bus.py::test_a_short_real_time_detumble_runs_b_dot_on_the_rods",
    "tests/test_mag_bus.py::test_a_controller_that_sends_no_rod_commands_still_runs_the_scenario_with_the_rods_held",
    "tests/test_mag_bus.py::test_a_python_law_in_sc_rt_controller_detumbles_and_switches_bitwise_as_sim",
    "tests/test_mag_sensor_bus.py::test_day_hold_sensed_in_lockstep_is_bitwise_the_cpp_engine",
    "tests/test_mag_sensor_bus.py::test_detumble_sensed_in_lockstep_is_bitwise_the_cpp_engine_through_its_mode_switch",
    "tests/test_mag_sensor_bus.py::test_a_python_law_in_sc_rt_controller_takes_the_samples_bitwise_as_sim",
    "tests/test_mag_sensor_bus.py::test_the_samples_with_authentication_are_still_bitwise",
    "tests/test_mag_sensor_bus.py::test_hostile_magnetometer_messages_during_a_lockstep_run_change_nothing",
    "tests/test_mag_sensor_bus.py::test_a_short_real_time_sensed_day_hold_uses_the_samples",
    # issue 43: a day on the C++ engine, with and without the momentum manager (~13 s each)
    "tests/test_day_hold.py::test_without_the_manager_the_wheels_gather_the_secular_torque_and_saturate",
    "tests/test_day_hold.py::test_with_the_manager_the_wheels_are_unloaded_and_kept_in_the_band",
    # issue 43: a three-run Monte Carlo of day_hold (30 min runs) and each run again by hand (~15 s)
    "tests/test_day_montecarlo.py::test_each_run_draws_the_declared_values_and_is_the_hand_edited_scenario",
    # issue 43 item 8: two short runs written with their figures and report.html (~5 s)
    "tests/test_mag_record.py::test_report_has_the_magnetic_figure_only_with_magnetic_control",
    # issue 43 item 6: a lockstep run over LCM with Basilisk's Stribeck switch (~1.7 s)
    "tests/test_stribeck_switching.py::test_lockstep_hil_is_bitwise_sim_with_the_switch_on",
    # issue #43: three orbits of momentum unloading on the C++ engine, twice (~5 s)
    "tests/test_mag_control.py::test_the_manager_keeps_the_wheels_unloaded_over_orbits",
    # issue #43: B-dot detumbling integrated by solve_ivp (a binding call per RHS evaluation)
    "tests/test_bdot.py::test_lyapunov_function_decreases_monotonically",
    # issue 38: a lockstep run over LCM and its rerun (~1.6 s)
    "tests/test_run_plan.py::test_rerun_replays_the_plan_a_lockstep_hil_run_recorded",
    # issue 38: a campaign and its reruns replaying the recorded draws (~10 s each)
    "tests/test_montecarlo_rerun.py::test_rerun_replays_the_recorded_draw_whatever_the_seed_and_table_say_now",
    "tests/test_montecarlo_rerun.py::test_sc_rt_rerun_of_a_run_alone_replays_its_plan_and_draw",
    # round 4: the gate's and the log's LCM runs, campaigns, interrupts (tests of 0.7 s or more)
    "tests/test_log_paced.py::test_a_logger_that_never_comes_back_stops_the_run_invalid",
    "tests/test_log_paced.py::test_a_stopped_logger_holds_the_lockstep_bench_and_loses_nothing",
    "tests/test_log_paced.py::test_lockstep_under_a_two_core_cpu_hog_loses_no_log_message",
    "tests/test_lockstep_answers.py::test_a_law_that_never_returns_fails_the_lockstep_run_named",
    "tests/test_lockstep_answers.py::test_a_controller_stopped_for_5_s_gets_its_run_bitwise_the_offline_one",
    "tests/test_out_dir.py::test_a_new_campaign_clears_the_previous_ones_files_and_a_resumed_one_keeps_them",
    "tests/test_envelope_if_asked.py::test_the_campaign_figure_and_rerun_speak_of_the_requirements",
    "tests/test_envelope_if_asked.py::test_the_report_and_the_console_show_no_envelope",
    "tests/test_law_process_end.py::test_an_interrupt_ends_sim_while_its_python_law_never_returns",
    "tests/test_law_process_end.py::test_a_campaign_survives_a_python_law_that_segfaults",
    "tests/test_law_process_end.py::test_a_campaign_goes_on_past_a_law_that_hangs_mid_step_and_resumes",
    "tests/test_law_process_end.py::test_compare_goes_on_past_a_law_that_hangs_mid_step",
    "tests/test_child_output.py::test_a_controller_over_its_memory_limit_fails_the_run",
    "tests/test_child_output.py::test_a_python_law_printing_without_end_leaves_a_capped_file",
    "tests/test_truth.py::test_mcap_pointing_is_the_true_error_row_by_row_the_laws_beside_it",
    "tests/test_truth.py::test_hil_live_carries_a_python_laws_telemetry_names",
    "tests/test_seq_window.py::test_one_forged_state_far_ahead_does_not_cut_the_controller_off",
    "tests/test_seq_window.py::test_one_forged_command_far_ahead_does_not_cut_the_plant_off",
    "tests/test_seq_window.py::test_commands_racing_the_controller_fail_the_run_named",
    "tests/test_seq_window.py::test_one_forged_state_inside_the_window_fails_the_run_named",
    "tests/test_report_verdict.py::test_report_of_a_log_gives_the_live_runs_law_failures",
    "tests/test_report_verdict.py::test_report_html_of_an_invalid_offline_run_says_invalid_in_its_headline",
    "tests/test_set_option.py::test_a_bad_set_is_refused_in_one_line_naming_the_key",
    "tests/test_set_option.py::test_set_runs_what_the_edited_file_runs_and_is_recorded",
    "tests/test_set_option.py::test_every_command_that_reads_a_scenario_takes_set",
    "tests/test_requirement_matrix.py::test_every_kind_through_a_campaign_and_its_ensemble_row",
    "tests/test_full_disk_outputs.py::test_a_full_disk_leaves_every_output_whole_or_absent",
    "tests/test_set_option.py::test_design_with_set_designs_for_the_edited_file",
    "tests/test_set_option.py::test_set_reaches_an_entry_of_an_array_as_montecarlo_keys_do",
    "tests/test_traceability.py::test_compare_and_montecarlo_record_their_inputs",
    "tests/test_truth.py::test_the_live_view_gives_the_same_true_error",
    "tests/test_compare_seeds.py::test_compare_over_seeds_says_what_lies_within_the_spread",
    "tests/test_compare_seeds.py::test_a_scenario_without_noise_runs_each_law_once",
    "tests/test_record_stream.py::test_lockstep_run_written_as_it_runs_is_bit_identical_to_offline_sim",
    "tests/test_inbox.py::test_two_chunks_live_then_flat_while_25_times_as_many_rows_fill",
    "tests/test_auth_config.py::test_config_channel_takes_only_a_verified_configuration",
    "tests/test_check.py::test_cli_exit_codes",
    "tests/test_cli_input.py::test_scrt_lcm_url_is_the_url_of_hil_and_emulator",
    "tests/test_controllers.py::test_reengagement_an_hour_into_a_1khz_run_costs_a_bounded_number_of_guidance_steps",
    "tests/test_doc_refs.py::test_every_cited_path_and_symbol_resolves",
    "tests/test_external.py::test_python_law_through_lcm_equals_offline_bitwise",
    "tests/test_floor.py::test_floor_of_an_event_triggered_null_controller",
    "tests/test_floor.py::test_self_test_prints_the_floor_table",
    "tests/test_hil_sensors.py::test_hostile_sensor_messages_during_a_lockstep_run_change_nothing",
    "tests/test_hil_sensors.py::test_lockstep_with_sensors_is_bit_identical_to_sim",
    "tests/test_library.py::test_each_shipped_scenario_states_what_its_run_does_and_does_it",
    "tests/test_mcap.py::test_bad_output_paths",
    "tests/test_mcap.py::test_damaged_logs_are_refused_unless_partial",
    "tests/test_mcap.py::test_fuzzed_logs_export_or_are_refused_never_crash",
    "tests/test_mcap.py::test_hil_and_report_write_the_same_mcap_as_export",
    "tests/test_montecarlo.py::test_cli_writes_the_report_and_the_dataset",
    "tests/test_out_dir.py::test_a_rerun_without_plots_keeps_no_figure_of_the_run_before",
    "tests/test_realtime_kept.py::test_a_realtime_run_whose_controller_hangs_is_invalid",
    "tests/test_references.py::test_a_file_reference_reaches_the_controller_process_and_the_log",
    "tests/test_report.py::test_report_without_config_needs_a_scenario",
    "tests/test_reproduce.py::test_command_writes_where_out_says_whatever_the_working_directory",
    "tests/test_reproduce.py::test_feasible_design_holds_its_bound_in_both_paper_cases",
    "tests/test_robustness.py::test_stale_states_give_safe_mode_and_recovery",
    "tests/test_start_record.py::test_report_labels_a_lockstep_run_of_a_statusless_external_controller",
    "tests/test_unsampled.py::test_sampled_loop_converges_to_the_unsampled_reference",
    "tests/test_html_report.py::test_report_opens_with_the_requirement_table_in_chromium",
    "tests/test_mrp.py::test_subtraction_matches_rotation_matrices",
    "tests/test_external.py::test_emulator_with_a_hand_started_controller_records_errors_and_label",
    "tests/test_doc_refs.py::test_every_allow_list_entry_is_still_needed",
    "tests/test_pylaw.py::test_cli_sim_with_a_python_law_equals_the_builtin",
    "tests/test_references.py::test_lockstep_hil_of_a_slew_is_bit_identical_to_sim",
    "tests/test_out_dir.py::test_an_out_held_by_a_live_run_is_refused_and_a_stale_claim_taken_over",
    "tests/test_library.py::test_sc_rt_scenarios_lists_them_outside_the_repository",
    "tests/test_law_telemetry.py::test_the_fixed_slots_go_through_the_bench_bitwise",
    "tests/test_pylaw_everywhere.py::test_a_python_law_with_sensors_in_lockstep_equals_sim",
    "tests/test_pylaw_everywhere.py::test_a_python_law_runs_a_campaign_equal_to_the_builtin",
    "tests/test_law_tables.py::test_a_python_law_named_by_the_scenario_runs_in_lockstep_bitwise",
    "tests/test_law_tables.py::test_a_log_written_before_the_change_still_reports",
    "tests/test_record_stream.py::test_metrics_of_a_run_on_disk_equal_those_of_the_run_held_whole",
    "tests/test_flight_wheels.py::test_lockstep_hil_is_bitwise_sim_with_flight_wheels_and_their_faults",
    "tests/test_orbit_plant.py::test_lockstep_hil_with_an_orbit_is_bitwise_sim",
    "tests/test_mag_plant_twin.py::test_lockstep_hil_with_a_residual_dipole_and_a_stuck_rod_is_bitwise_sim",
    "tests/test_hil.py::test_lockstep_hil_is_bit_identical_to_offline_sim",
    "tests/test_requirement_matrix.py::test_every_kind_through_hil_lockstep_and_its_report",
    "tests/test_requirement_matrix.py::test_every_kind_through_compare_and_a_campaigns_rerun",
    "tests/test_gate.py::test_hil_strict_exits_1_on_a_failing_run_and_0_on_a_passing_one",
    "tests/test_gate.py::test_montecarlo_strict_gates_the_campaign_and_a_rerun",
    "tests/test_realtime_kept.py::test_a_realtime_run_whose_plant_stalls_is_invalid",
    "tests/test_report_verdict.py::test_report_of_a_log_with_another_plants_states_is_invalid",
    "tests/test_stall_timeout.py::test_progress_and_the_work_after_the_steps_are_never_stopped",
    "tests/test_stall_timeout.py::test_a_child_that_stops_beating_is_killed_naming_its_last_time",
    "tests/test_stall_timeout.py::test_sim_of_a_python_law_that_never_returns_fails_naming_it",
    # issue 39 item 6: sim and hil runs, and readers in a fresh interpreter (pandas, polars: 2-6 s each)
    "tests/test_one_format.py::test_sim_and_lockstep_hil_write_one_file_of_one_schema",
    "tests/test_one_format.py::test_pyarrow_pandas_and_polars_read_a_run_without_sc_rt_as_run_load_does",
    "tests/test_one_format.py::test_the_docs_pandas_and_polars_examples_run_as_written_without_sc_rt",
    "tests/test_one_format.py::test_every_sim_engine_writes_trajectory_arrow_and_no_npz",
)


def pytest_collection_modifyitems(items):
    """Tests that need the out-of-tree plugin builds (the ``plugins`` fixture
    (below), ``laws`` of test_law_door.py: a cmake build of example
    plugins, 2-20 s once) are slow, and so are those of SLOW_TESTS."""
    for item in items:
        if {"plugins", "laws"} & set(getattr(item, "fixturenames", ())) or \
                item.nodeid.split("[")[0] in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def plugins(tmp_path_factory):
    """examples/quaternion_feedback and tests/law_plugins, each built like a
    user's project (tests/plugbuild.py), once per session."""
    import plugbuild

    return plugbuild.build_all(tmp_path_factory.mktemp("plugins"))


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
