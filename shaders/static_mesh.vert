#version 450 core
// Reference program for the benchmark: the same mesh with precomputed,
// static per-vertex positions and radiance (no low-rank evaluation), so the
// cost of the superposition in low_rank.vert can be measured in one run.

layout(location = 0) in vec3 position;
layout(location = 1) in vec3 vertex_radiance;

uniform mat4 view_projection;

out vec3 world_position;
out vec3 radiance;

void main() {
  world_position = position;
  radiance = vertex_radiance;
  gl_Position = view_projection * vec4(position, 1.0);
}
