#include "phasecast/precompute/simulation/support_motion.h"

#include <Eigen/Geometry>

#include <cmath>

namespace phasecast::precompute {

SupportMotion::SupportMotion(const SupportSettings& settings) : settings_(settings) {
  settings_.axis.normalize();
}

double SupportMotion::pulse_shape(double t) const {
  if (settings_.pulse_tau <= 0) return 0;
  const double s = t / settings_.pulse_tau;
  return (1 - s) * std::exp(-s);
}

Eigen::Vector3d SupportMotion::velocity(const SupportState& state) const {
  return state.held + pulse_shape(state.pulse_time) * state.pulse;
}

FrameKinematics SupportMotion::kinematics(const SupportState& state) const {
  Eigen::Vector3d rate = velocity(state);
  Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();
  if (settings_.pulse_tau > 0) {
    const double s = state.pulse_time / settings_.pulse_tau;
    acceleration = state.pulse * (s - 2) / settings_.pulse_tau * std::exp(-s);  // d/dt of pulse_shape
  }
  FrameKinematics k;
  if (settings_.rotational) {
    k.angular_velocity = rate;
    k.angular_acceleration = acceleration;
  } else {
    k.linear_velocity = rate;
    k.linear_acceleration = acceleration;
  }
  return k;
}

// A held velocity that would drive the support past a range end is dropped.
Eigen::Vector3d SupportMotion::limited(const SupportState& state, const Eigen::Vector3d& w) const {
  if (!settings_.limited()) return w;
  const double s = state.coordinate.dot(settings_.axis);
  const double along = w.dot(settings_.axis);
  if ((s >= settings_.range_max && along > 0) || (s <= settings_.range_min && along < 0)) {
    return Eigen::Vector3d::Zero();
  }
  return w;
}

Eigen::Vector3d SupportMotion::impulse(SupportState& state, const Eigen::Vector3d& alpha_impulse) const {
  const Eigen::Vector3d before = velocity(state);
  if (settings_.pulse_tau > 0) {
    state.pulse = alpha_impulse;
    state.pulse_time = 0;
  } else {
    state.held = limited(state, alpha_impulse);
  }
  return velocity(state) - before;
}

Eigen::Vector3d SupportMotion::hold(SupportState& state, const Eigen::Vector3d& alpha_forcing) const {
  const Eigen::Vector3d before = velocity(state);
  state.held = limited(state, alpha_forcing);
  return velocity(state) - before;
}

Eigen::Vector3d SupportMotion::advance(SupportState& state, double h) const {
  state.coordinate += h * state.held;
  if (settings_.pulse_tau > 0) state.pulse_time += h;
  if (!settings_.limited()) return Eigen::Vector3d::Zero();
  const double s = state.coordinate.dot(settings_.axis);
  const double clamped = std::clamp(s, settings_.range_min, settings_.range_max);
  if (clamped == s) return Eigen::Vector3d::Zero();
  state.coordinate += (clamped - s) * settings_.axis;
  const Eigen::Vector3d before = velocity(state);
  state.held = limited(state, state.held);
  return velocity(state) - before;
}

Eigen::Vector3d SupportMotion::point_velocity(const Eigen::Vector3d& dw, const Eigen::Vector3d& r) const {
  return settings_.rotational ? Eigen::Vector3d(dw.cross(r - settings_.pivot)) : dw;
}

Eigen::Matrix<double, 3, 4> SupportMotion::transform(const SupportState& state) const {
  Eigen::Matrix<double, 3, 4> T;
  if (settings_.rotational) {
    Eigen::Vector3d angle = state.coordinate;
    if (settings_.pulse_tau > 0)
      angle += state.pulse_time * std::exp(-state.pulse_time / settings_.pulse_tau) * state.pulse;
    const double theta = angle.norm();
    const Eigen::Matrix3d R =
        theta > 0 ? Eigen::AngleAxisd(theta, angle / theta).toRotationMatrix() : Eigen::Matrix3d::Identity();
    T.leftCols<3>() = R;
    T.col(3) = settings_.pivot - R * settings_.pivot;
  } else {
    Eigen::Vector3d offset = state.coordinate;
    if (settings_.pulse_tau > 0)
      offset += state.pulse_time * std::exp(-state.pulse_time / settings_.pulse_tau) * state.pulse;
    T.leftCols<3>().setIdentity();
    T.col(3) = offset;
  }
  return T;
}

}  // namespace phasecast::precompute
