#include "phasecast/client/frame_output.h"

#include "phasecast/client/image_io.h"

#include <fmt/format.h>

#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace phasecast::client {
namespace {

std::string shell_quote(const std::string& word) {
  std::string q = "'";
  for (char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

}  // namespace

std::filesystem::path find_ffmpeg() {
  const char* path = std::getenv("PATH");
  std::istringstream dirs(path ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    const auto candidate = std::filesystem::path(dir.empty() ? "." : dir) / "ffmpeg";
    std::error_code ec;
    if (std::filesystem::is_regular_file(candidate, ec)) return candidate;
  }
  return {};
}

FramePacer::Clock::duration FramePacer::wait(Clock::time_point now) {
  const auto period = std::chrono::duration_cast<Clock::duration>(period_);
  if (!next_ || now - *next_ > period) next_ = now;  // the first frame, or fallen behind: from now
  const auto due = *next_;
  *next_ += period;
  return due > now ? due - now : Clock::duration::zero();
}

FrameOutput::FrameOutput(LowRankRenderer& renderer, int width, int height, OutputOptions options)
    : renderer_(&renderer), width_(width), height_(height), options_(std::move(options)) {
  if (options_.dump_frame) check_vertex_dump_path(options_.dump_path);
  if (options_.png_dir) std::filesystem::create_directories(*options_.png_dir);
  if (!options_.video) return;
  const auto ffmpeg = find_ffmpeg();
  if (ffmpeg.empty()) {
    throw std::runtime_error(
        fmt::format("--video {}: ffmpeg is not installed (not found on PATH); install it or "
                    "write PNG frames with --out",
                    options_.video->string()));
  }
  // Raw RGBA on stdin; even sizes for yuv420p, which every player reads.
  const auto command = fmt::format(
      "{} -y -loglevel error -f rawvideo -pix_fmt rgba -s {}x{} -r {} -i - -vf "
      "'pad=ceil(iw/2)*2:ceil(ih/2)*2' "
      "-pix_fmt yuv420p {}",
      shell_quote(ffmpeg.string()), width_, height_, options_.video_fps,
      shell_quote(options_.video->string()));
  ffmpeg_ = ::popen(command.c_str(), "w");
  if (!ffmpeg_)
    throw std::runtime_error(fmt::format("--video {}: cannot start ffmpeg", options_.video->string()));
}

FrameOutput::~FrameOutput() {
  if (ffmpeg_) ::pclose(ffmpeg_);
}

void FrameOutput::render(const FrameState& frame) {
  render(std::span(&frame, 1));
}

// Pixels come back from the GPU only when a PNG or the video needs them.
void FrameOutput::render(std::span<const FrameState> frames) {
  if (!first_) first_ = std::chrono::steady_clock::now();
  const auto start = std::chrono::steady_clock::now();
  const bool keep = options_.png_dir || ffmpeg_;
  Image image;
  if (keep) {
    image = renderer_->render(frames);
  } else {
    renderer_->draw(frames);
    renderer_->finish();  // render-only time is the GPU's, not only the calls'
  }
  stats_.render_seconds += seconds_since(start);
  ++stats_.frames;
  const std::uint64_t number = frames.front().frame;
  if (last_frame_ && number <= *last_frame_) ++session_;
  last_frame_ = number;
  if (options_.png_dir) write_png(image, *options_.png_dir / frame_file_name(number, session_));
  if (ffmpeg_ && std::fwrite(image.rgba.data(), 1, image.rgba.size(), ffmpeg_) != image.rgba.size()) {
    throw std::runtime_error(
        fmt::format("--video {}: ffmpeg stopped accepting frames", options_.video->string()));
  }
  if (options_.dump_frame && *options_.dump_frame == number && !dumped_) {
    write_vertex_dump(renderer_->evaluate(frames), options_.dump_path);
    dumped_ = true;
  }
  stats_.wall_seconds = seconds_since(*first_);
}

void FrameOutput::finish() {
  if (ffmpeg_) {
    const int status = ::pclose(ffmpeg_);
    ffmpeg_ = nullptr;
    if (status != 0) {
      throw std::runtime_error(
          fmt::format("--video {}: ffmpeg failed (exit status {})", options_.video->string(), status));
    }
  }
  if (options_.dump_frame && !dumped_) {
    throw std::runtime_error(
        fmt::format("--dump-vertices {}: that frame was never rendered", *options_.dump_frame));
  }
}

}  // namespace phasecast::client
