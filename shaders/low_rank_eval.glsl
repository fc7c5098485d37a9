// The low-rank evaluation of one scene point of one instance (§5.3), shared
// by low_rank.vert (per-point pass with transform feedback, or inside the
// triangle draw) and low_rank.comp (per-point pass as a compute shader).
// Spliced in by embed_shaders.cmake after bindings.glsl.
//
// GPU layout (packed by low_rank_renderer.cpp from the row-major protocol
// layout): ranks are padded to whole vec4 blocks, r_u4 = ceil(r_u / 4) and
// r_a4 = ceil(r_a / 4), so each basis row is read with vec4 loads, and the
// bases lie in point rows or point tiles (BasisLayout; bindings.glsl,
// PHASECAST_TILED, whose tile size the renderer defines per program).

#ifndef PHASECAST_TEXEL_READS
layout(std430, binding = PHASECAST_BINDING_MEAN_SHAPE) readonly buffer MeanShape { float x_bar[]; };         // 3S (eq. 7)
layout(std430, binding = PHASECAST_BINDING_DISPLACEMENT_BASIS) readonly buffer DisplacementBasis { vec4 U_u[]; };   // tiled, 3 r_u4 per point
// The same buffer with --half: each vec4 as four 16-bit floats in two uints.
layout(std430, binding = PHASECAST_BINDING_DISPLACEMENT_BASIS) readonly buffer DisplacementBasisHalf { uvec2 U_u_half[]; };
layout(std430, binding = PHASECAST_BINDING_POINT_FLAGS) readonly buffer PointFlags { uint flags[]; };         // bit 0 deformable, 1 attached
layout(std430, binding = PHASECAST_BINDING_REST_NORMALS) readonly buffer RestNormals { float normals[]; };     // 3S
layout(std430, binding = PHASECAST_BINDING_REDUCED) readonly buffer Reduced { vec4 q[]; };                // [instance]: q_u (r_u4) then q_a (r_a4)
layout(std430, binding = PHASECAST_BINDING_MEAN_DOTTED) readonly buffer MeanDotted { vec4 M_dot[]; };         // [dotted copy][S]: xyz = M_bar_c . L_c
layout(std430, binding = PHASECAST_BINDING_BASIS_DOTTED) readonly buffer BasisDotted { vec4 U_dot[]; };        // [dotted copy] tiled, 3 r_a4 per point: (U_a . L)_j

// SH light, coefficient 16c + k in light[base + 4c + k / 4][k % 4]; base 0 is
// the world light rotated into the instance's frame, base 12 the same light
// rotated into its support frame. Instances that see the same light share
// one light-dotted copy of the transfer (dotted.x).
struct Instance {  // PHASECAST_INSTANCE_VEC4S vec4s
  mat4 placement;  // instance frame -> world
  mat4 support;    // support frame -> world (the placement included)
  vec4 light[24];
  vec4 dotted;  // x: the light-dotted copy its points read, as a float
};
layout(std430, binding = PHASECAST_BINDING_INSTANCES) readonly buffer Instances { Instance instances[]; };

vec3 x_bar_at(uint v) { return vec3(x_bar[3u * v], x_bar[3u * v + 1u], x_bar[3u * v + 2u]); }
vec4 U_u_at(uint i) {
#ifdef PHASECAST_HALF_BASES  // --half: defined by low_rank_renderer.cpp, one program per precision
  uvec2 h = U_u_half[i];
  return vec4(unpackHalf2x16(h.x), unpackHalf2x16(h.y));
#else
  return U_u[i];
#endif
}
uint flags_at(uint v) { return flags[v]; }
vec3 normal_at(uint v) { return vec3(normals[3u * v], normals[3u * v + 1u], normals[3u * v + 2u]); }
vec4 q_at(uint i) { return q[i]; }
vec4 M_dot_at(uint v) { return M_dot[v]; }
vec4 U_dot_at(uint i) { return U_dot[i]; }
// Instance i's support transform for attached points, else its placement.
mat4 frame_of(uint i, bool attached) { return attached ? instances[i].support : instances[i].placement; }
vec4 light_of(uint i, int k) { return instances[i].light[k]; }
uint dotted_copy_of(uint i) { return uint(instances[i].dotted.x); }
#else
// The same buffers read as buffer textures on the texture units numbered as
// their storage bindings (low_rank.comp and light_dot.comp on llvmpipe, ComputeReads): Mesa 22's
// llvmpipe loads from a storage buffer one lane at a time, with a branch per
// lane and value, while a texel fetch is one gather for all lanes
// (docs/performance-client.md). The values and the sums are the same.
layout(binding = PHASECAST_BINDING_MEAN_SHAPE) uniform samplerBuffer x_bar_texels;  // RGB32F, S
#ifdef PHASECAST_HALF_BASES
layout(binding = PHASECAST_BINDING_DISPLACEMENT_BASIS) uniform usamplerBuffer U_u_texels;  // RG32UI: a vec4 as 4 halves
#else
layout(binding = PHASECAST_BINDING_DISPLACEMENT_BASIS) uniform samplerBuffer U_u_texels;  // RGBA32F
#endif
layout(binding = PHASECAST_BINDING_POINT_FLAGS) uniform usamplerBuffer flags_texels;   // R32UI
layout(binding = PHASECAST_BINDING_REST_NORMALS) uniform samplerBuffer normal_texels;  // RGB32F
layout(binding = PHASECAST_BINDING_REDUCED) uniform samplerBuffer q_texels;            // RGBA32F
layout(binding = PHASECAST_BINDING_MEAN_DOTTED) uniform samplerBuffer M_dot_texels;    // RGBA32F
layout(binding = PHASECAST_BINDING_BASIS_DOTTED) uniform samplerBuffer U_dot_texels;   // RGBA32F
layout(binding = PHASECAST_BINDING_INSTANCES) uniform samplerBuffer instance_texels;   // RGBA32F, as struct Instance

vec3 x_bar_at(uint v) { return texelFetch(x_bar_texels, int(v)).xyz; }
vec4 U_u_at(uint i) {
#ifdef PHASECAST_HALF_BASES
  uvec2 h = texelFetch(U_u_texels, int(i)).xy;
  return vec4(unpackHalf2x16(h.x), unpackHalf2x16(h.y));
#else
  return texelFetch(U_u_texels, int(i));
#endif
}
uint flags_at(uint v) { return texelFetch(flags_texels, int(v)).x; }
vec3 normal_at(uint v) { return texelFetch(normal_texels, int(v)).xyz; }
vec4 q_at(uint i) { return texelFetch(q_texels, int(i)); }
vec4 M_dot_at(uint v) { return texelFetch(M_dot_texels, int(v)); }
vec4 U_dot_at(uint i) { return texelFetch(U_dot_texels, int(i)); }
// Instance i's texels: placement columns 0-3, support columns 4-7, lights
// 8-31, its dotted copy 32; the matrix is chosen before it is fetched.
int instance_texel(uint i) { return PHASECAST_INSTANCE_VEC4S * int(i); }
mat4 frame_of(uint i, bool attached) {
  int t = instance_texel(i) + (attached ? 4 : 0);
  return mat4(texelFetch(instance_texels, t), texelFetch(instance_texels, t + 1), texelFetch(instance_texels, t + 2),
              texelFetch(instance_texels, t + 3));
}
vec4 light_of(uint i, int k) { return texelFetch(instance_texels, instance_texel(i) + 8 + k); }
uint dotted_copy_of(uint i) { return uint(texelFetch(instance_texels, instance_texel(i) + 32).x); }
#endif

// Ranks in vec4 blocks and whether there is an appearance model: fixed per
// scene, so the renderer defines them per program (with_defines) and the
// loops over them unroll.
const int r_u4 = PHASECAST_R_U4;
const int r_a4 = PHASECAST_R_A4;
const bool has_transfer = PHASECAST_HAS_TRANSFER;  // false: the scene has no appearance model (§4)
// Scenes larger than one storage block are drawn a block of points at a
// time, one instance at a time, with every per-point buffer bound from the
// block's first point (low_rank_renderer.cpp, "point blocks"); otherwise
// first_point and instance_base are 0 and dotted_stride is S rounded up to 64.
uniform int first_point;    // gl_VertexID of the bound buffers' first point
uniform int instance_base;  // added to gl_InstanceID
uniform int dotted_stride;  // points per dotted copy in the bound MeanDotted, BasisDotted

// Eq. 7: x = x_bar + U_u q_u for deformable points.
// v: the point's index in the bound per-point buffers.
vec3 displaced_position(uint v, bool deformable, uint q0) {
  vec3 x = x_bar_at(v);
  if (deformable) {
    uint n = uint(r_u4), w = 3u * n;
    for (uint b = 0u; b < n; ++b) {
      vec4 qb = q_at(q0 + b);
      x += vec3(dot(U_u_at(PHASECAST_TILED(v, b, w)), qb), dot(U_u_at(PHASECAST_TILED(v, n + b, w)), qb),
                dot(U_u_at(PHASECAST_TILED(v, 2u * n + b, w)), qb));
    }
  }
  return x;
}

// §4.2: exit radiance = (M_bar + U_a q_a) . L per colour channel, from the
// light-dotted form (light_dot.vert): M_bar.L + sum_j (U_a.L)_j q_a[j].
// v: the point's index in the bound dotted buffers.
vec3 transfer_radiance(uint v, uint q0) {
  vec3 rgb = M_dot_at(v).xyz;
  uint n = uint(r_a4), qa = q0 + uint(r_u4);
  for (uint c = 0u; c < 3u; ++c) {
    for (uint b = 0u; b < n; ++b) rgb[c] += dot(U_dot_at(PHASECAST_TILED(v, c * n + b, 3u * n)), q_at(qa + b));
  }
  return rgb;
}

// Without an appearance model: unshadowed grey diffuse from the rest normal,
// (rho/pi) sum_k A_l Y_k(n) L_k (Ramamoorthi & Hanrahan 2001), bands 0..2.
vec3 fallback_radiance(uint v, uint i, int base) {
  vec3 n = normalize(normal_at(v));
  vec4 y0 = vec4(0.2820948, -0.4886025 * n.y, 0.4886025 * n.z, -0.4886025 * n.x);
  vec4 y1 = vec4(1.0925484 * n.x * n.y, -1.0925484 * n.y * n.z, 0.9461747 * n.z * n.z - 0.3153916,
                 -1.0925484 * n.x * n.z);
  float y8 = 0.5462742 * (n.x * n.x - n.y * n.y);
  vec4 a0 = vec4(3.1415927, 2.0943951, 2.0943951, 2.0943951);
  const float a2 = 0.7853982;
  vec3 rgb;
  for (int c = 0; c < 3; ++c) {
    rgb[c] = dot(a0 * y0, light_of(i, base + 4 * c)) + a2 * dot(y1, light_of(i, base + 4 * c + 1)) +
             a2 * y8 * light_of(i, base + 4 * c + 2).x;
  }
  return 0.7 / 3.1415927 * rgb;
}

// Point v (its index in the bound per-point buffers) of instance i: world
// position and linear exit radiance.
void evaluate_point(uint v, uint i, out vec3 world, out vec3 rgb) {
  uint q0 = i * uint(r_u4 + r_a4);
  uint f = flags_at(v);
  bool attached = (f & 2u) != 0u;
  vec3 x = displaced_position(v, (f & 1u) != 0u, q0);
  world = (frame_of(i, attached) * vec4(x, 1.0)).xyz;
  int base = attached ? 12 : 0;
  uint dotted = dotted_copy_of(i) * uint(dotted_stride) + v;
  rgb = has_transfer ? transfer_radiance(dotted, q0) : fallback_radiance(v, i, base);
}
