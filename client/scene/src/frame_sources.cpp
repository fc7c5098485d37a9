#include "phasecast/client/frame_sources.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
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

void expect_recorded_with(const Recording& rec, const ClientBasis& basis, const std::string& recording_name,
                          const std::string& package_name) {
  const auto& scenes = rec.header().scenes();
  const auto match = std::find_if(scenes.begin(), scenes.end(),
                                  [&](const v1::RecordedScene& s) { return s.scene() == basis.scene; });
  if (match == scenes.end()) {
    std::vector<std::string> names;
    for (const auto& s : scenes) names.push_back(fmt::format("'{}'", s.scene()));
    throw RecordingError(fmt::format(
        "recording {}: no scene '{}' (expected the scene of {}; it records {})", recording_name, basis.scene,
        package_name, names.empty() ? std::string("none") : fmt::format("{}", fmt::join(names, ", "))));
  }
  if (match->content_hash() != basis.content_hash) {
    throw RecordingError(fmt::format(
        "recording {}: scene '{}' was recorded with package hash {:016x}, but {} has hash {:016x} "
        "(expected the same package file)",
        recording_name, basis.scene, match->content_hash(), package_name, basis.content_hash));
  }
}

RecordedFrames recorded_frames(const Recording& rec, std::optional<std::uint32_t> instance,
                               const std::string& source, const std::optional<std::string>& scene) {
  auto counts = [&](const v1::Frame& f) { return !scene || f.scene().empty() || f.scene() == *scene; };
  std::vector<std::uint32_t> present;  // instances with frames that count, in order of their first frame
  for (const auto& e : rec.entries) {
    if (!e.has_frame() || !counts(e.frame())) continue;
    if (std::find(present.begin(), present.end(), e.frame().instance()) == present.end())
      present.push_back(e.frame().instance());
  }
  const std::string of_scene = scene ? fmt::format(" of scene '{}'", *scene) : std::string();
  if (present.empty()) {
    throw RecordingError(
        scene ? fmt::format("recording {}: no frames{} (expected frames of the package's scene)", source,
                            of_scene)
              : fmt::format("recording {}: no frames (expected at least one)", source));
  }
  if (instance && std::find(present.begin(), present.end(), *instance) == present.end()) {
    throw RecordingError(
        fmt::format("recording {}: no frames of instance {} (expected one of {}: the instances{} "
                    "it holds)",
                    source, *instance, fmt::join(present, ", "), of_scene));
  }
  RecordedFrames r;
  r.instance = instance.value_or(present.front());
  for (const auto& e : rec.entries) {
    if (e.has_frame() && e.frame().instance() == r.instance && counts(e.frame()))
      r.frames.push_back(frame_state(e.frame()));
  }
  return r;
}

}  // namespace phasecast::client
