#pragma once
// A simulation as phasecast-render draws it (--simulation run.h5): the
// orbit store of `phasecast-precompute simulate` (or of sample or import)
// shown on the scene's own points, colours and light, through the same
// renderer as served frames. Nothing is reduced: a chunk of K frames rides
// in an exact displacement basis, U_u's K columns the chunk's displacements
// of the scene points from rest and frame k's q_u the k-th unit vector, so
// x_bar + U_u q_u (eq. 7) is the simulated position to float rounding. The
// transfer is the rest shape's (§4.1): colours and light are the scene's,
// but the self-shadowing does not follow the motion.
//
// This room links the offline libraries (scene files, scene points,
// transfer); only phasecast-render carries it, the thin client rooms do not.

#include "phasecast/client/client_basis.h"
#include "phasecast/client/frame_state.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::client {

// Frames per chunk: at most 64, fewer where U_u would pass 64 MiB.
int simulation_chunk_frames(int points);

class SimulationView {
 public:
  // Reads the store and the scene that made it: `scene_file`, else the
  // scene file the store names. Refuses a store of another scene naming each
  // field that differs. Computes the rest transfer, reporting (pass, done,
  // total) to `progress`. Throws std::invalid_argument, one line that starts
  // with the store's path.
  SimulationView(const std::filesystem::path& store, const std::optional<std::filesystem::path>& scene_file,
                 const std::function<void(const char* pass, long done, long total)>& progress = {});
  ~SimulationView();
  SimulationView(SimulationView&&) noexcept;

  const std::string& scene() const;
  const std::filesystem::path& scene_file() const;
  double dt() const;
  int frames() const;
  int points() const;
  // The first `frames` frames (all when 0) in chunks of simulation_chunk_frames.
  int chunks(std::uint64_t frames = 0) const;
  // Its basis: r_u = frames.size(), r_a = 0, the rest shape's transfer; its
  // frame numbers are the store's frame indices.
  FrameChunk chunk(int index, std::uint64_t frames = 0) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phasecast::client
