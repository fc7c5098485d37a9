#version 450 core
// The backdrop behind the scene (phasecast-render --backdrop on): a ground
// plane at the rest mesh's lowest point (y up). It receives no transfer: a
// neutral diffuse floor lit by the light probe's irradiance for an up-facing
// normal, exposed and sRGB-encoded on the CPU (floor_colour; floor_dark is
// 12 % less radiance), with a faint checker between the two (cells of a third
// of the scene radius R) so depth reads, fading into the flat background
// colour as a Gaussian of the distance from the scene (1/e at 2.5 R, below
// 1/255 at the square's edges, so it has no visible edge). Drawn first,
// without depth: the scene is always drawn over it.

in vec3 world_position;

uniform vec2 ground_centre;
uniform float scene_radius;
uniform vec3 floor_colour;  // display values (encoded)
uniform vec3 floor_dark;
uniform vec3 background;

out vec4 colour;

// 1 on odd cells, 0 on even ones, box-filtered over the pixel's footprint so
// far cells blend to grey instead of aliasing.
float checker(vec2 p) {
  vec2 w = max(abs(dFdx(p)), abs(dFdy(p))) + 1e-4;
  vec2 i = 2.0 * (abs(fract((p - 0.5 * w) * 0.5) - 0.5) - abs(fract((p + 0.5 * w) * 0.5) - 0.5)) / w;
  return 0.5 - 0.5 * i.x * i.y;
}

void main() {
  vec2 p = (world_position.xz - ground_centre) / scene_radius;  // in scene radii
  float fade = exp(-0.16 * dot(p, p));
  colour = vec4(mix(background, mix(floor_colour, floor_dark, checker(3.0 * p)), fade), 1.0);
}
