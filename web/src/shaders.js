// GLSL ES 3.00 ports of shaders/low_rank.vert (+ light_dot.comp inline),
// static_mesh.vert and radiance.frag. The bases are RGBA32F textures
// (packing.js) instead of storage buffers; the sizes are compile-time
// constants, one evaluation program per scene.

// The per-point pass, run once per scene point and instance (gl.POINTS,
// rasterizer off, one instanced draw for every instance in view):
// world_position and radiance captured by transform feedback, instance after
// instance, as the C++ client's Evaluation::per_point_pass. Each instance's
// q, support, placement and support-frame light are its row of
// instances_tex (packing.js packInstance).
export function evaluationVertexShader({ r_u4, r_a4, log2Width, hasTransfer }) {
  return `#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;

#define R_U4 ${r_u4}
#define R_A4 ${r_a4}
#define HAS_TRANSFER ${hasTransfer ? 1 : 0}
#define LOG2_WIDTH ${log2Width}
#define R_Q (R_U4 + R_A4)

uniform sampler2D points_tex;   // [S]: x̄ (eq. 7) in xyz, flags in w (1 deformable, 2 attached)
uniform sampler2D normals_tex;  // [S]: rest normals
uniform sampler2D U_u_tex;      // [3S][r_u4]
uniform sampler2D M_bar_tex;    // [S][3][4]: k in vec4s
uniform sampler2D U_a_tex;      // [48S][r_a4]
uniform sampler2D instances_tex;  // [instance][R_Q + 20]: q, support, placement, support-frame light
// SH light, coefficient 16c + k in [4c + k / 4][k % 4]: the world light, the
// same for every instance (each row of instances_tex holds it rotated into
// that instance's support frame).
uniform vec4 world_light[12];

// This instance's q_u (r_u4 vec4s), then q_a (r_a4), and the light this
// point sees (world or support frame), read once per point.
vec4 q[R_Q + 1];
vec4 light[12];

out vec3 world_position;
out vec3 radiance;

vec4 fetch(sampler2D t, int i) {
  return texelFetch(t, ivec2(i & ((1 << LOG2_WIDTH) - 1), i >> LOG2_WIDTH), 0);
}

vec4 instance_texel(int i) {
  return texelFetch(instances_tex, ivec2(i, gl_InstanceID), 0);
}

mat4 instance_matrix(int first) {
  return mat4(instance_texel(first), instance_texel(first + 1), instance_texel(first + 2), instance_texel(first + 3));
}

// Eq. 7: x = x̄ + U_u q_u for deformable points.
vec3 displaced_position(int v, vec3 x, bool deformable) {
  if (deformable) {
    int row = 3 * v;
    for (int b = 0; b < R_U4; ++b) {
      vec4 qb = q[b];
      x += vec3(dot(fetch(U_u_tex, row * R_U4 + b), qb), dot(fetch(U_u_tex, (row + 1) * R_U4 + b), qb),
                dot(fetch(U_u_tex, (row + 2) * R_U4 + b), qb));
    }
  }
  return x;
}

#if HAS_TRANSFER
// §4.2: exit radiance (M̄ + U_a q_a) . L per colour channel, light-dotted
// here each frame (light_dot.comp): M̄_c.L_c + sum_j (U_a.L)_{c,j} q_a[j].
vec3 transfer_radiance(int v) {
  vec3 rgb;
  for (int c = 0; c < 3; ++c) {
    float sum = 0.0;
    for (int kb = 0; kb < 4; ++kb) sum += dot(fetch(M_bar_tex, 12 * v + 4 * c + kb), light[4 * c + kb]);
    for (int b = 0; b < R_A4; ++b) {
      vec4 acc = vec4(0.0);
      for (int kb = 0; kb < 4; ++kb) {
        vec4 L = light[4 * c + kb];
        int row = 48 * v + 16 * c + 4 * kb;
        acc += fetch(U_a_tex, row * R_A4 + b) * L.x + fetch(U_a_tex, (row + 1) * R_A4 + b) * L.y +
               fetch(U_a_tex, (row + 2) * R_A4 + b) * L.z + fetch(U_a_tex, (row + 3) * R_A4 + b) * L.w;
      }
      sum += dot(acc, q[R_U4 + b]);
    }
    rgb[c] = sum;
  }
  return rgb;
}
#endif

// Without an appearance model: unshadowed grey diffuse from the rest normal,
// (rho/pi) sum_k A_l Y_k(n) L_k (Ramamoorthi & Hanrahan 2001), bands 0..2.
vec3 fallback_radiance(int v) {
  vec3 n = normalize(fetch(normals_tex, v).xyz);
  vec4 y0 = vec4(0.2820948, -0.4886025 * n.y, 0.4886025 * n.z, -0.4886025 * n.x);
  vec4 y1 = vec4(1.0925484 * n.x * n.y, -1.0925484 * n.y * n.z, 0.9461747 * n.z * n.z - 0.3153916,
                 -1.0925484 * n.x * n.z);
  float y8 = 0.5462742 * (n.x * n.x - n.y * n.y);
  vec4 a0 = vec4(3.1415927, 2.0943951, 2.0943951, 2.0943951);
  const float a2 = 0.7853982;
  vec3 rgb;
  for (int c = 0; c < 3; ++c) {
    rgb[c] = dot(a0 * y0, light[4 * c]) + a2 * dot(y1, light[4 * c + 1]) + a2 * y8 * light[4 * c + 2].x;
  }
  return 0.7 / 3.1415927 * rgb;
}

void main() {
  int v = gl_VertexID;
  vec4 point = fetch(points_tex, v);
  int flags = int(point.w);
  bool attached = (flags & 2) != 0;
  for (int i = 0; i < R_Q; ++i) q[i] = instance_texel(i);
  vec3 x = displaced_position(v, point.xyz, (flags & 1) != 0);
  // support: support frame -> world (the placement included); placement:
  // instance frame -> world, where the instance stands among others.
  world_position = (instance_matrix(attached ? R_Q : R_Q + 4) * vec4(x, 1.0)).xyz;
  for (int i = 0; i < 12; ++i) light[i] = attached ? instance_texel(R_Q + 8 + i) : world_light[i];
#if HAS_TRANSFER
  radiance = transfer_radiance(v);
#else
  radiance = fallback_radiance(v);
#endif
  gl_PointSize = 1.0;
  gl_Position = vec4(0.0);
}
`;
}

// Transform feedback needs a linked program, so a fragment stage that never runs.
export const DISCARD_FRAGMENT_SHADER = `#version 300 es
precision mediump float;
out vec4 colour;
void main() { colour = vec4(0.0); }
`;

// The triangles, from the evaluated points as vertex attributes (static_mesh.vert).
export const DRAW_VERTEX_SHADER = `#version 300 es
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 vertex_radiance;
uniform mat4 view_projection;
out vec3 radiance;
void main() {
  radiance = vertex_radiance;
  gl_Position = view_projection * vec4(position, 1.0);
}
`;

// radiance.frag: exposure, clamp, sRGB encoding.
export const RADIANCE_FRAGMENT_SHADER = `#version 300 es
precision highp float;
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
`;
