#version 450 core
// Displays the interpolated exit radiance: exposure, clamp, sRGB encoding.

in vec3 world_position;
in vec3 radiance;

uniform float exposure;

out vec4 colour;

vec3 srgb_encode(vec3 linear) {
  vec3 lo = 12.92 * linear;
  vec3 hi = 1.055 * pow(linear, vec3(1.0 / 2.4)) - 0.055;
  return mix(lo, hi, step(vec3(0.0031308), linear));
}

void main() {
  colour = vec4(srgb_encode(clamp(radiance * exposure, 0.0, 1.0)), 1.0);
}
