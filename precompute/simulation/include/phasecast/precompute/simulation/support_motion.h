#pragma once
// Motion of the rigid support (door, pot, dashboard) that the deformable
// scene is attached to. The simulator works in the support's frame (§3), so the
// support's motion enters only as fictitious forces (centrifugal, Coriolis,
// Euler, frame acceleration), as impulsive velocity changes of the particles
// when the support's velocity jumps, and as the velocity of the still air
// relative to the frame (drag).
//
// The palette parameter of a support-driven scene is a 3-vector: the support's
// angular velocity (rad/s, rotational supports) or linear velocity (m/s).
//   alpha_I (impulse): the support velocity set at the start of an entry, or,
//                      when pulse_tau > 0, the peak velocity of a jolt
//                      w(t) = alpha_I (1 - t/tau) e^(-t/tau), whose displacement
//                      alpha_I t e^(-t/tau) returns to rest;
//   alpha_F (forcing): the support velocity held while the entry is active.
// A range [range_min, range_max] (rad or m along `axis`) stops the support at
// its ends, e.g. the door's 90 degrees.

#include <Eigen/Core>

namespace phasecast::precompute {

struct SupportSettings {
  bool rotational = false;
  Eigen::Vector3d axis = Eigen::Vector3d::UnitY();  // unit
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
  double range_min = 0;  // range_min == range_max: unlimited
  double range_max = 0;
  double pulse_tau = 0;  // s; > 0: impulses are jolts

  bool limited() const { return range_max > range_min; }
};

// Everything needed to continue the support's motion from a saved state.
struct SupportState {
  Eigen::Vector3d held = Eigen::Vector3d::Zero();        // held velocity (alpha_F after range limits)
  Eigen::Vector3d pulse = Eigen::Vector3d::Zero();       // peak velocity of the running jolt
  double pulse_time = 0;                                 // s since the jolt began
  Eigen::Vector3d coordinate = Eigen::Vector3d::Zero();  // integrated held motion: angle*axis or offset
};

// Frame kinematics at one instant, in support-frame coordinates.
struct FrameKinematics {
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_acceleration = Eigen::Vector3d::Zero();
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d linear_acceleration = Eigen::Vector3d::Zero();
};

class SupportMotion {
 public:
  explicit SupportMotion(const SupportSettings& settings);

  const SupportSettings& settings() const { return settings_; }

  // Total support velocity (held + jolt) of `state`.
  Eigen::Vector3d velocity(const SupportState& state) const;
  FrameKinematics kinematics(const SupportState& state) const;

  // Applies alpha_I; returns the jump of the support velocity.
  Eigen::Vector3d impulse(SupportState& state, const Eigen::Vector3d& alpha_impulse) const;
  // Holds alpha_F (clamped by the range); returns the jump of the support velocity.
  Eigen::Vector3d hold(SupportState& state, const Eigen::Vector3d& alpha_forcing) const;
  // Advances the state by h seconds; returns the velocity jump when a range end stops the support.
  Eigen::Vector3d advance(SupportState& state, double h) const;

  // Velocity of frame point r relative to the world when the support velocity jumps by dw.
  Eigen::Vector3d point_velocity(const Eigen::Vector3d& dw, const Eigen::Vector3d& r) const;
  // 3x4 transform [R | t] taking support-frame points to the world.
  Eigen::Matrix<double, 3, 4> transform(const SupportState& state) const;

 private:
  Eigen::Vector3d limited(const SupportState& state, const Eigen::Vector3d& w) const;
  double pulse_shape(double t) const;
  SupportSettings settings_;
};

}  // namespace phasecast::precompute
