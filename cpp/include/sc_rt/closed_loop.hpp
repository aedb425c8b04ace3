// Offline closed loop in C++ (the "cpp" engine of sc-rt sim): the plant twin
// (plant.hpp) and a controller, sampled at the control rate with a
// zero-order hold. Same loop, same order of operations as python/sc_rt/sim/engines.py.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "sc_rt/controllers.hpp"
#include "sc_rt/mekf.hpp"
#include "sc_rt/plant.hpp"

namespace sc_rt {

struct ClosedLoopResult {
  int rows = 0;           //!< rows written (n_ctrl + 1 unless diverged)
  bool diverged = false;  //!< the plant state became non-finite
  LawFailures law_failures;  //!< the law's contained failures (Controller::law_failures)
  std::vector<std::string> telemetry_names;  //!< the law's (Controller::telemetry_names): the telemetry columns
  // One row per control instant, row-major, widths as named.
  std::vector<double> t;                                           // 1
  std::vector<double> sigma_BN, omega_BN_B, sigma_DN, sigma_BD;    // 3
  std::vector<double> omega_BD_B, z1, z2, delta2, chi, lam, e1, e2, x2d;  // 3
  std::vector<double> wheel_speed, u_cmd, u_sat, wheel_accel, vs;  // 4
  std::vector<double> rho_hat;                                     // 1
  std::vector<double> telemetry;                                   // kLawMaxTelemetry: the law's named values
  std::vector<int> flags;                                          // 1
  std::vector<int> ctrl_mode;                                      // 1 (MODE_*)
  // With sensors (nav given; empty otherwise): NavTelemetry per row.
  std::vector<double> sigma_BN_est, bias_est, bias_true, att_est_error, innovation;  // 3
  std::vector<double> P_diag;                                      // 6
  std::vector<double> nis;                                         // 1

  //! Room for n rows (the navigation's columns too when nav): sized once,
  //! then overwritten chunk after chunk (ClosedLoop::run).
  void reserve_rows(std::size_t n, bool nav);
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
  //! the law's telemetry names (the columns of ClosedLoopResult::telemetry)
  const std::vector<std::string>& telemetry_names() const;

 private:
  PlantParams plant_;  // copies: the loop outlives its caller's arguments (chunked runs)
  ActuatorParams act_;
  LumpedDisturbance delta2_;  // the recorded delta_2, its model built once
  std::unique_ptr<Controller> ctl_;
  std::unique_ptr<Navigation> nv_;
  NavTelemetry tel_;
  PlantState x_;
  Vec4 motor_ = Vec4::Zero();  // the motor torques of torque-commanded wheels (their lag's state)
  int n_ctrl_, n_sub_;
  double rate_, h_;
  std::int64_t next_ = 0;  // the next plant step at which a sensor is due
  int k_ = 0;
  bool done_ = false, diverged_ = false;
};

// n_ctrl control periods of 1/rate s (n_ctrl + 1 rows, t_k = k / rate), each
// integrated with n_sub RK4 plant steps of 1/(rate n_sub) s.
// nav (optional): sensors and estimator (mekf.hpp), ticked at the plant
// steps i = k n_sub + j where a sensor samples or delivers (next_tick), from
// the state at the step's start; the law gets
// nav->measure(), the row's flags include the navigation's. Without nav the
// loop is exactly the one without sensors.
// (A ClosedLoop run whole into one result.)
ClosedLoopResult simulate_closed_loop(const ControllerConfig& cfg, const PlantParams& plant,
                                      const ActuatorParams& act, const PlantState& x0, int n_ctrl,
                                      int n_sub, double rate, const NavConfig* nav = nullptr);

}  // namespace sc_rt
