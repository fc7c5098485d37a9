#version 450 core
#include "bindings.glsl"
#include "low_rank_eval.glsl"
// The thin client's low-rank superposition (§5.3) as a vertex program. Bases
// live in shader storage buffers uploaded once; per frame only q_u, q_a
// (buffer Reduced) and the support transforms change. No vertex attributes:
// gl_VertexID is the scene point index and gl_InstanceID the instance: many
// instances of one scene, each with its own (q_u, q_a), support and placement
// in the world, are one instanced draw. Run once per point and instance
// (glDrawArraysInstanced GL_POINTS, rasterizer off) with world_position and
// radiance captured by transform feedback for the triangle draw, or
// (Evaluation::in_draw) inside glDrawElementsInstanced. low_rank.comp is the
// same pass as a compute shader. The transfer arrives light-dotted
// (light_dot.comp).

uniform mat4 view_projection;

out vec3 world_position;  // captured by transform feedback (--dump-vertices)
out vec3 radiance;        // linear exit radiance, RGB

void main() {
  evaluate_point(uint(gl_VertexID - first_point), uint(gl_InstanceID + instance_base), world_position, radiance);
  gl_Position = view_projection * vec4(world_position, 1.0);
}
