// Offline closed loop in C++ (the "cpp" engine of sc-rt sim): the plant twin
// (plant.hpp) and a controller, sampled at the control rate with a
// zero-order hold. Same loop, same order of operations as python/sc_rt/sim/engines.py.
#pragma once
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "sc_rt/controllers.hpp"
#include "sc_rt/fields.hpp"
#include "sc_rt/mekf.hpp"
#include "sc_rt/plant.hpp"

namespace sc_rt {

static_assert(field_width(FieldId::telemetry) == kLawMaxTelemetry, "fields.hpp: telemetry's width");
static_assert(field_width(FieldId::rod_dipole_cmd) == kMaxRods, "fields.hpp: rod_dipole_cmd's width");
static_assert(field_width(FieldId::rod_dipole) == kMaxRods, "fields.hpp: rod_dipole's width");

// The producers of the table's rows from the core's structs (fields.hpp):
// f(FieldId, value) for every packed field of a Command and every kNav field
// of the navigation's telemetry, a value an Eigen vector or one number.
// These are the one place a Command or NavTelemetry member becomes a field;
// tests/test_fields.py checks that every field is produced exactly once.
template <class F>
void for_each_command_field(const Command& c, F&& f) {
  f(FieldId::sigma_DN, c.sigma_DN);
  f(FieldId::sigma_BD, c.sigma_BD);
  f(FieldId::omega_BD_B, c.omega_BD_B);
  f(FieldId::u_cmd, c.u_cmd);
  f(FieldId::u_sat, c.u_sat);
  f(FieldId::z1, c.z1);
  f(FieldId::z2, c.z2);
  f(FieldId::chi, c.chi);
  f(FieldId::lam, c.lam);
  f(FieldId::e1, c.e1);
  f(FieldId::e2, c.e2);
  f(FieldId::vs, c.vs);
  f(FieldId::x2d, c.x2d);
  f(FieldId::rho_hat, c.rho_hat);
  f(FieldId::telemetry, Eigen::Map<const Eigen::Matrix<double, kLawMaxTelemetry, 1>>(c.telemetry.data()));
  f(FieldId::flags, static_cast<double>(c.flags));
  f(FieldId::ctrl_mode, static_cast<double>(c.mode));
  f(FieldId::rod_dipole_cmd, c.magnetic.rod_dipole_cmd);
  f(FieldId::m_B_cmd, c.magnetic.m_B_cmd);
  f(FieldId::B_B, c.magnetic.B_B);
  f(FieldId::h_wheels_B, c.magnetic.h_wheels_B);
  f(FieldId::wheel_fill, c.magnetic.wheel_fill);
  f(FieldId::unloading, static_cast<double>(c.magnetic.unloading));
  f(FieldId::detumble_mode, static_cast<double>(c.magnetic.detumble_mode));
}
template <class F>
void for_each_nav_field(const NavTelemetry& t, F&& f) {
  f(FieldId::sigma_BN_est, t.sigma_est);
  f(FieldId::bias_est, t.bias_est);
  f(FieldId::bias_true, t.bias_true);
  f(FieldId::P_diag, t.P_diag);
  f(FieldId::att_est_error, t.att_error);
  f(FieldId::innovation, t.innovation);
  f(FieldId::nis, t.nis);
  f(FieldId::gyro_cal_est, t.cal_est);
  f(FieldId::gyro_cal_3sigma, t.cal_3sigma);
}

// The closed loop's rows: one buffer, column-major by field (fields.hpp):
// field f's values are the block [field_offset(f) capacity,
// (field_offset(f) + width) capacity), row after row inside it (a row's
// values contiguous, as the Python dict's (rows, width) arrays).
struct ClosedLoopResult {
  int rows = 0;           //!< rows written (n_ctrl + 1 unless diverged)
  bool diverged = false;  //!< the plant state became non-finite
  LawFailures law_failures;  //!< the law's contained failures (Controller::law_failures)
  std::vector<std::string> telemetry_names;  //!< the law's (Controller::telemetry_names): the telemetry columns
  std::size_t capacity = 0;  //!< rows of room (reserve_rows)
  bool nav = false;          //!< the kNav fields have room (a run with sensors)
  std::vector<double> data;  //!< capacity x row_width(nav ? kNav : kLoop) values, field blocks

  //! Room for n rows (the kNav fields too when nav): sized once, then
  //! overwritten chunk after chunk (ClosedLoop::run).
  void reserve_rows(std::size_t n, bool nav);
  //! Field f's block: row i's values at col(f) + i width(f).
  double* col(FieldId f) { return data.data() + static_cast<std::size_t>(field_offset(f)) * capacity; }
  const double* col(FieldId f) const {
    return data.data() + static_cast<std::size_t>(field_offset(f)) * capacity;
  }
  //! Write row i of field f (an Eigen vector of its width, or one number).
  template <class V>
  void put(FieldId f, int i, const V& v) {
    double* d = col(f) + static_cast<std::size_t>(i) * static_cast<std::size_t>(field_width(f));
    if constexpr (std::is_arithmetic_v<V>) {
      *d = static_cast<double>(v);
    } else {
      for (int j = 0; j < v.size(); ++j) d[j] = v(j);
    }
  }
};

// The offline closed loop as a resumable object: run() advances it by a
// number of control instants and writes their rows from row 0 of `out`, so
// a long run can be recorded chunk by chunk in buffers of a fixed size
// (memory independent of the duration). Without `out` it records nothing:
// the same arithmetic (law, wheels, plant) without the recording, the bare
// loop bench/bench_sim.py compares the engine with.
class ClosedLoop {
 public:
  ClosedLoop(const ControllerConfig& cfg, const PlantParams& plant, const ActuatorParams& act,
             const PlantState& x0, int n_ctrl, int n_sub, double rate, const NavConfig* nav = nullptr);
  ~ClosedLoop();
  ClosedLoop(const ClosedLoop&) = delete;
  ClosedLoop& operator=(const ClosedLoop&) = delete;
  //! Up to `rows` more control instants (fewer at the end or where the plant
  //! diverged); the rows written (out->rows is set to it when out is given).
  int run(int rows, ClosedLoopResult* out);
  bool done() const { return done_; }
  bool diverged() const { return diverged_; }
  int next_row() const { return k_; }  //!< the index of the next control instant
  const PlantState& state() const { return x_; }  //!< the plant state at next_row()'s instant
  const LawFailures& law_failures() const;
  //! the law's telemetry names (the columns of the result's telemetry field)
  const std::vector<std::string>& telemetry_names() const;

 private:
  PlantParams plant_;  // copies: the loop outlives its caller's arguments (chunked runs)
  ActuatorParams act_;
  LumpedDisturbance delta2_;  // the recorded delta_2, its model built once
  std::unique_ptr<Controller> ctl_;
  std::unique_ptr<Navigation> nv_;
  NavTelemetry tel_;
  PlantState x_;
  WheelCarry motor_;  // torque-commanded wheels' carried state: motor torques (a lag's), Stribeck switches
  int n_ctrl_, n_sub_;
  double rate_, h_;
  std::int64_t next_ = 0;  // the next plant step at which a sensor is due
  int k_ = 0;
  bool done_ = false, diverged_ = false;
  bool mag_ = false;   // magnetic control: the controller gets the true field in B
  bool rods_ = false;  // and its rod commands reach the plant's rods
  bool mag_meas_ = false;  // magnetic control with sensors: the controller gets the magnetometer's field
  // the navigation's tick i at t from the current state (the magnetometer's true field evaluated when due)
  void tick(std::int64_t i, double t);
};

// n_ctrl control periods of 1/rate s (n_ctrl + 1 rows, t_k = k / rate), each
// integrated with n_sub RK4 plant steps of 1/(rate n_sub) s.
// nav (optional): sensors and estimator (mekf.hpp), ticked at the plant
// steps i = k n_sub + j where a sensor samples or delivers (next_tick), from
// the state at the step's start; the law gets
// nav->measure(), the row's flags include the navigation's; with magnetic
// control its magnetic part gets nav->field_B(), the magnetometer's (which
// must be enabled: std::invalid_argument otherwise). Without nav the loop is
// exactly the one without sensors.
// (A ClosedLoop run whole into one result.)
ClosedLoopResult simulate_closed_loop(const ControllerConfig& cfg, const PlantParams& plant,
                                      const ActuatorParams& act, const PlantState& x0, int n_ctrl,
                                      int n_sub, double rate, const NavConfig* nav = nullptr);

}  // namespace sc_rt
