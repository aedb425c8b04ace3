// Fixed-size Eigen types used throughout the core (no heap allocation).
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross()

namespace sc_rt {
using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Matrix<double, 4, 1>;
using Mat3 = Eigen::Matrix3d;
using Mat34 = Eigen::Matrix<double, 3, 4>;
using Mat43 = Eigen::Matrix<double, 4, 3>;
}  // namespace sc_rt
