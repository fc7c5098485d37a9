#version 450 core
// The thin client's low-rank superposition (§5.3). Bases live in shader
// storage buffers uploaded once; per frame only q_u, q_a (buffer Reduced) and
// the support transform change. Drawn with glDrawElements and no vertex
// attributes: gl_VertexID is the scene point index.

layout(std430, binding = 0) readonly buffer MeanShape { float x_bar[]; };        // 3S (eq. 7)
layout(std430, binding = 1) readonly buffer DisplacementBasis { float U_u[]; };  // 3S x r_u, row-major
layout(std430, binding = 2) readonly buffer MeanTransfer { float M_bar[]; };     // 48S: point, channel, k
layout(std430, binding = 3) readonly buffer TransferBasis { float U_a[]; };      // 48S x r_a, row-major
layout(std430, binding = 4) readonly buffer PointFlags { uint flags[]; };        // bit 0 deformable, 1 attached
layout(std430, binding = 5) readonly buffer RestNormals { float normals[]; };    // 3S
layout(std430, binding = 6) readonly buffer Reduced { float q[]; };              // q_u (r_u) then q_a (r_a)

uniform int r_u;
uniform int r_a;
uniform bool has_transfer;       // false: the scene has no appearance model (§4)
uniform mat4 support;            // support frame -> world
uniform mat4 view_projection;
uniform vec4 light_world[12];    // SH light: coefficient 16c + k in [(16c + k) / 4][(16c + k) % 4]
uniform vec4 light_support[12];  // the same light rotated into the support frame

out vec3 world_position;  // captured by transform feedback (--dump-vertices)
out vec3 radiance;        // linear exit radiance, RGB

float light_coefficient(bool in_support, int i) {
  return in_support ? light_support[i / 4][i % 4] : light_world[i / 4][i % 4];
}

// Eq. 7: x = x_bar + U_u q_u for deformable points.
vec3 displaced_position(uint v, bool deformable) {
  uint row = 3u * v;
  vec3 x = vec3(x_bar[row], x_bar[row + 1u], x_bar[row + 2u]);
  if (deformable) {
    uint ru = uint(r_u);
    for (uint j = 0u; j < ru; ++j) {
      x += vec3(U_u[row * ru + j], U_u[(row + 1u) * ru + j], U_u[(row + 2u) * ru + j]) * q[j];
    }
  }
  return x;
}

// §4.2: exit radiance = (M_bar + U_a q_a) . L, per colour channel.
vec3 transfer_radiance(uint v, bool in_support) {
  vec3 rgb = vec3(0.0);
  uint ra = uint(r_a);
  for (int c = 0; c < 3; ++c) {
    float sum = 0.0;
    for (int k = 0; k < 16; ++k) {
      uint row = 48u * v + uint(16 * c + k);
      float m = M_bar[row];
      for (uint j = 0u; j < ra; ++j) m += U_a[row * ra + j] * q[uint(r_u) + j];
      sum += m * light_coefficient(in_support, 16 * c + k);
    }
    rgb[c] = sum;
  }
  return rgb;
}

// Without an appearance model: unshadowed grey diffuse from the rest normal,
// (rho/pi) sum_k A_l Y_k(n) L_k (Ramamoorthi & Hanrahan 2001), bands 0..2.
vec3 fallback_radiance(uint v, bool in_support) {
  vec3 n = normalize(vec3(normals[3u * v], normals[3u * v + 1u], normals[3u * v + 2u]));
  float y[9] = float[9](0.2820948, -0.4886025 * n.y, 0.4886025 * n.z, -0.4886025 * n.x,
                        1.0925484 * n.x * n.y, -1.0925484 * n.y * n.z, 0.9461747 * n.z * n.z - 0.3153916,
                        -1.0925484 * n.x * n.z, 0.5462742 * (n.x * n.x - n.y * n.y));
  float a_hat[9] = float[9](3.1415927, 2.0943951, 2.0943951, 2.0943951, 0.7853982, 0.7853982, 0.7853982,
                            0.7853982, 0.7853982);
  vec3 rgb = vec3(0.0);
  for (int c = 0; c < 3; ++c) {
    for (int k = 0; k < 9; ++k) rgb[c] += a_hat[k] * y[k] * light_coefficient(in_support, 16 * c + k);
  }
  return 0.7 / 3.1415927 * rgb;
}

void main() {
  uint v = uint(gl_VertexID);
  uint f = flags[v];
  bool attached = (f & 2u) != 0u;
  vec3 x = displaced_position(v, (f & 1u) != 0u);
  world_position = attached ? (support * vec4(x, 1.0)).xyz : x;
  radiance = has_transfer ? transfer_radiance(v, attached) : fallback_radiance(v, attached);
  gl_Position = view_projection * vec4(world_position, 1.0);
  gl_PointSize = 1.0;
}
