#include "sc_rt/plant.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "plant_kernels.hpp"
#include "sc_rt/util.hpp"

namespace sc_rt {

using detail::dist3;
using detail::held_dipole;
using detail::inv3;
using detail::MagField;
using detail::OrbitGG;
using detail::Rhs;
using detail::WheelMap;

namespace {

std::string idx(const char* name, int i) {
  return std::string(name) + "[" + std::to_string(i) + "]";
}

void check_spd(const Mat3& M, const std::string& name, std::vector<std::string>& errs) {
  if ((M - M.transpose()).cwiseAbs().maxCoeff() > 1e-9 * M.cwiseAbs().maxCoeff()) {
    errs.push_back(name + " is not symmetric: " + format_matrix(M));
    return;
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> es(0.5 * (M + M.transpose()), Eigen::EigenvaluesOnly);
  if (!(es.eigenvalues().minCoeff() > 0.0))
    errs.push_back(name + " is not positive definite (eigenvalues " +
                   format_matrix(es.eigenvalues()) + "): " + format_matrix(M));
}

void check_fault(const WheelFault& f, const std::string& pre, std::vector<std::string>& errs) {
  if (!f.active) return;
  if (!(f.effectiveness >= 0.0 && f.effectiveness <= 1.0))
    errs.push_back(pre + "effectiveness must be in [0, 1], got " + format_double(f.effectiveness));
  if (!std::isfinite(f.bias))
    errs.push_back(pre + "bias must be finite, got " + format_double(f.bias));
  if (!std::isfinite(f.onset))
    errs.push_back(pre + "onset must be finite, got " + format_double(f.onset));
  else if (!(f.end > f.onset))  // NaN fails too; +inf: never ends
    errs.push_back(pre + "end must be > onset (" + format_double(f.onset) + "), got " +
                   format_double(f.end));
  if (!(std::isfinite(f.rate) && f.rate > 0.0))
    errs.push_back(pre + "rate must be finite and > 0, got " + format_double(f.rate));
  if (!(std::isfinite(f.friction) && f.friction >= 0.0))
    errs.push_back(pre + "friction must be finite and >= 0, got " + format_double(f.friction));
}

// (15) saturation as comparisons, NaN stays NaN (actuators.py _sat4).
void sat4(const ActuatorParams& a, const Vec4& u, double out[4]) {
  for (int i = 0; i < 4; ++i) {
    const double ui = u(i), lo = a.umin(i), hi = a.umax(i);
    out[i] = ui < lo ? lo : (ui > hi ? hi : ui);
  }
}

// Actual accelerations (15),(16), stuck wheels, then the finite wheel-speed
// limits (actuators.py _accel4). omega is read only for a finite limit.
void accel4(const ActuatorParams& a, double t, const double sat[4], const double omega[4],
            double acc[4]) {
  for (int i = 0; i < 4; ++i) {
    acc[i] = sat[i];
    const WheelFault& f = a.faults[static_cast<std::size_t>(i)];
    if (f.active && f.onset <= t && t < f.end) {
      if (f.stuck) {
        acc[i] = 0.0;
      } else {
        const double Y = -std::expm1(-f.rate * (t - f.onset));  // (16)
        const double s = sat[i];
        acc[i] = s + Y * ((f.effectiveness - 1.0) * s + f.bias);  // (15)
      }
    }
  }
  for (int i = 0; i < 4; ++i) {
    const double wm = a.max_wheel_speed(i);
    if (!std::isfinite(wm)) continue;
    const double w = omega[i];
    if ((w >= wm && acc[i] > 0.0) || (w <= -wm && acc[i] < 0.0)) acc[i] = 0.0;
  }
}

bool any_fault(const ActuatorParams& a) {
  for (const WheelFault& f : a.faults)
    if (f.active) return true;
  return false;
}

bool any_limit(const ActuatorParams& a) {
  for (int i = 0; i < 4; ++i)
    if (std::isfinite(a.max_wheel_speed(i))) return true;
  return false;
}

void unpack(const PlantState& x, double s[3], double w[3], double O[4]) {
  for (int i = 0; i < 3; ++i) s[i] = x.sigma_BN(i), w[i] = x.omega_BN_B(i);
  for (int i = 0; i < 4; ++i) O[i] = x.wheel_speed(i);
}

}  // namespace

std::vector<std::string> validate(const PlantParams& p) {
  std::vector<std::string> errs;
  const bool J0_ok = p.J0.allFinite();
  const bool dJ_ok = p.dJ.allFinite();
  if (!J0_ok) errs.push_back("J0 is not finite: " + format_matrix(p.J0));
  else check_spd(p.J0, "J0", errs);
  if (!dJ_ok) errs.push_back("dJ is not finite: " + format_matrix(p.dJ));
  else if ((p.dJ - p.dJ.transpose()).cwiseAbs().maxCoeff() >
           1e-9 * std::max(1.0, p.dJ.cwiseAbs().maxCoeff()))
    errs.push_back("dJ is not symmetric: " + format_matrix(p.dJ));
  if (J0_ok && dJ_ok) {
    const Mat3 J = p.J0 + p.dJ;
    const Eigen::SelfAdjointEigenSolver<Mat3> es(0.5 * (J + J.transpose()), Eigen::EigenvaluesOnly);
    if (!(es.eigenvalues().minCoeff() > 0.0))
      errs.push_back("J0 + dJ (the true inertia J) is not positive definite (eigenvalues " +
                     format_matrix(es.eigenvalues()) + "): " + format_matrix(J));
  }
  if (!p.Cbar.allFinite()) errs.push_back("Cbar is not finite: " + format_matrix(p.Cbar));
  else
    for (int i = 0; i < 4; ++i) {
      const double n = p.Cbar.col(i).norm();
      if (std::abs(n - 1.0) > 1e-2)
        errs.push_back("Cbar column " + std::to_string(i) + " is not a unit vector (norm " +
                       format_double(n) + ")");
    }
  for (int i = 0; i < 4; ++i)
    if (!(std::isfinite(p.Jw(i)) && p.Jw(i) > 0.0))
      errs.push_back(idx("Jw", i) + " must be > 0, got " + format_double(p.Jw(i)));
  if (!(std::isfinite(p.w0) && p.w0 >= 0.0))
    errs.push_back("w0 must be finite and >= 0, got " + format_double(p.w0));
  if (!p.dist_amp.allFinite())
    errs.push_back("dist_amp is not finite: " + format_matrix(p.dist_amp));
  if (!p.dist_freq.allFinite())
    errs.push_back("dist_freq is not finite: " + format_matrix(p.dist_freq));
  if (!p.dist_bias.allFinite())
    errs.push_back("dist_bias is not finite: " + format_matrix(p.dist_bias));
  if (p.orbit.enabled)
    for (const std::string& e : validate(p.orbit)) errs.push_back("orbit." + e);
  if (!p.residual_dipole.allFinite())
    errs.push_back("residual_dipole is not finite: " + format_matrix(p.residual_dipole));
  if (p.field && !p.orbit.enabled) errs.push_back("field needs an orbit (orbit.enabled)");
  if (p.rods.enabled) {
    for (const std::string& e : validate(p.rods.params)) errs.push_back("rods." + e);
    for (std::size_t i = 0; i < p.rods.fault.size(); ++i)
      if (p.rods.fault[i] != RodFault::Healthy &&
          !(std::isfinite(p.rods.stuck[i]) && std::isfinite(p.rods.onset[i]) && p.rods.end[i] > p.rods.onset[i]))
        errs.push_back("rods: rod " + std::to_string(i + 1) + "'s fault needs a finite dipole and onset, end > onset");
  }
  return errs;
}

Vec3 rods_dipole_B(const PlantRods& r, double t, const RodVec* d_cmd, RodVec* applied) {
  const int n = static_cast<int>(r.params.G_B.cols());
  double d[kMaxRods];
  for (int i = 0; i < n; ++i) {
    const double lim = r.params.dipole_max(i);
    const double c = d_cmd != nullptr ? (*d_cmd)(i) : 0.0;
    d[i] = std::min(std::max(c, -lim), lim);  // per-rod clip, as MtbEffector
  }
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (r.fault[k] == RodFault::Healthy || !(r.onset[k] <= t && t < r.end[k])) continue;
    if (r.fault[k] == RodFault::Dead) d[i] = 0.0;
    else if (r.fault[k] == RodFault::Stuck) d[i] = r.stuck[k];
    else d[i] = -d[i];
  }
  if (applied != nullptr) {  // (a fixed-capacity vector: no allocation)
    applied->resize(n);
    for (int i = 0; i < n; ++i) (*applied)(i) = d[i];
  }
  Vec3 m;
  for (int row = 0; row < 3; ++row) {
    double s = r.params.G_B(row, 0) * d[0];
    for (int i = 1; i < n; ++i) s = s + r.params.G_B(row, i) * d[i];
    m(row) = s;
  }
  return m;
}

bool plant_field_B(const PlantParams& p, double t, const Vec3& sigma_BN, Vec3& B_B) {
  if (!p.field) return false;
  const double none[3] = {1.0, 0.0, 0.0};  // any non-null dipole: MagField then evaluates the field
  const detail::MagField mag(p, none);
  double mb[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  mag(t, mb);  // mb[3..5]: B_N [T]
  double r[3];
  detail::rotate_to_B(sigma_BN(0), sigma_BN(1), sigma_BN(2), mb[3], mb[4], mb[5], r);
  B_B = Vec3(r[0], r[1], r[2]);
  return true;
}

std::shared_ptr<const GeomagField> plant_field(const OrbitParams& orbit, const std::string& model) {
  if (model == "none") return nullptr;
  return std::make_shared<const GeomagField>(geomag_model_coefficients(model, decimal_year(orbit.jd_epoch)));
}

std::vector<std::string> validate(const WheelFault& f) {
  std::vector<std::string> errs;
  check_fault(f, "", errs);
  return errs;
}

std::vector<std::string> validate(const ActuatorParams& a) {
  std::vector<std::string> errs;
  for (int i = 0; i < 4; ++i) {
    const double lo = a.umin(i), hi = a.umax(i);
    if (!(std::isfinite(lo) && std::isfinite(hi)))
      errs.push_back(idx("umin", i) + "/" + idx("umax", i) + " must be finite, got " +
                     format_double(lo) + ", " + format_double(hi));
    else if (!(lo < hi))
      errs.push_back(idx("umin", i) + " must be < " + idx("umax", i) + ": umin = " +
                     format_double(lo) + ", umax = " + format_double(hi));
    if (!(a.max_wheel_speed(i) > 0.0))  // NaN fails too; +inf: no limit
      errs.push_back(idx("max_wheel_speed", i) + " must be > 0, got " +
                     format_double(a.max_wheel_speed(i)));
    const WheelFault& f = a.faults[static_cast<std::size_t>(i)];
    check_fault(f, idx("faults", i) + ".", errs);
    if (f.active && f.friction != 1.0 && !a.wheels.enabled)
      errs.push_back(idx("faults", i) + ".friction needs torque-commanded wheels (wheels.enabled)");
    if (a.wheels.enabled) {
      const WheelLimits& l = a.wheels.limits[static_cast<std::size_t>(i)];
      const WheelFriction& fr = a.wheels.friction[static_cast<std::size_t>(i)];
      const double v[] = {l.u_max, l.u_min, l.p_max, l.omega_max, fr.coulomb, fr.static_, fr.beta, fr.viscous,
                          fr.omega_limit_cycle};
      for (double x : v)
        if (!(std::isfinite(x) && x >= 0.0)) {
          errs.push_back(idx("wheels", i) + ": limits and friction must be finite and >= 0, got " +
                         format_double(x));
          break;
        }
    }
  }
  if (a.wheels.enabled && a.wheels.stribeck && a.wheels.stribeck_switching)
    errs.push_back("wheels: stribeck (always on) and stribeck_switching (Basilisk's switch) exclude each other");
  return errs;
}

double fault_Y(const WheelFault& f, double t) {
  // (16): 0 before onset, 1 - exp(-a (t - T)) from onset, 0 from the end on
  if (f.active && f.onset <= t && t < f.end) return -std::expm1(-f.rate * (t - f.onset));
  return 0.0;
}

WheelOutput wheel_accel(const ActuatorParams& a, double t, const Vec4& u_cmd,
                        const Vec4& wheel_speed) {
  double sat[4], omega[4], acc[4];
  sat4(a, u_cmd, sat);
  for (int i = 0; i < 4; ++i) omega[i] = wheel_speed(i);
  accel4(a, t, sat, omega, acc);
  WheelOutput out;
  for (int i = 0; i < 4; ++i) {
    out.u_sat(i) = sat[i];
    out.accel(i) = acc[i];
    out.Y(i) = fault_Y(a.faults[static_cast<std::size_t>(i)], t);
  }
  return out;
}

Vec3 disturbance(const PlantParams& p, double t) {
  double d[3];
  dist3(p, t, d);
  return Vec3(d[0], d[1], d[2]);
}

PlantState plant_derivative(const PlantParams& p, double t, const PlantState& x,
                            const Vec4& wheel_accel, const Vec3* dipole_B) {
  const Rhs f(p.J0 + p.dJ, p.w0);
  const WheelMap wheel(p);
  const OrbitGG gg(p);
  double m[3], mb[6];
  const MagField mag(p, held_dipole(p, dipole_B, m) ? m : nullptr);
  double s[3], w[3], O[4], acc[4], hw[3], tw[3], d[3], k[6], g[4];
  unpack(x, s, w, O);
  for (int i = 0; i < 4; ++i) acc[i] = wheel_accel(i);
  wheel(O, hw);
  wheel(acc, tw);
  dist3(p, t, d);
  f(s, w, hw, tw, d, k, gg(t, g), mag(t, mb));
  PlantState dx;
  dx.sigma_BN = Vec3(k[0], k[1], k[2]);
  dx.omega_BN_B = Vec3(k[3], k[4], k[5]);
  dx.wheel_speed = wheel_accel;
  return dx;
}

PlantState plant_rk4_step(const PlantParams& p, const ActuatorParams& a, double t,
                          const PlantState& x, double h, const Vec4& u_cmd, const Vec3* dipole_B) {
  if (a.wheels.enabled) return torque_rk4_step(p, a, t, x, h, u_cmd, nullptr, dipole_B);
  Vec3 rod_m;  // no dipole input: the rods' for a zero command (plant.py rk4_step)
  if (dipole_B == nullptr && p.rods.enabled) {
    rod_m = rods_dipole_B(p.rods, t);
    dipole_B = &rod_m;
  }
  // The mirror of plant.py rk4_step, operation for operation. The wheel
  // states enter (7) only through hw = Cbar Jw Omega_w and tw = Cbar Jw
  // Omega_w_dot: a stage's hw is hw0 + c tw_prev (linearity), not Cbar Jw
  // (Omega_0 + c a_prev), which rounds differently.
  const Rhs f(p.J0 + p.dJ, p.w0);
  const WheelMap wheel(p);
  double s[3], w[3], O[4], sat[4];
  unpack(x, s, w, O);
  sat4(a, u_cmd, sat);
  const double hh = 0.5 * h;
  const double tm = t + hh;
  const double te = t + h;
  double d1[3], dm[3], de[3];
  dist3(p, t, d1);
  dist3(p, tm, dm);
  dist3(p, te, de);
  // the orbit's gravity-gradient terms at the three stage times (null: none)
  const OrbitGG gg(p);
  double gb1[4], gbm[4], gbe[4];
  const double* g1 = gg(t, gb1);
  const double* gm = gg(tm, gbm);
  const double* ge = gg(te, gbe);
  // the body dipole over the step and the field at the three stage times (null: none)
  double m[3], mb1b[6], mbmb[6], mbeb[6];
  const MagField mag(p, held_dipole(p, dipole_B, m) ? m : nullptr);
  const double* mb1 = mag(t, mb1b);
  const double* mbm = mag(tm, mbmb);
  const double* mbe = mag(te, mbeb);
  const bool limit = any_limit(a);
  const bool timed = any_fault(a) || limit;
  double hw[3];
  wheel(O, hw);
  // stage accelerations A, B, C, E; wheel torques ta, tb, tc, te_;
  // stages k1 = (p, q), k2 = (P, Q), k3 = (u, v), k4 = (U, V) as in plant.py
  double A[4], B[4], C[4], E[4], ta[3], tb[3], tc[3], tE[3];
  double k1[6], k2[6], k3[6], k4[6], xs[3], xw[3], xh[3], xO[4];
  // stage 1 at (t, x0)
  if (timed) accel4(a, t, sat, O, A);
  else
    for (int i = 0; i < 4; ++i) A[i] = sat[i];
  wheel(A, ta);
  f(s, w, hw, ta, d1, k1, g1, mb1);
  // stage 2 at (t + h/2, x0 + h/2 k1)
  if (timed) {
    for (int i = 0; i < 4; ++i) xO[i] = O[i] + hh * A[i];
    accel4(a, tm, sat, xO, B);
    wheel(B, tb);
  } else {
    for (int i = 0; i < 4; ++i) B[i] = A[i];
    for (int i = 0; i < 3; ++i) tb[i] = ta[i];
  }
  for (int i = 0; i < 3; ++i) {
    xs[i] = s[i] + hh * k1[i];
    xw[i] = w[i] + hh * k1[3 + i];
    xh[i] = hw[i] + hh * ta[i];
  }
  f(xs, xw, xh, tb, dm, k2, gm, mbm);
  // stage 3 at (t + h/2, x0 + h/2 k2): without a speed limit, the same
  // time and acceleration as stage 2
  if (limit) {
    for (int i = 0; i < 4; ++i) xO[i] = O[i] + hh * B[i];
    accel4(a, tm, sat, xO, C);
    wheel(C, tc);
  } else {
    for (int i = 0; i < 4; ++i) C[i] = B[i];
    for (int i = 0; i < 3; ++i) tc[i] = tb[i];
  }
  for (int i = 0; i < 3; ++i) {
    xs[i] = s[i] + hh * k2[i];
    xw[i] = w[i] + hh * k2[3 + i];
    xh[i] = hw[i] + hh * tb[i];
  }
  f(xs, xw, xh, tc, dm, k3, gm, mbm);
  // stage 4 at (t + h, x0 + h k3)
  if (timed) {
    for (int i = 0; i < 4; ++i) xO[i] = O[i] + h * C[i];
    accel4(a, te, sat, xO, E);
    wheel(E, tE);
  } else {
    for (int i = 0; i < 4; ++i) E[i] = A[i];
    for (int i = 0; i < 3; ++i) tE[i] = ta[i];
  }
  for (int i = 0; i < 3; ++i) {
    xs[i] = s[i] + h * k3[i];
    xw[i] = w[i] + h * k3[3 + i];
    xh[i] = hw[i] + h * tc[i];
  }
  f(xs, xw, xh, tE, de, k4, ge, mbe);
  // x(t + h) = x0 + h/6 (k1 + 2 k2 + 2 k3 + k4)
  const double h6 = h / 6.0;
  double sn[3];
  for (int i = 0; i < 3; ++i) sn[i] = s[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
  const double ss = sn[0] * sn[0] + sn[1] * sn[1] + sn[2] * sn[2];
  if (ss > 1.0)  // MRP shadow set: same attitude, |sigma| <= 1
    for (int i = 0; i < 3; ++i) sn[i] = -sn[i] / ss;
  PlantState y;
  for (int i = 0; i < 3; ++i) {
    y.sigma_BN(i) = sn[i];
    y.omega_BN_B(i) = w[i] + h6 * (k1[3 + i] + 2.0 * (k2[3 + i] + k3[3 + i]) + k4[3 + i]);
  }
  for (int i = 0; i < 4; ++i) y.wheel_speed(i) = O[i] + h6 * (A[i] + 2.0 * (B[i] + C[i]) + E[i]);
  return y;
}

Vec3 total_momentum_N(const PlantParams& p, const PlantState& x) {
  // H_B = J omega + Cbar Jw Omega_w (3), row by row left to right, then
  // C_NB(sigma) H_B = C_BN(-sigma) H_B (rotate_to_B, orbit.hpp)
  double hb[3];
  for (int r = 0; r < 3; ++r) {
    double v = (p.J0(r, 0) + p.dJ(r, 0)) * x.omega_BN_B(0);
    v += (p.J0(r, 1) + p.dJ(r, 1)) * x.omega_BN_B(1);
    v += (p.J0(r, 2) + p.dJ(r, 2)) * x.omega_BN_B(2);
    for (int i = 0; i < 4; ++i) v += (p.Cbar(r, i) * p.Jw(i)) * x.wheel_speed(i);
    hb[r] = v;
  }
  double h[3];
  detail::rotate_to_B(-x.sigma_BN(0), -x.sigma_BN(1), -x.sigma_BN(2), hb[0], hb[1], hb[2], h);
  return Vec3(h[0], h[1], h[2]);
}

struct LumpedDisturbance::Impl {
  // As plant.py: omega_dot of (7) with the true J, the actual accelerations
  // and d(t), minus the model of (21): the same right-hand side with J0 (u_g0
  // too), the saturated commands and no d:
  // J0^-1 [-W^ (J0 W + Cbar Jw Omega_w) + u_g0 - Cbar Jw u_sat].
  const PlantParams& p;
  const Rhs f, f0;
  const WheelMap wheel;
  const OrbitGG gg;  // the true plant's u_g; the model's u_g0 keeps the w0 form of (21)
  double m[3];         // [A m^2] the residual dipole (its torque is part of delta_2)
  const MagField mag;  // the residual dipole in the field (not the magnetorquers')
  explicit Impl(const PlantParams& pp)
      : p(pp), f(pp.J0 + pp.dJ, pp.w0), f0(pp.J0, pp.w0), wheel(pp), gg(pp),
        mag(pp, held_dipole(pp, nullptr, m) ? m : nullptr) {}
  Vec3 operator()(double t, const PlantState& x, const Vec4& u_sat, const Vec4& accel) const {
    double s[3], w[3], O[4], v[4], hw[3], ta[3], tu[3], d[3], a3[6], m3[6], g[4], mb[6];
    const double zero[3] = {0.0, 0.0, 0.0};
    unpack(x, s, w, O);
    wheel(O, hw);
    for (int i = 0; i < 4; ++i) v[i] = accel(i);
    wheel(v, ta);
    for (int i = 0; i < 4; ++i) v[i] = u_sat(i);
    wheel(v, tu);
    dist3(p, t, d);
    f(s, w, hw, ta, d, a3, gg(t, g), mag(t, mb));
    f0(s, w, hw, tu, zero, m3);
    return Vec3(a3[3] - m3[3], a3[4] - m3[4], a3[5] - m3[5]);
  }
};

LumpedDisturbance::LumpedDisturbance(const PlantParams& p) : impl_(std::make_unique<Impl>(p)) {}
LumpedDisturbance::~LumpedDisturbance() = default;
Vec3 LumpedDisturbance::operator()(double t, const PlantState& x, const Vec4& u_sat, const Vec4& accel) const {
  return (*impl_)(t, x, u_sat, accel);
}

Vec3 lumped_disturbance(const PlantParams& p, double t, const PlantState& x, const Vec4& u_sat,
                        const Vec4& accel) {
  return LumpedDisturbance::Impl(p)(t, x, u_sat, accel);
}

}  // namespace sc_rt
