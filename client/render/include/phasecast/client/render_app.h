#pragma once
// phasecast-render as a library call, so the tool's main stays thin: pick
// the frame source (server, recording or the package's own portrait), set up
// backend, renderer, camera and light, render, report.

#include "phasecast/client/client_basis.h"
#include "phasecast/client/frame_state.h"

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

namespace phasecast::client {

// Instances one renderer draws at most (--count, --instances).
inline constexpr int kMaxInstancesInView = 4096;

struct RenderOptions {
  // Frame source: exactly one of connect, replay (+ package) or package alone.
  std::string connect;                    // tcp://host:5555 (command socket)
  std::optional<std::uint32_t> instance;  // network: the instance to follow
  // Several instances of one scene in one view, on a grid: these (network,
  // replay), or every instance of the scene (network: --instances all).
  std::vector<std::uint32_t> instances;
  bool all_instances = false;
  std::string create;  // network: create an instance of this scene (--count of them)
  int count = 1;       // --create: instances made; local mode: copies of the IRF, each further on
  std::optional<std::filesystem::path> layout;  // where several instances stand (layout.h); default: a grid
  bool half = false;                            // U_u and U_a as 16-bit floats on the GPU (--half)
  std::optional<std::filesystem::path> replay;  // recording file
  std::optional<std::filesystem::path> package;
  std::optional<int> play_irf;  // local mode: IRF to play (default 0)

  std::string backend = "osmesa";
  int width = 512, height = 512;
  std::uint64_t max_frames = 0;  // 0: all (local/replay) or until interrupted (network)
  std::optional<std::filesystem::path> out_dir;
  std::optional<std::filesystem::path> video;
  // The view: each absent option is the scene's ([view] in the package),
  // else grace, a floor under the rest mesh, and 1.
  std::string light;
  std::optional<bool> backdrop;  // the ground behind the scene (--backdrop on|off)
  std::optional<float> exposure;
  std::optional<std::uint64_t> dump_frame;
  std::filesystem::path dump_path;
  std::string eye, target, up;  // "x,y,z" overrides of the scene camera
  std::optional<float> fov_y_deg;

  double frame_timeout_s = 3;        // network: silence after which the server counts as gone
  double give_up_after_s = 60;       // network: exit when no frame could be rendered for this long
  double request_timeout_s = 2;      // network: wait this long for each reply (3 attempts)
  std::filesystem::path server_key;  // network: the server's CURVE public key file (NAME.pub)
  std::filesystem::path client_key;  // network: this client's CURVE secret key file (NAME.key)
};

// "1,2,3" -> {1, 2, 3}, each once; throws std::invalid_argument naming
// --instances and what was expected.
std::vector<std::uint32_t> parse_instance_list(const std::string& text);

// "on" -> true, "off" -> false; anything else throws std::invalid_argument
// naming `option` and the two values expected.
bool parse_on_off(const std::string& value, const std::string& option);

// Throws std::invalid_argument naming the offending option; every failure
// is one line in the exception. Progress and the summary go to `log`. The
// session ends, with its summary, once `interrupted` is set (the tool's
// SIGINT and SIGTERM handlers set it).
void run_render(const RenderOptions& options, std::ostream& log, const std::atomic<bool>& interrupted);

// Frames that bring their own bases, a chunk at a time: a simulation drawn
// as it was simulated (phasecast-render --simulation, simulation_view.h).
// Each chunk's bases replace the last ones on the same context; the window,
// PNG numbering and video go on.
struct FrameChunks {
  std::string source;       // named in the log and in errors
  std::string description;  // the log's first line says what is drawn
  double dt = 0;            // s between frames
  int chunks = 0;
  std::uint64_t frames = 0;  // in all the chunks
  std::function<FrameChunk(int index)> chunk;
};

// Renders `chunks` with the options' backend, size, camera, light, outputs
// and --frames; the frame-source options (--connect, --replay, --package,
// --instances, --create, --count, --layout, --play-irf, CURVE keys) are
// refused, one line naming the option. Otherwise as run_render.
void render_chunks(const RenderOptions& options, const FrameChunks& chunks, std::ostream& log,
                   const std::atomic<bool>& interrupted);

}  // namespace phasecast::client
