#pragma once
// One frame of reduced state as the client renders it: (q_u, q_a) and the
// support transform, from a published Frame, a recording or the package's
// own portrait (local mode).

#include "phasecast/client/client_basis.h"

#include <cstdint>
#include <string>
#include <vector>

namespace phasecast::client {

struct FrameState {
  std::uint64_t frame = 0;     // the server's frame number (PNG names use it)
  std::vector<float> q_u;      // r_u (eq. 6)
  std::vector<float> q_a;      // r_a (§4.2)
  std::vector<float> support;  // 12: 3x4 row-major support -> world; empty: identity
};

// Frames that bring their own bases (a chunk of a simulation drawn as it
// was simulated, simulation_view.h): the frames are evaluated with `basis`.
struct FrameChunk {
  ClientBasis basis;
  std::vector<FrameState> frames;
};

// Checks sizes against the bases and that every value is finite. Throws
// std::invalid_argument: "<source>: frame 12: q_u has 3 values (expected r_u = 4)".
void validate_frame(const FrameState& frame, const ClientBasis& basis, const std::string& source);

}  // namespace phasecast::client
