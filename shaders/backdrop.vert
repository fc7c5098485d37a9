#version 450 core
// The backdrop's ground: one square on the plane y = ground_height around
// the scene, 2 * ground_extent on a side, drawn as a triangle strip of 4
// vertices made from gl_VertexID (no vertex data). Its projection has its
// own near and far planes around the square (the scene's would cut it off);
// depth is not tested, so they change nothing else.

uniform mat4 view_projection;
uniform float ground_height;
uniform vec2 ground_centre;  // x, z under the scene's centre
uniform float ground_extent;

out vec3 world_position;

void main() {
  vec2 corner = vec2(float(gl_VertexID & 1), float((gl_VertexID >> 1) & 1)) * 2.0 - 1.0;
  world_position = vec3(ground_centre.x + ground_extent * corner.x, ground_height,
                        ground_centre.y + ground_extent * corner.y);
  gl_Position = view_projection * vec4(world_position, 1.0);
}
