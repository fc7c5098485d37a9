#version 450 core
#include "bindings.glsl"
#include "low_rank_eval.glsl"
// The per-point pass as a compute shader (Evaluation::compute_pass): one
// invocation per scene point (x) and instance (y; with point blocks, one
// block of one instance per dispatch), writing position and
// radiance where transform feedback would (6 floats per point, instance
// after instance), for the triangle draw to read as vertex attributes.
// llvmpipe runs compute shaders on all its threads and vertex programs on
// one, so there this is the fast path (docs/performance-client.md).

layout(local_size_x = 64) in;

layout(std430, binding = PHASECAST_BINDING_EVALUATED) writeonly buffer Evaluated { float evaluated[]; };

uniform int points;      // points in this dispatch: S, or a block's (low_rank_eval.glsl)
uniform int out_base;    // where the dispatch's first point goes in Evaluated (instance i starts at i S)
uniform int out_stride;  // points per instance in Evaluated: S, or 0 for one instance per dispatch

void main() {
  uint v = gl_GlobalInvocationID.x, slot = gl_GlobalInvocationID.y;
  if (v >= uint(points)) return;
  vec3 world, rgb;
  evaluate_point(v, slot + uint(instance_base), world, rgb);
  uint at = 6u * (uint(out_base) + slot * uint(out_stride) + v);
  evaluated[at] = world.x;
  evaluated[at + 1u] = world.y;
  evaluated[at + 2u] = world.z;
  evaluated[at + 3u] = rgb.r;
  evaluated[at + 4u] = rgb.g;
  evaluated[at + 5u] = rgb.b;
}
