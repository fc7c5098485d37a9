#include "phasecast/client/frame_sources.h"

#include <fmt/format.h>

#include <stdexcept>

namespace phasecast::client {

std::vector<FrameState> portrait_frames(const core::ScenePackage& p, int irf) {
  const auto& pp = p.portrait;
  if (irf < 0 || irf >= pp.irf_count()) {
    throw std::invalid_argument(
        fmt::format("--play-irf {} is out of range (expected 0..{}: the package has {} IRFs)", irf,
                    pp.irf_count() - 1, pp.irf_count()));
  }
  const auto i = static_cast<std::size_t>(irf);
  std::vector<FrameState> frames;
  for (int t = 0; t < pp.irf_length[i]; ++t) {
    const int node = pp.irf_start[i] + t;
    FrameState f;
    f.frame = static_cast<std::uint64_t>(t);
    f.q_u.assign(pp.q_u.row(node).data(), pp.q_u.row(node).data() + pp.q_u.cols());
    f.q_a.assign(pp.q_a.row(node).data(), pp.q_a.row(node).data() + pp.q_a.cols());
    if (pp.support.rows() > 0) {
      f.support.assign(pp.support.row(node).data(), pp.support.row(node).data() + pp.support.cols());
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

FrameState frame_state(const v1::Frame& frame) {
  FrameState f;
  f.frame = frame.frame();
  f.q_u.assign(frame.q_u().begin(), frame.q_u().end());
  f.q_a.assign(frame.q_a().begin(), frame.q_a().end());
  f.support.assign(frame.support().begin(), frame.support().end());
  return f;
}

std::vector<FrameState> recorded_frames(const Recording& rec, std::optional<std::uint32_t> instance,
                                        const std::string& source) {
  std::vector<FrameState> frames;
  for (const auto& e : rec.entries) {
    if (!e.has_frame()) continue;
    if (!instance) instance = e.frame().instance();
    if (e.frame().instance() == *instance) frames.push_back(frame_state(e.frame()));
  }
  if (frames.empty()) {
    throw RecordingError(instance ? fmt::format("recording {}: no frames of instance {}", source, *instance)
                                  : fmt::format("recording {}: no frames", source));
  }
  return frames;
}

}  // namespace phasecast::client
