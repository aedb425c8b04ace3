// The true plant (docs/MODEL.md sections 1 and 2): what the emulator integrates.
// The same model as the Python reference sc_rt.model.plant / sc_rt.model.actuators,
// compiled for batch speed. The hot path (wheel_accel, disturbance,
// plant_derivative, plant_rk4_step, lumped_disturbance) repeats the Python
// code's scalar operations in the same order, so the two engines give
// BIT-IDENTICAL results (tests/test_plant.py); this relies on IEEE double
// without contraction (-ffp-contract=off) and on glibc's cos/expm1, which
// Python's math module calls too. Edit the two together.
//
// State: sigma_BN (MRP), omega_BN_B [rad/s], wheel speeds Omega_w [rad/s,
// relative to the body].
//   Kinematics (1),(2): sigma_dot = G(sigma) omega.
//   Dynamics (7), TRUE inertia J = J0 + dJ:
//     J omega_dot = -omega^ (J omega + Cbar Jw Omega_w) - Cbar Jw Omega_w_dot + u_g + d(t)
//   Gravity gradient (5),(6): u_g = 3 w0^2 R3^ J R3, R3 = R(sigma) e3 (10);
//   with an orbit (PlantParams::orbit.enabled) u_g = 3 mu / r^3 n_B^ J n_B,
//   n_B = R(sigma) r_N / r at each RK4 stage's time (orbit.hpp).
//   Magnetic torque (docs/MODEL.md section 16): with a field (PlantParams::field,
//   along the orbit) tau = m_B x C_BN(sigma) B_N(t) at each RK4 stage, m_B the
//   residual dipole plus the magnetorquers' body dipole held over the step
//   (plant_rk4_step's dipole_B); no term at all when m_B is exactly zero.
//   Wheels: Omega_w_dot = the actual acceleration of (15),(16) (wheel_accel).
//
// Fault conventions (shared with sc_rt.model.actuators): a fault is active on
// onset <= t < end (Y = 0 from end on, abrupt); a stuck wheel has zero
// acceleration while its fault is active, whatever Y; with |Omega_i| >=
// max_wheel_speed_i an acceleration that drives the speed further out is 0
// (applied after the fault model). A NaN command propagates.
//
// Pure functions: no I/O, no allocation. They assume valid parameters: check
// them once with validate() (the Python binding's constructors do).
#pragma once
#include <memory>
#include <array>
#include <limits>
#include <string>
#include <vector>

#include "sc_rt/geomag.hpp"
#include "sc_rt/magnetorquer.hpp"
#include "sc_rt/orbit.hpp"
#include "sc_rt/types.hpp"
#include "sc_rt/wheels.hpp"

namespace sc_rt {

// The plant's magnetorquer rods (sc_rt.model.rods; docs/MODEL.md section 16):
// axes and limits, and at most one timed fault per rod (active on onset <= t < end).
struct PlantRods {
  bool enabled = false;                    //!< false: no rods
  MagnetorquerParams params{};             //!< G_B (3 x N) unit axes, dipole_max [A m^2]
  std::array<RodFault, kMaxRods> fault{};  //!< per rod, Healthy by default
  std::array<double, kMaxRods> stuck{};    //!< [A m^2] a stuck rod's dipole
  std::array<double, kMaxRods> onset{};    //!< [s] the fault's onset
  std::array<double, kMaxRods> end{};      //!< [s] the fault's end (inf: never)
};

// The body dipole m_B = G d [A m^2] of rod commands d_cmd [A m^2] (null: all 0)
// at t [s]: each clipped to +-dipole_max, then its active fault (dead 0, stuck
// its dipole, reversed -d), as Magnetorquers::update; the sums in rod order.
// applied (optional): each rod's dipole d [A m^2] (N values, the record's
// rod_dipole; sc_rt.model.rods.rods_applied).
Vec3 rods_dipole_B(const PlantRods& r, double t, const RodVec* d_cmd = nullptr, RodVec* applied = nullptr);

// The true plant. Defaults are the paper's (Section 4): J0, dJ, Cbar, Jw and d(t).
struct PlantParams {
  Mat3 J0 = (Mat3() << 10, 0, 0, 0, 15, 0, 0, 0, 20).finished();  //!< [kg m^2] nominal inertia
  Mat3 dJ = (Mat3() << 2, 0, 0, 0, -1, 0, 0, 0, 2).finished();    //!< [kg m^2] error; J = J0 + dJ
  Mat34 Cbar = (Mat34() << -0.9992, -0.0300, -0.0256, -0.6086,
                            -0.0394, 0.7455, 0.6653, 0.7913,
                            0.0009, -0.6658, 0.7461, 0.0469).finished();  //!< [-] wheel axes in B
  Vec4 Jw = Vec4::Constant(0.338);               //!< [kg m^2] wheel spin inertias
  double w0 = 0.0011;                            //!< [rad/s] orbit rate of (5)
  Vec3 dist_amp = Vec3(5e-3, -5e-3, 6e-3);       //!< [N m] d(t) = bias + amp cos(freq t)
  Vec3 dist_freq = Vec3(0.02, 0.025, 0.04);      //!< [rad/s]
  Vec3 dist_bias = Vec3::Zero();                 //!< [N m]
  //! enabled: u_g of the orbit's actual radius and nadir (orbit.hpp) replaces the w0 form of (5)
  OrbitParams orbit{};
  //! the geomagnetic field along the orbit (IGRF-14, its dipole or WMM2025 at the orbit's
  //! epoch, plant_field); null: none. Shared: built once, read by every step.
  std::shared_ptr<const GeomagField> field{};
  Vec3 residual_dipole = Vec3::Zero();  //!< [A m^2] the spacecraft's residual dipole in B (m x B)
  //! test-only: false drops the orbit's gravity gradient (u_g then has the w0 form; w0 = 0: none)
  bool orbit_gravity_gradient = true;
  //! enabled: magnetorquer rods; with no dipole input a step holds their dipole for a
  //! zero command (a stuck rod's; none when healthy), rods_dipole_B
  PlantRods rods{};
};

// The field `model` ("none": null, "dipole", "igrf", "wmm2025";
// geomag_model_coefficients) at the orbit's epoch, for PlantParams::field
// (sc_rt.model.field.field_for's).
std::shared_ptr<const GeomagField> plant_field(const OrbitParams& orbit, const std::string& model);

// The plant's field in B, B_B = C_BN(sigma_BN) B_N(t) [T], B_N at the orbit's
// position at t [s] (the magnetic torque's evaluation, plant_kernels.hpp
// MagField, then rotate_to_B): what the offline engines give the controller
// on a run without a magnetometer (sc_rt.model.plant.field_B, the same
// operations). false, B_B untouched, without a field.
bool plant_field_B(const PlantParams& p, double t, const Vec3& sigma_BN, Vec3& B_B);

// One fault of one wheel, (16).
struct WheelFault {
  bool active = false;                                    //!< false: healthy wheel
  double effectiveness = 1.0;                             //!< [-] L_i in [0, 1]
  double bias = 0.0;                                      //!< [rad/s^2] ubar_i
  double onset = 0.0;                                     //!< [s] T_i
  double end = std::numeric_limits<double>::infinity();   //!< [s] abrupt end (inf: never)
  double rate = 1.0;                                      //!< [1/s] a_i
  bool stuck = false;                                     //!< zero acceleration while active
  double friction = 1.0;  //!< [-] friction multiplier as Y -> 1 (torque-commanded wheels)
};

struct ActuatorParams {
  Vec4 umin = Vec4::Constant(-7.0);  //!< [rad/s^2] lower limits of (15)
  Vec4 umax = Vec4::Constant(10.0);  //!< [rad/s^2] upper limits of (15)
  Vec4 max_wheel_speed = Vec4::Constant(std::numeric_limits<double>::infinity());  //!< [rad/s]
  std::array<WheelFault, 4> faults{};  //!< faults[i] is wheel i's (0-based)
  TorqueWheels wheels{};  //!< enabled: flight-like wheels replace umin/umax/max_wheel_speed
};

struct PlantState {
  Vec3 sigma_BN = Vec3::Zero();     //!< [-] MRP of B relative to N
  Vec3 omega_BN_B = Vec3::Zero();   //!< [rad/s] body rate in B
  Vec4 wheel_speed = Vec4::Zero();  //!< [rad/s] wheel speeds relative to the body
};

struct WheelOutput {
  Vec4 u_sat;  //!< [rad/s^2] saturated commands sat(uc)
  Vec4 accel;  //!< [rad/s^2] actual wheel accelerations Omega_w_dot
  Vec4 Y;      //!< [-] fault activations Y_i(t) of (16)
};

// Every problem with the parameters, each naming the field and the value;
// empty if valid.
std::vector<std::string> validate(const PlantParams& p);
std::vector<std::string> validate(const ActuatorParams& a);
// Problems of one fault (an inactive fault has none).
std::vector<std::string> validate(const WheelFault& f);

// Y_i(t) of (16): 0 outside [onset, end), 1 - exp(-rate (t - onset)) inside.
double fault_Y(const WheelFault& f, double t);

// Saturation and the fault model (15),(16), stuck wheels, speed limit.
WheelOutput wheel_accel(const ActuatorParams& a, double t, const Vec4& u_cmd,
                        const Vec4& wheel_speed);

// The wheels' output of a row at (t, x) for the command u_cmd, either wheel
// model: for the paper's wheels wheel_accel's; for torque-commanded ones
// u_sat = the applied motor torque / Jw, accel = Omega_w_dot of the dynamics
// (torque_plant.cpp; sc_rt.model.truth.row).
// motor: what the run carries at t (plant_rk4_step's): the motor torques of
// wheels with a lag, the Stribeck switches (the row takes the step's first
// stage's); may be null only without a lag and without stribeck_switching
// (std::invalid_argument otherwise).
// dipole_B: [A m^2] the magnetorquers' body dipole the step from t holds
// (plant_rk4_step's; null: the rods' for a zero command), so that the row's
// accel is the step's first stage's (docs/MODEL.md section 17).
WheelOutput plant_row(const PlantParams& p, const ActuatorParams& a, double t, const PlantState& x,
                      const Vec4& u_cmd, const WheelCarry* motor = nullptr, const Vec3* dipole_B = nullptr);

// [N m s] the total angular momentum in N of (3), H_N = C_NB(sigma) (J omega +
// Cbar Jw Omega_w) with the true J = J0 + dJ (the record's H_N;
// sc_rt.model.momentum.total_momentum_N, the same operations).
Vec3 total_momentum_N(const PlantParams& p, const PlantState& x);

// What torque-commanded wheels hold over a step from t (sc_rt.model.torque_plant.step_inputs):
// motor torques [N m], friction scales, seizure brakes [N m s].
void torque_step_inputs(const PlantParams& p, const ActuatorParams& a, double t, const Vec4& u_cmd,
                        const Vec4& wheel_speed, double u[4], double scale[4], double brake[4]);

// One RK4 step of the plant on torque-commanded wheels (plant_rk4_step calls it
// when a.wheels.enabled). No allocation.
// motor: the motor torques [N m] and the Stribeck switches carried from step
// to step (zero at the start), advanced to t + h; null: wheels without a lag
// and without stribeck_switching (std::invalid_argument otherwise).
// dipole_B: the magnetorquers' body dipole [A m^2] held over the step (null: none).
PlantState torque_rk4_step(const PlantParams& p, const ActuatorParams& a, double t, const PlantState& x,
                           double h, const Vec4& u_cmd, WheelCarry* motor = nullptr,
                           const Vec3* dipole_B = nullptr);

// plant_rk4_step with the motor state of torque-commanded wheels (unused for
// the paper's wheels): what a loop that carries it calls.
PlantState plant_rk4_step(const PlantParams& p, const ActuatorParams& a, double t, const PlantState& x,
                          double h, const Vec4& u_cmd, WheelCarry& motor, const Vec3* dipole_B = nullptr);

// d(t) = bias + amp cos(freq t) [N m], in B.
Vec3 disturbance(const PlantParams& p, double t);

// The state derivative for the given actual wheel accelerations [rad/s^2]
// (the wheel_speed field of the result is Omega_w_dot = wheel_accel).
PlantState plant_derivative(const PlantParams& p, double t, const PlantState& x,
                            const Vec4& wheel_accel, const Vec3* dipole_B = nullptr);

// One classical RK4 step from t to t + h [s]; u_cmd [rad/s^2] held (ZOH), the
// actual acceleration re-evaluated by wheel_accel at each stage's time and
// wheel speeds; then the MRP short set (|sigma| > 1 -> -sigma/|sigma|^2).
// dipole_B: the magnetorquers' body dipole m_B = G d [A m^2] held over the
// step (null: none); with the residual dipole it acts through p.field.
PlantState plant_rk4_step(const PlantParams& p, const ActuatorParams& a, double t,
                          const PlantState& x, double h, const Vec4& u_cmd, const Vec3* dipole_B = nullptr);

// The true lumped disturbance delta_2 of (20),(21) [rad/s^2] (docs/MODEL.md section 4):
// omega_dot_true - J0^-1 [-W^ (J0 W + Cbar Jw Omega_w) + u_g0] - B u_sat, with
// W = omega_BN_B, u_g0 = 3 w0^2 R3^ J0 R3, B = -J0^-1 Cbar Jw.
Vec3 lumped_disturbance(const PlantParams& p, double t, const PlantState& x, const Vec4& u_sat,
                        const Vec4& accel);

// The same, its two right-hand sides and the wheel map built once (a loop
// that records delta_2 at every row): bitwise the function's values.
class LumpedDisturbance {
 public:
  explicit LumpedDisturbance(const PlantParams& p);
  ~LumpedDisturbance();
  LumpedDisturbance(const LumpedDisturbance&) = delete;
  LumpedDisturbance& operator=(const LumpedDisturbance&) = delete;
  Vec3 operator()(double t, const PlantState& x, const Vec4& u_sat, const Vec4& accel) const;
  struct Impl;  // plant.cpp (lumped_disturbance() uses it on the stack)

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace sc_rt
