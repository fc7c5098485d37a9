#version 450 core
#include "bindings.glsl"
// The light-dotted form of the transfer model (§4.2, §5.3): per scene point
// and colour channel, M_bar . L and U_a . L (one value per transfer mode).
// Exit radiance is then M_bar.L + sum_j (U_a.L)_j q_a[j]: 3 (1 + r_a) values
// per point each frame instead of 48 (1 + r_a). A compute shader, one
// invocation per point (llvmpipe runs compute on all its threads, vertex
// shading on one), dispatched only when the light seen by the points changes:
// a new light, or a new support rotation (the light is rotated into the
// support frame for attached points).

layout(local_size_x = 64) in;

#ifndef PHASECAST_TEXEL_READS
layout(std430, binding = PHASECAST_BINDING_MEAN_TRANSFER) readonly buffer MeanTransfer { vec4 M_bar[]; };  // tiled, [3][4] per point: k in vec4s
layout(std430, binding = PHASECAST_BINDING_TRANSFER_BASIS) readonly buffer TransferBasis { vec4 U_a[]; };  // tiled, [48][r_a4] per point
// The same buffer with --half: each vec4 as four 16-bit floats in two uints.
layout(std430, binding = PHASECAST_BINDING_TRANSFER_BASIS) readonly buffer TransferBasisHalf { uvec2 U_a_half[]; };
layout(std430, binding = PHASECAST_BINDING_POINT_FLAGS) readonly buffer PointFlags { uint flags[]; };     // bit 1 attached

vec4 M_bar_at(uint i) { return M_bar[i]; }
vec4 U_a_at(uint i) {
#ifdef PHASECAST_HALF_BASES  // --half: defined by low_rank_renderer.cpp, one program per precision
  uvec2 h = U_a_half[i];
  return vec4(unpackHalf2x16(h.x), unpackHalf2x16(h.y));
#else
  return U_a[i];
#endif
}
uint flags_at(uint v) { return flags[v]; }
#else
// The same buffers as buffer textures (ComputeReads; low_rank_eval.glsl says why).
layout(binding = PHASECAST_BINDING_MEAN_TRANSFER) uniform samplerBuffer M_bar_texels;  // RGBA32F
#ifdef PHASECAST_HALF_BASES
layout(binding = PHASECAST_BINDING_TRANSFER_BASIS) uniform usamplerBuffer U_a_texels;  // RG32UI: a vec4 as 4 halves
#else
layout(binding = PHASECAST_BINDING_TRANSFER_BASIS) uniform samplerBuffer U_a_texels;  // RGBA32F
#endif
layout(binding = PHASECAST_BINDING_POINT_FLAGS) uniform usamplerBuffer flags_texels;  // R32UI

vec4 M_bar_at(uint i) { return texelFetch(M_bar_texels, int(i)); }
vec4 U_a_at(uint i) {
#ifdef PHASECAST_HALF_BASES
  uvec2 h = texelFetch(U_a_texels, int(i)).xy;
  return vec4(unpackHalf2x16(h.x), unpackHalf2x16(h.y));
#else
  return texelFetch(U_a_texels, int(i));
#endif
}
uint flags_at(uint v) { return texelFetch(flags_texels, int(v)).x; }
#endif
layout(std430, binding = PHASECAST_BINDING_MEAN_DOTTED) writeonly buffer MeanDotted { vec4 M_dot[]; };   // [dotted copy][S]: xyz = M_bar_c . L_c
layout(std430, binding = PHASECAST_BINDING_BASIS_DOTTED) writeonly buffer BasisDotted { vec4 U_dot[]; };  // [dotted copy] tiled, [3][r_a4] per point: (U_a . L)_j

const int r_a4 = PHASECAST_R_A4;  // defined by the renderer (low_rank_eval.glsl)

uniform vec4 light[24];  // the instance's, as in low_rank.vert: its frame at 0, its support frame at 12
uniform int points;      // points to dot: S, or the block's (low_rank.vert, "point blocks")
uniform int out_base;    // where the dotted copy's values start (one copy per light the instances see)

void main() {
  uint v = gl_GlobalInvocationID.x;
  if (v >= uint(points)) return;
  int base = (flags_at(v) & 2u) != 0u ? 12 : 0;
  uint n = uint(r_a4), w = 48u * n, out_v = uint(out_base) + v;
  vec3 mean_dotted;
  for (int c = 0; c < 3; ++c) {
    vec4 sum = vec4(0.0);
    for (int kb = 0; kb < 4; ++kb) sum += M_bar_at(PHASECAST_TILED(v, uint(4 * c + kb), 12u)) * light[base + 4 * c + kb];
    mean_dotted[c] = sum.x + sum.y + sum.z + sum.w;
    for (uint b = 0u; b < n; ++b) {
      vec4 acc = vec4(0.0);
      for (int kb = 0; kb < 4; ++kb) {
        vec4 L = light[base + 4 * c + kb];
        uint row = uint(16 * c + 4 * kb);
        acc += U_a_at(PHASECAST_TILED(v, row * n + b, w)) * L.x + U_a_at(PHASECAST_TILED(v, (row + 1u) * n + b, w)) * L.y +
               U_a_at(PHASECAST_TILED(v, (row + 2u) * n + b, w)) * L.z +
               U_a_at(PHASECAST_TILED(v, (row + 3u) * n + b, w)) * L.w;
      }
      U_dot[PHASECAST_TILED(out_v, uint(c) * n + b, 3u * n)] = acc;
    }
  }
  M_dot[out_v] = vec4(mean_dotted, 0.0);
}
