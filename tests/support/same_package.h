#pragma once
// Every dataset and attribute of two scene packages is equal, bit for bit
// (gtest expectations that name what differs; packages carry no times, so
// equal content also means equal file bytes, which tests may compare too).

#include "phasecast/core/package.h"

#include <gtest/gtest.h>

namespace phasecast::testing {

inline void expect_same_package(const core::ScenePackage& a, const core::ScenePackage& b) {
  EXPECT_EQ(a.attributes.scene, b.attributes.scene);
  EXPECT_EQ(a.attributes.dt, b.attributes.dt);
  EXPECT_EQ(a.attributes.beta, b.attributes.beta);
  EXPECT_EQ(a.attributes.blend_lambda, b.attributes.blend_lambda);
  EXPECT_EQ(a.attributes.camera, b.attributes.camera);
  EXPECT_EQ(a.mesh.rest_positions, b.mesh.rest_positions);
  EXPECT_EQ(a.mesh.triangles, b.mesh.triangles);
  EXPECT_EQ(a.mesh.normals, b.mesh.normals);
  EXPECT_EQ(a.mesh.deformable, b.mesh.deformable);
  EXPECT_EQ(a.mesh.attached, b.mesh.attached);
  EXPECT_EQ(a.palette.names, b.palette.names);
  EXPECT_EQ(a.palette.alpha_impulse, b.palette.alpha_impulse);
  EXPECT_EQ(a.palette.alpha_forcing, b.palette.alpha_forcing);
  EXPECT_EQ(a.palette.transitions, b.palette.transitions);
  EXPECT_EQ(a.palette.on_end, b.palette.on_end);
  EXPECT_EQ(a.palette.group, b.palette.group);
  EXPECT_EQ(a.palette.max_in_a_row, b.palette.max_in_a_row);
  ASSERT_EQ(a.palette.kinematics.size(), b.palette.kinematics.size());
  for (size_t i = 0; i < a.palette.kinematics.size(); ++i) {
    const auto &ka = a.palette.kinematics[i], &kb = b.palette.kinematics[i];
    EXPECT_EQ(ka.axis, kb.axis);
    EXPECT_EQ(ka.pivot, kb.pivot);
    EXPECT_EQ(ka.rotational, kb.rotational);
    EXPECT_EQ(ka.rate, kb.rate);
    EXPECT_EQ(ka.range_max, kb.range_max);
  }
  EXPECT_EQ(a.reduction.mean_shape, b.reduction.mean_shape);
  EXPECT_EQ(a.reduction.U_u, b.reduction.U_u);
  EXPECT_EQ(a.reduction.singular_values, b.reduction.singular_values);
  EXPECT_EQ(a.reduction.rel_error, b.reduction.rel_error);
  EXPECT_EQ(a.portrait.q_u, b.portrait.q_u);
  EXPECT_EQ(a.portrait.qdot_u, b.portrait.qdot_u);
  EXPECT_EQ(a.portrait.q_a, b.portrait.q_a);
  EXPECT_EQ(a.portrait.irf_start, b.portrait.irf_start);
  EXPECT_EQ(a.portrait.irf_length, b.portrait.irf_length);
  EXPECT_EQ(a.portrait.irf_palette, b.portrait.irf_palette);
  EXPECT_EQ(a.portrait.nearest_irf, b.portrait.nearest_irf);
  EXPECT_EQ(a.portrait.support, b.portrait.support);
  ASSERT_EQ(a.appearance.has_value(), b.appearance.has_value());
  if (a.appearance) {
    EXPECT_EQ(a.appearance->mean_transfer, b.appearance->mean_transfer);
    EXPECT_EQ(a.appearance->U_a, b.appearance->U_a);
    EXPECT_EQ(a.appearance->cluster_nodes, b.appearance->cluster_nodes);
    EXPECT_EQ(a.appearance->nrbf_weights, b.appearance->nrbf_weights);
    EXPECT_EQ(a.appearance->nrbf_regularization, b.appearance->nrbf_regularization);
    EXPECT_EQ(a.appearance->nrbf_centers, b.appearance->nrbf_centers);
    EXPECT_EQ(a.appearance->nrbf_widths, b.appearance->nrbf_widths);
    EXPECT_EQ(a.appearance->singular_values, b.appearance->singular_values);
    EXPECT_EQ(a.appearance->rel_error, b.appearance->rel_error);
  }
}

}  // namespace phasecast::testing
