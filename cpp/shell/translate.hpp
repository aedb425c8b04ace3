// Translators between LCM messages and core types: conversion only, no
// logic, no I/O (Drake's three-layer message design).
#pragma once
#include <sc_rt_lcm/controller_config_t.hpp>
#include <sc_rt_lcm/controller_status_t.hpp>
#include <sc_rt_lcm/gyro_t.hpp>
#include <sc_rt_lcm/magnetometer_t.hpp>
#include <sc_rt_lcm/plant_state_t.hpp>
#include <sc_rt_lcm/rod_cmd_t.hpp>
#include <sc_rt_lcm/star_tracker_t.hpp>
#include <sc_rt_lcm/tachometer_t.hpp>
#include <sc_rt_lcm/wheel_cmd_t.hpp>

#include "sc_rt/controllers.hpp"
#include "sc_rt/mekf.hpp"

namespace sc_rt {

// Throws std::invalid_argument when the message is inconsistent; the law is
// resolved (a plugin loaded) by the Controller; the
// returned config still needs validate() (Controller's constructor does it).
ControllerConfig config_from_lcm(const sc_rt_lcm::controller_config_t& msg);
sc_rt_lcm::controller_config_t config_to_lcm(const ControllerConfig& c, const std::string& scenario);

// The magnetic part (mag_*, bdot_*) of a controller_config_t: none unless
// the momentum manager or B-dot is enabled. Throws std::invalid_argument for
// an impossible rod count or kind; the values are MagneticConfig's validate's.
void magnetic_from_lcm(const sc_rt_lcm::controller_config_t& msg, MagneticConfig& c);
void magnetic_to_lcm(const MagneticConfig& c, sc_rt_lcm::controller_config_t& msg);

// Decode a controller_config_t from its LCM encoding (fingerprint checked).
ControllerConfig config_from_bytes(const void* data, int size);

Measurement measurement_from_lcm(const sc_rt_lcm::plant_state_t& msg);

void fill_wheel_cmd(const Command& c, sc_rt_lcm::wheel_cmd_t& msg);
// The rods' dipole commands of c (n_rods of them; a non-finite one, no
// decision, as 0). seq, session, state_seq and utime are the caller's.
void fill_rod_cmd(const Command& c, int n_rods, sc_rt_lcm::rod_cmd_t& msg);
// The field in B [T] of an ideal magnetometer's message (source
// SOURCE_TRUE_FIELD, frame FRAME_BODY) into B_B; false (B_B untouched) for a
// sensor's sample or a non-finite field.
bool field_from_lcm(const sc_rt_lcm::magnetometer_t& msg, Vec3& B_B);
// A magnetometer's sample (source SOURCE_SENSOR, frame FRAME_SENSOR) into s;
// false (s untouched) for anything else or a non-finite sample.
bool mag_sample_from_lcm(const sc_rt_lcm::magnetometer_t& msg, MagSample& s);
// law: the controller's law code (Controller::law_code()).
// n_telemetry: how many named values the law declared (Controller::telemetry_names)
void fill_status(const Command& c, int law, int n_telemetry, sc_rt_lcm::controller_status_t& msg);

// The estimator's part of a controller_config_t (nav_*): enabled only for a
// scenario with [sensors]. Throws std::invalid_argument when inconsistent.
struct NavSetup {
  bool enabled = false;
  bool use_estimate = false;
  MekfParams mekf;
  Vec3 sigma0 = Vec3::Zero();  //!< the initial attitude estimate
  bool mag_enabled = false;    //!< the magnetometer's samples feed the magnetic part (nav_mag_enabled)
  Mat3 mag_R_SB = Mat3::Identity();  //!< [-] its known mounting, body to sensor (nav_mag_R_SB)
};
NavSetup nav_from_lcm(const sc_rt_lcm::controller_config_t& msg);
NavSetup nav_from_bytes(const void* data, int size);

// Sensor messages to the core's samples (no checks: the shell's gate checks).
GyroSample gyro_from_lcm(const sc_rt_lcm::gyro_t& msg);
StarSample star_from_lcm(const sc_rt_lcm::star_tracker_t& msg);
TachSample tach_from_lcm(const sc_rt_lcm::tachometer_t& msg);
// The estimator's telemetry into the status message (nav = 1).
void fill_nav_status(const NavTelemetry& t, sc_rt_lcm::controller_status_t& msg);

}  // namespace sc_rt
