// The 6-state MEKF's covariance step, by 3x3 blocks (included by mekf.cpp
// only, inside its anonymous namespace's scope of sc_rt; see MekfT::propagate_into).
#pragma once
#include <cmath>
#if defined(__SSE2__) && !defined(SC_RT_EIGEN_COVARIANCE)
#define SC_RT_SSE2_COVARIANCE 1
#include <emmintrin.h>
#endif

#include "sc_rt/mekf.hpp"

namespace sc_rt {
namespace mekf_detail {

// The covariance step of MekfT<6>::propagate_into (see there):
//   F = exp(-theta^) = I - (sin a / a) theta^ + ((1 - cos a) / a^2) theta^ theta^, a = |theta|
//   (a < 1e-8: I - theta^ + theta^ theta^ / 2)
//   T1 = F P11 - dt P12', T2 = F P12 - dt P22 (rows 1-3 of Phi P)
//   P11 <- sym(T1 F' - dt T2 + q11 I), P12 <- a T2 - q12 I, P22 <- sym(a^2 P22 + q22 I)
// sym(N) = (N + N') / 2.
#ifdef SC_RT_SSE2_COVARIANCE
// By hand in SSE2, bit for bit in the order of the Eigen expressions it replaced (kept below
// for other targets; -DSC_RT_EIGEN_COVARIANCE selects them here too, to compare): Eigen
// evaluates a 3x3 product column by column, rows 0-1 as one packet summed in k order,
// ((a0 b0 + a1 b1) + a2 b2), row 2 as a scalar reduction, a0 b0 + (a1 b1 + a2 b2). Here the
// 3x3 temporaries stay in registers (Eigen stores and reloads them: ~15 % of the propagation).
// A 3x3 M is kept as lo[j] = rows 0-1 of column j, hi[j] = row 2.
struct M3 {
  __m128d lo[3];
  double hi[3];
};
inline double row0(__m128d v) { return _mm_cvtsd_f64(v); }
inline double row1(__m128d v) { return _mm_cvtsd_f64(_mm_unpackhi_pd(v, v)); }
inline double coeff(const M3& m, int i, int j) { return i == 0 ? row0(m.lo[j]) : i == 1 ? row1(m.lo[j]) : m.hi[j]; }
// C = A B, B given by its coefficients b(k, j).
template <class B>
inline void mul(const M3& A, B b, M3& C) {
  for (int j = 0; j < 3; ++j) {
    const double b0 = b(0, j), b1 = b(1, j), b2 = b(2, j);
    __m128d r = _mm_mul_pd(A.lo[0], _mm_set1_pd(b0));
    r = _mm_add_pd(_mm_mul_pd(A.lo[1], _mm_set1_pd(b1)), r);
    r = _mm_add_pd(_mm_mul_pd(A.lo[2], _mm_set1_pd(b2)), r);
    C.lo[j] = r;
    C.hi[j] = A.hi[0] * b0 + (A.hi[1] * b1 + A.hi[2] * b2);
  }
}

inline void covariance_step(const Mat6& Pin, Mat6& Pout, const Vec3& v, double an, double dt, double a,
                            double q11, double q12, double q22) {
  const double x = v.x(), y = v.y(), z = v.z();
  const double S[3][3] = {{0.0, -z, y}, {z, 0.0, -x}, {-y, x, 0.0}};
  double c1 = 1.0, c2 = 0.5;
  const bool small = an < 1e-8;
  if (!small) {
    c1 = std::sin(an) / an;
    c2 = (1.0 - std::cos(an)) / (an * an);
  }
  M3 cS, SS, F;
  for (int j = 0; j < 3; ++j) {
    cS.lo[j] = _mm_set_pd(c2 * S[1][j], c2 * S[0][j]);
    cS.hi[j] = c2 * S[2][j];
  }
  mul(cS, [&](int k, int j) { return S[k][j]; }, SS);
  for (int j = 0; j < 3; ++j) {
    double f[3];
    for (int i = 0; i < 3; ++i) f[i] = ((i == j ? 1.0 : 0.0) - (small ? S[i][j] : c1 * S[i][j])) + coeff(SS, i, j);
    F.lo[j] = _mm_set_pd(f[1], f[0]);
    F.hi[j] = f[2];
  }
  const double* Pd = Pin.data();  // column-major, outer stride 6 (every read before the writes: Pout may be Pin)
  auto p = [Pd](int i, int j) { return Pd[i + 6 * j]; };
  M3 T1, T2, N11;
  mul(F, [&](int k, int j) { return p(k, j); }, T1);
  mul(F, [&](int k, int j) { return p(k, 3 + j); }, T2);
  const __m128d vdt = _mm_set1_pd(dt);
  for (int j = 0; j < 3; ++j) {
    T1.lo[j] = _mm_sub_pd(T1.lo[j], _mm_mul_pd(vdt, _mm_set_pd(p(j, 4), p(j, 3))));  // - dt P12'
    T1.hi[j] = T1.hi[j] - dt * p(j, 5);
    T2.lo[j] = _mm_sub_pd(T2.lo[j], _mm_mul_pd(vdt, _mm_loadu_pd(Pd + 3 + 6 * (3 + j))));  // - dt P22
    T2.hi[j] = T2.hi[j] - dt * p(5, 3 + j);
  }
  mul(T1, [&](int k, int j) { return coeff(F, j, k); }, N11);  // T1 F'
  const double aa = a * a;
  double n11[3][3], n12[3][3], n22[3][3];
  const __m128d va = _mm_set1_pd(a), vaa = _mm_set1_pd(aa);
  for (int j = 0; j < 3; ++j) {
    const __m128d l = _mm_sub_pd(N11.lo[j], _mm_mul_pd(vdt, T2.lo[j]));
    n11[0][j] = row0(l);
    n11[1][j] = row1(l);
    n11[2][j] = N11.hi[j] - dt * T2.hi[j];
    const __m128d m12 = _mm_mul_pd(va, T2.lo[j]);
    n12[0][j] = row0(m12);
    n12[1][j] = row1(m12);
    n12[2][j] = a * T2.hi[j];
    const __m128d m22 = _mm_mul_pd(vaa, _mm_loadu_pd(Pd + 3 + 6 * (3 + j)));
    n22[0][j] = row0(m22);
    n22[1][j] = row1(m22);
    n22[2][j] = aa * p(5, 3 + j);
  }
  for (int i = 0; i < 3; ++i) {
    n11[i][i] += q11;
    n12[i][i] -= q12;
    n22[i][i] += q22;
  }
  double* Pw = Pout.data();
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      Pw[i + 6 * j] = 0.5 * (n11[i][j] + n11[j][i]);
      Pw[i + 6 * (3 + j)] = n12[i][j];
      Pw[(3 + j) + 6 * i] = n12[i][j];
      Pw[(3 + i) + 6 * (3 + j)] = 0.5 * (n22[i][j] + n22[j][i]);
    }
}
#else
inline void covariance_step(const Mat6& P, Mat6& Pout, const Vec3& theta, double an, double dt, double a,
                            double q11, double q12, double q22) {
  const Mat3 S = skew(theta);
  const Mat3 F11 = an < 1e-8 ? Mat3(Mat3::Identity() - S + 0.5 * S * S)
                             : Mat3(Mat3::Identity() - (std::sin(an) / an) * S +
                                    ((1.0 - std::cos(an)) / (an * an)) * S * S);
  const Mat3 P11 = P.topLeftCorner<3, 3>(), P12 = P.topRightCorner<3, 3>(), P22 = P.bottomRightCorner<3, 3>();
  const Mat3 T1 = F11 * P11 - dt * P12.transpose();
  const Mat3 T2 = F11 * P12 - dt * P22;
  Mat3 N11 = T1 * F11.transpose() - dt * T2;
  Mat3 N12 = a * T2;
  Mat3 N22 = (a * a) * P22;
  N11.diagonal().array() += q11;
  N12.diagonal().array() -= q12;
  N22.diagonal().array() += q22;
  Pout.topLeftCorner<3, 3>() = 0.5 * (N11 + N11.transpose());
  Pout.topRightCorner<3, 3>() = N12;
  Pout.bottomLeftCorner<3, 3>() = N12.transpose();
  Pout.bottomRightCorner<3, 3>() = 0.5 * (N22 + N22.transpose());
}
#endif

}  // namespace mekf_detail
}  // namespace sc_rt
