#pragma once
// What happens to each rendered frame: a PNG named by the server's frame
// number (and the session: frame numbers start again when a server restarts,
// files never replace earlier ones), an MP4 through ffmpeg, the vertex dump
// of one chosen frame, and the frames/s figures (render-only and end-to-end).

#include "phasecast/client/low_rank_renderer.h"

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <span>
#include <string>

namespace phasecast::client {

struct OutputOptions {
  std::optional<std::filesystem::path> png_dir;  // frame_file_name(frame, session) here
  std::optional<std::filesystem::path> video;    // MP4 through ffmpeg
  double video_fps = 60;
  std::optional<std::uint64_t> dump_frame;  // --dump-vertices FRAME path
  std::filesystem::path dump_path;
};

struct RenderStats {
  std::uint64_t frames = 0;
  double render_seconds = 0;  // inside the renderer: draw + read back
  double wall_seconds = 0;    // first frame received to last frame written
  double render_fps() const { return render_seconds > 0 ? double(frames) / render_seconds : 0; }
  double end_to_end_fps() const { return wall_seconds > 0 ? double(frames) / wall_seconds : 0; }
};

// Shows frames at the stream's own rate on a screen (window backend, local
// and replay modes, which have every frame at once): frame k is due at
// start + k period. A renderer that falls behind by more than a period
// starts again from now rather than rushing to catch up.
class FramePacer {
 public:
  using Clock = std::chrono::steady_clock;
  explicit FramePacer(double period_s) : period_(std::chrono::duration<double>(period_s)) {}
  // How long to wait before showing the next frame, seen at `now`.
  Clock::duration wait(Clock::time_point now);

 private:
  std::chrono::duration<double> period_;
  std::optional<Clock::time_point> next_;
};

// Path of ffmpeg on PATH, or empty.
std::filesystem::path find_ffmpeg();

class FrameOutput {
 public:
  // Creates the PNG directory and starts ffmpeg. Throws std::runtime_error
  // when ffmpeg is needed but not installed (the message says so).
  FrameOutput(LowRankRenderer& renderer, int width, int height, OutputOptions options);
  ~FrameOutput();
  FrameOutput(const FrameOutput&) = delete;
  FrameOutput& operator=(const FrameOutput&) = delete;

  // Renders `frame` with the current renderer. A frame number not above the
  // last one starts a new session (a restarted server): its PNG names carry it.
  // Pixels are read back from the GPU only for PNGs and the video.
  void render(const FrameState& frame);
  // Several instances in one view (one frame per placement of the renderer),
  // named and numbered by the first one's frame.
  void render(std::span<const FrameState> frames);
  // Renders with `renderer` from now on (new bases); files, video and
  // figures go on, so nothing written so far is replaced.
  void set_renderer(LowRankRenderer& renderer) { renderer_ = &renderer; }
  // Closes the video; throws if a requested vertex dump never happened.
  void finish();
  const RenderStats& stats() const { return stats_; }
  bool dumped() const { return dumped_; }
  // 0 until frame numbers first go back, then 1, 2, ... (frame_file_name).
  unsigned session() const { return session_; }

 private:
  LowRankRenderer* renderer_;
  int width_, height_;
  OutputOptions options_;
  std::FILE* ffmpeg_ = nullptr;
  RenderStats stats_;
  std::optional<std::chrono::steady_clock::time_point> first_;
  bool dumped_ = false;
  unsigned session_ = 0;
  std::optional<std::uint64_t> last_frame_;
};

}  // namespace phasecast::client
