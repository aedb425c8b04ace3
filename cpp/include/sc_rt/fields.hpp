// The run record's per-row fields the core produces: one table, declared
// once (issue 39 item 1). Every mirror is built from it: the closed loop's
// result buffer (closed_loop.hpp), step_packed's row and the navigation's
// packed telemetry (bindings), the Python dict's columns and
// _core.FIELD_TABLE (read by sc_rt.results.record.fields, sc_rt.wire.codec),
// and the telemetry block of controller_status_t (generated at build time
// from this table by cpp/tools/gen_status_lcm.cpp). Adding a per-row
// quantity is a row here and a line in its producer (closed_loop.hpp
// for_each_command_field / for_each_nav_field).
//
// Pure data: no I/O, no allocation; constexpr, so the generator and the
// step path read the same table at compile time.
#pragma once
#include <cstddef>
#include <string_view>

namespace sc_rt {

// X(name, width, dtype, unit, unit_rule, source, group, packed, bus, core, doc)
//  name      the array's name in the record, the dict and controller_status_t
//  width     values per row (1: a scalar per row)
//  dtype     the record's numpy dtype: "f8" or "i8" (stored as double here:
//            the integers are small and exact)
//  unit      its unit on acceleration-commanded wheels ("-": none)
//  unit_rule "" (fixed), "command": the unit of the wheel command, resolved
//            per run from the wheels' interface (rad/s^2 acceleration, N m
//            torque; SpacecraftParams::wheel_torque_command), or "law": the
//            unit the law commands (LawCommand; a law's own state: the
//            controller converts only its command to the wheels' unit)
//  source    where the value comes from: plant (the integrated state),
//            controller (the Command), truth (the plant's true value),
//            estimator (the navigation filter)
//  group     kLoop: every closed-loop row; kNav: rows of a run with sensors
//  packed    part of the Command (step_packed's row, for_each_command_field)
//  bus       travels in controller_status_t (its generated telemetry block)
//  core      every producer fills it (the metrics check it is finite)
//  doc       what it means (equation numbers: docs/MODEL.md's)
// Every kLoop row precedes every kNav row (a result without sensors holds
// the kLoop prefix only).
#define SC_RT_FIELDS(X)                                                                                          \
  X(t, 1, "f8", "s", "", "plant", kLoop, false, false, true, "control instant t_k = k / rate")                   \
  X(sigma_BN, 3, "f8", "-", "", "plant", kLoop, false, false, true,                                             \
    "MRP attitude of the body B relative to N at t_k")                                                           \
  X(omega_BN_B, 3, "f8", "rad/s", "", "plant", kLoop, false, false, true, "body rate relative to N, body frame")  \
  X(wheel_speed, 4, "f8", "rad/s", "", "plant", kLoop, false, false, true, "wheel speeds relative to the body")   \
  X(sigma_DN, 3, "f8", "-", "", "controller", kLoop, true, true, true, "desired attitude (guidance) at t_k")       \
  X(sigma_BD, 3, "f8", "-", "", "controller", kLoop, true, true, true,                                          \
    "attitude tracking error, MRP of B relative to D (8)")                                                       \
  X(omega_BD_B, 3, "f8", "rad/s", "", "controller", kLoop, true, true, true, "rate tracking error, body frame (8)") \
  X(u_cmd, 4, "f8", "rad/s^2", "command", "controller", kLoop, true, false, true,                                \
    "wheel command before saturation (what the law asked for)")                                                  \
  X(u_sat, 4, "f8", "rad/s^2", "command", "controller", kLoop, true, false, true,                                \
    "the command after the controller's saturation (15)")                                                        \
  X(wheel_accel, 4, "f8", "rad/s^2", "", "truth", kLoop, false, false, true,                                    \
    "actual wheel acceleration, faults applied (15)")                                                            \
  X(z1, 3, "f8", "rad/s", "", "controller", kLoop, true, true, true, "NESO estimate of the rate error state")      \
  X(z2, 3, "f8", "rad/s^2", "", "controller", kLoop, true, true, true, "NESO estimate of the lumped disturbance")  \
  X(delta2, 3, "f8", "rad/s^2", "", "truth", kLoop, false, false, true, "true lumped disturbance (20),(21)")       \
  X(chi, 3, "f8", "-", "", "controller", kLoop, true, true, true, "prescribed envelope chi(t) the controller used (29)") \
  X(lam, 3, "f8", "-", "", "controller", kLoop, true, true, true, "normalised error lambda = sigma_BD / chi (30)") \
  X(e1, 3, "f8", "-", "", "controller", kLoop, true, true, false, "transformed error of the PPC (34)")            \
  X(e2, 3, "f8", "rad/s", "", "controller", kLoop, true, true, false, "second DSC surface error (27)")           \
  X(vs, 4, "f8", "rad/s^2", "law", "controller", kLoop, true, true, false, "anti-windup auxiliary state (42)")     \
  X(x2d, 3, "f8", "rad/s", "", "controller", kLoop, true, true, false,                                          \
    "the law's filtered virtual control, DSC's filter output (LawOutput.x2d; 0 unused)")                         \
  X(rho_hat, 1, "f8", "rad/s^2", "", "controller", kLoop, true, true, false,                                    \
    "the law's adaptive gain (LawOutput.rho_hat: RFT's; 0 unused)")                                              \
  X(telemetry, 8, "f8", "-", "", "controller", kLoop, true, true, false,                                        \
    "the law's named telemetry (LawOutput.telemetry): column i is the run's telemetry_names[i], "               \
    "unit as its name gives it ('name [unit]'); 0 unused")                                                       \
  X(flags, 1, "i8", "-", "", "controller", kLoop, true, false, false,                                           \
    "controller flags bit set (safety, bound, invalid input)")                                                   \
  X(ctrl_mode, 1, "i8", "-", "", "controller", kLoop, true, false, false,                                       \
    "controller mode: 0 INIT, 1 NORMAL, 2 SAFE; -1 unknown")                                                     \
  X(rod_dipole_cmd, 6, "f8", "A m^2", "", "controller", kLoop, true, true, false,                              \
    "magnetorquer rod dipole commands, rod i in column i (0 beyond the rods given; NaN: no magnetic control)")   \
  X(m_B_cmd, 3, "f8", "A m^2", "", "controller", kLoop, true, true, false,                                     \
    "body dipole commanded, G_B rod_dipole_cmd (NaN: no magnetic control)")                                      \
  X(B_B, 3, "f8", "T", "", "controller", kLoop, true, true, false,                                             \
    "geomagnetic field in B the controller used: without [sensors] the true field, with them the "            \
    "magnetometer's latest sample rotated to B by its known mounting (NaN: none)")                             \
  X(h_wheels_B, 3, "f8", "N m s", "", "controller", kLoop, true, true, false,                                  \
    "wheels' momentum Cbar Jw Omega from the measured speeds (NaN: no momentum manager)")                       \
  X(wheel_fill, 1, "f8", "-", "", "controller", kLoop, true, true, false,                                      \
    "momentum manager's |h_err_B| / capacity (NaN: no momentum manager)")                                        \
  X(unloading, 1, "i8", "-", "", "controller", kLoop, true, true, false,                                       \
    "momentum manager's unloading state: 1 on, 0 off; -1 no momentum manager")                                  \
  X(detumble_mode, 1, "i8", "-", "", "controller", kLoop, true, true, false,                                   \
    "B-dot mode: 0 detumble, 1 attitude; -1 no B-dot (a switch: flags bit 13, FLAG_MODE_SWITCH)")                \
  X(H_N, 3, "f8", "N m s", "", "truth", kLoop, false, false, false,                                               \
    "total angular momentum in N, C_NB (J omega_BN_B + Cbar Jw wheel_speed) with the true J (3) "                  \
    "(NaN: the unsampled engine, lockstep)")                                                                     \
  X(B_B_true, 3, "f8", "T", "", "truth", kLoop, false, false, false,                                            \
    "the plant's true geomagnetic field in B at t_k, C_BN(sigma_BN) B_N(t_k), beside the B_B the controller "  \
    "used (NaN: no magnetic control, the unsampled engine, lockstep)")                                         \
  X(m_B, 3, "f8", "A m^2", "", "truth", kLoop, false, false, false,                                             \
    "body dipole the rods applied from t_k, G_B rod_dipole: the held rod commands through the rods' limits and "  \
    "active faults (a zero command without magnetic control), residual dipole not included (NaN: no rods, the "   \
    "unsampled engine)")                                                                                         \
  X(rod_dipole, 6, "f8", "A m^2", "", "truth", kLoop, false, false, false,                                      \
    "each rod's dipole applied from t_k, rod i in column i: its command clipped to its limit, then its active "  \
    "fault (dead 0, stuck its dipole, reversed -d) (NaN beyond the rods, without rods, the unsampled engine)")   \
  X(sigma_BN_est, 3, "f8", "-", "", "estimator", kNav, false, true, false,                                      \
    "MEKF attitude estimate at t_k (what the law gets with measurement = estimate)")                             \
  X(bias_est, 3, "f8", "rad/s", "", "estimator", kNav, false, true, false, "MEKF gyro bias estimate")            \
  X(bias_true, 3, "f8", "rad/s", "", "truth", kNav, false, false, false,                                        \
    "the gyro's true bias (bias0 + Gauss-Markov + random walk)")                                                 \
  X(P_diag, 6, "f8", "rad^2, (rad/s)^2", "", "estimator", kNav, false, true, false,                             \
    "MEKF covariance diagonal: attitude error (3, body) then bias error (3)")                                    \
  X(att_est_error, 3, "f8", "rad", "", "truth", kNav, false, false, false,                                      \
    "estimation error: rotation vector of the true attitude relative to the estimate, body frame")               \
  X(innovation, 3, "f8", "rad", "", "estimator", kNav, false, true, false,                                      \
    "star tracker residual of the last update since the previous row (NaN: none)")                               \
  X(nis, 1, "f8", "-", "", "estimator", kNav, false, true, false,                                               \
    "normalised innovation squared z' S^-1 z of that update (NaN: none)")                                     \
  X(gyro_cal_est, 9, "f8", "-, rad", "", "estimator", kNav, false, true, false,                                 \
    "calibrating filter's gyro scale factors s1 s2 s3 [-], then misalignments ku1 ku2 ku3, kl1 kl2 kl3 [rad] "   \
    "of S = [[s1 ku1 ku2], [kl1 s2 ku3], [kl2 kl3 s3]] (NaN: the 6-state filter)")                               \
  X(gyro_cal_3sigma, 9, "f8", "-, rad", "", "estimator", kNav, false, true, false,                              \
    "3 sigma of each gyro_cal_est value, 3 sqrt of the filter's covariance diagonal (NaN: the 6-state filter)")

//! Which rows hold a field: every closed-loop row, or a run with sensors.
enum FieldGroup : int { kLoop = 0, kNav = 1 };

//! One row of the table (the X-macro's columns; see SC_RT_FIELDS).
struct FieldSpec {
  std::string_view name;
  int width;              //!< values per row
  std::string_view dtype;  //!< "f8" or "i8"
  std::string_view unit;   //!< on acceleration-commanded wheels
  std::string_view unit_rule;  //!< "" or "command"
  std::string_view source;
  FieldGroup group;
  bool packed;  //!< in the Command (step_packed)
  bool bus;     //!< in controller_status_t
  bool core;    //!< every producer fills it
  std::string_view doc;
};

//! A field's index in kFields: one enumerator per row, named as the field.
enum class FieldId : int {
#define SC_RT_FIELD_ID(name, ...) name,
  SC_RT_FIELDS(SC_RT_FIELD_ID)
#undef SC_RT_FIELD_ID
};

inline constexpr FieldSpec kFields[] = {
#define SC_RT_FIELD_SPEC(name, width, dtype, unit, rule, source, group, packed, bus, core, doc) \
  FieldSpec{#name, width, dtype, unit, rule, source, group, packed, bus, core, doc},
    SC_RT_FIELDS(SC_RT_FIELD_SPEC)
#undef SC_RT_FIELD_SPEC
};
inline constexpr int kFieldCount = static_cast<int>(sizeof(kFields) / sizeof(kFields[0]));

constexpr const FieldSpec& field_spec(FieldId f) { return kFields[static_cast<int>(f)]; }
constexpr int field_width(FieldId f) { return field_spec(f).width; }

//! The field's first value in a row of every field of groups <= its own,
//! in table order (the closed loop's result buffer: field blocks).
constexpr int field_offset(FieldId f) {
  int o = 0;
  for (int i = 0; i < static_cast<int>(f); ++i) o += kFields[i].width;
  return o;
}
//! Values per row of the group's fields and every group before it.
constexpr int row_width(FieldGroup g) {
  int o = 0;
  for (const FieldSpec& s : kFields)
    if (s.group <= g) o += s.width;
  return o;
}
//! The field's first value in step_packed's row (the packed fields in table
//! order); -1 when the field is not packed.
constexpr int packed_offset(FieldId f) {
  if (!field_spec(f).packed) return -1;
  int o = 0;
  for (int i = 0; i < static_cast<int>(f); ++i)
    if (kFields[i].packed) o += kFields[i].width;
  return o;
}
constexpr int packed_size() {
  int o = 0;
  for (const FieldSpec& s : kFields)
    if (s.packed) o += s.width;
  return o;
}
//! The field's first value in the navigation's packed telemetry (the kNav
//! fields in table order, then nav_flags); -1 for a kLoop field.
constexpr int nav_offset(FieldId f) {
  if (field_spec(f).group != kNav) return -1;
  int o = 0;
  for (int i = 0; i < static_cast<int>(f); ++i)
    if (kFields[i].group == kNav) o += kFields[i].width;
  return o;
}
//! The kNav fields' values and the navigation's flags (one more value).
constexpr int nav_size() { return row_width(kNav) - row_width(kLoop) + 1; }

constexpr bool loop_before_nav() {
  bool nav = false;
  for (const FieldSpec& s : kFields) {
    if (s.group == kNav) nav = true;
    if (s.group == kLoop && nav) return false;
  }
  return true;
}
static_assert(loop_before_nav(), "SC_RT_FIELDS: every kLoop field must precede the kNav fields");

}  // namespace sc_rt
