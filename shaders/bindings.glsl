// Shader storage bindings of the thin client's programs: one source for the
// GLSL (embed_shaders.cmake splices this file where a shader includes it) and
// the C++ that binds the buffers (client/render/src/low_rank_renderer.cpp).
// Only preprocessor lines and comments, so that it reads the same in both.
#define PHASECAST_BINDING_MEAN_SHAPE 0          // x-bar, 3S (eq. 7)
#define PHASECAST_BINDING_DISPLACEMENT_BASIS 1  // U_u, [3S][r_u4] vec4s
#define PHASECAST_BINDING_MEAN_TRANSFER 2       // M-bar, [S][3][4] vec4s
#define PHASECAST_BINDING_TRANSFER_BASIS 3      // U_a, [48S][r_a4] vec4s
#define PHASECAST_BINDING_POINT_FLAGS 4         // bit 0 deformable, bit 1 attached
#define PHASECAST_BINDING_REST_NORMALS 5        // 3S
#define PHASECAST_BINDING_REDUCED 6             // per instance: q_u (r_u4 vec4s) then q_a (r_a4)
#define PHASECAST_BINDING_MEAN_DOTTED 7         // [instance][S]: xyz = M-bar_c . L_c
#define PHASECAST_BINDING_BASIS_DOTTED 8        // [instance][S][3][r_a4]: (U_a . L)_j
#define PHASECAST_BINDING_INSTANCES 9           // per instance: placement, support, lights
#define PHASECAST_BINDING_EVALUATED 10          // low_rank.comp's output: 6 floats per point and instance
#define PHASECAST_BINDING_COUNT 11
