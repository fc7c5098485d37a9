// Shader storage bindings of the thin client's programs: one source for the
// GLSL (embed_shaders.cmake splices this file where a shader includes it) and
// the C++ that binds the buffers (client/render/src/low_rank_renderer.cpp).
// Only preprocessor lines and comments, so that it reads the same in both.
// Buffers marked "tiled" hold W vec4s per point in tiles of PHASECAST_POINT_TILE
// points: within a tile, the points' vec4 j lie side by side, so neighbouring
// invocations (points) read neighbouring memory. PHASECAST_TILED(v, j, W) is
// the index of point v's vec4 j; a bound block of points starts on a tile.
#ifndef PHASECAST_POINT_TILE  // the renderer defines 1u for point rows (BasisLayout)
#define PHASECAST_POINT_TILE 64u
#endif
#define PHASECAST_TILED(v, j, W) \
  ((v) / PHASECAST_POINT_TILE * (PHASECAST_POINT_TILE * (W)) + (j) * PHASECAST_POINT_TILE + (v) % PHASECAST_POINT_TILE)
#define PHASECAST_BINDING_MEAN_SHAPE 0          // x-bar, 3S (eq. 7)
#define PHASECAST_BINDING_DISPLACEMENT_BASIS 1  // U_u, tiled, W = 3 r_u4: row c, vec4 block b at c r_u4 + b
#define PHASECAST_BINDING_MEAN_TRANSFER 2       // M-bar, tiled, W = 12: channel c, k-block kb at 4c + kb
#define PHASECAST_BINDING_TRANSFER_BASIS 3      // U_a, tiled, W = 48 r_a4: row 16c + k, block b at (16c + k) r_a4 + b
#define PHASECAST_BINDING_POINT_FLAGS 4         // bit 0 deformable, bit 1 attached
#define PHASECAST_BINDING_REST_NORMALS 5        // 3S
#define PHASECAST_BINDING_REDUCED 6             // per instance: q_u (r_u4 vec4s) then q_a (r_a4)
#define PHASECAST_BINDING_MEAN_DOTTED 7         // [dotted copy][S]: xyz = M-bar_c . L_c
#define PHASECAST_BINDING_BASIS_DOTTED 8        // [dotted copy] tiled, W = 3 r_a4: (U_a . L)_j of channel c at c r_a4 + b
#define PHASECAST_BINDING_INSTANCES 9           // per instance: placement, support, lights
#define PHASECAST_BINDING_EVALUATED 10          // low_rank.comp's output: 6 floats per point and instance
#define PHASECAST_BINDING_COUNT 11
#define PHASECAST_INSTANCE_VEC4S 33  // an instance's entry in Instances: 2 mat4s, 24 lights, its dotted copy
