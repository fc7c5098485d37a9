#pragma once
// Diffuse precomputed radiance transfer (§4.1; Sloan, Kautz & Snyder 2002) on a
// static triangle mesh, by ray casting with Embree 3.
//
// Convention (docs/transfer.md): transfer row p holds 3 x 16 floats, index
// 16 c + k for RGB channel c and SH index k = l(l+1)+m (phasecast/core/sh.h), so
// that the exit radiance of channel c at point p under a distant SH light L is
//   L'_pc = sum_k T[p, 16 c + k] * L_ck        (§4.1: L'_p = sum_i (M_p)_i (L_p)_i)
// with albedo and the 1/pi of the diffuse BRDF included.

#include "phasecast/core/eigen_types.h"

#include <array>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>

namespace phasecast::precompute {

// Unshadowed: V = 1. Shadowed: V = 0 where the ray hits any triangle.
// Interreflected: shadowed plus `bounces` bounces of diffuse light gathered
// from the transfer at the front faces the same rays hit.
enum class TransferMode { unshadowed, shadowed, interreflected };

// "unshadowed" | "shadowed" | "interreflected"; throws std::invalid_argument otherwise.
TransferMode parse_transfer_mode(const std::string& name);
const char* transfer_mode_name(TransferMode mode);

struct TransferOptions {
  TransferMode mode = TransferMode::shadowed;
  int rays = 1024;                                // directions of the fixed sphere set
  int bounces = 2;                                // interreflected only
  std::array<float, 3> albedo{0.8f, 0.8f, 0.8f};  // rho per RGB channel, in [0, 1]
  MatrixXfR point_albedo;                         // S x 3: rho of each point (empty: `albedo` everywhere)
  int threads = 0;                                // 0: std::thread::hardware_concurrency()
  // Called from the calling thread with (stage, done, total) while work runs.
  std::function<void(const char* stage, long done, long total)> progress;
};

// Checks the options (rays >= 1, bounces >= 0, albedo and point_albedo in
// [0, 1], threads >= 0); throws std::invalid_argument naming the bad field.
void validate_transfer_options(const TransferOptions& options);

// Fixed direction set: `count` unit vectors, a spherical Fibonacci lattice
// (deterministic, equal solid angle 4 pi / count each). Returns count x 3.
MatrixXfR sphere_directions(int count);

// Diffuse transfer of every scene point.
//   @param[in] positions  #S by 3 scene points (mesh vertices)
//   @param[in] triangles  #F by 3 point indices; a triangle's front face is the
//                         side its (counter-clockwise) winding faces. A
//                         double-sided surface is two coplanar triangles with
//                         opposite windings over duplicated points; rays that
//                         hit it gather from the side they see.
//   @param[in] normals    #S by 3 unit normals (the hemisphere each point sees)
//   @param[in] options    mode, rays, bounces, albedo, threads, progress
//   @return               #S by 48 transfer (row p, column 16 c + k)
// Interreflected light takes the colour of every surface it left: bounce b
// at p gathers rho_p times bounce b-1 at the hit points (colour bleeding).
// Throws std::invalid_argument for bad shapes, indices, NaN or non-unit normals.
MatrixXfR compute_transfer(const MatrixXfR& positions, const MatrixXuR& triangles, const MatrixXfR& normals,
                           const TransferOptions& options);

}  // namespace phasecast::precompute
