// Frames/s of the low-rank vertex program (§5.3) at 512x512 and 1280x720,
// and the same mesh drawn from static per-vertex data in the same run, so
// that the cost of the evaluation is the difference of the two.
//
// Scenes: cloth grids of the paper's sizes, every point deformable and
// attached, r_u = 12 smooth modes and r_a = 7 transfer modes (the "12+7"
// superposition of issue 7). PHASECAST_BENCH_BACKEND=egl picks another backend.

#include "phasecast/client/camera.h"
#include "phasecast/client/low_rank_renderer.h"

#include <benchmark/benchmark.h>

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <cmath>
#include <cstdlib>
#include <numbers>

namespace phasecast::client {
namespace {

constexpr double kPi = std::numbers::pi;

// An n x n grid on [0,1]^2 with sine modes for U_u and U_a.
ClientBasis grid_scene(int n, int r_u, int r_a) {
  ClientBasis b;
  b.scene = "grid";
  b.points = n * n;
  b.rank_u = r_u;
  b.rank_a = r_a;
  const auto S = static_cast<std::size_t>(b.points);
  b.U_u.resize(3 * S * static_cast<std::size_t>(r_u));
  b.U_a.resize(48 * S * static_cast<std::size_t>(r_a));
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x = double(i) / (n - 1), y = double(j) / (n - 1);
      const auto v = static_cast<std::size_t>(j * n + i);
      b.mean_shape.insert(b.mean_shape.end(), {float(x), float(y), 0.0f});
      b.normals.insert(b.normals.end(), {0.0f, 0.0f, 1.0f});
      for (int k = 0; k < r_u; ++k) {
        const double mode = std::sin((k / 3 + 1) * kPi * x) * std::sin((k % 3 + 1) * kPi * y) / n;
        b.U_u[(3 * v + 2) * static_cast<std::size_t>(r_u) + static_cast<std::size_t>(k)] = float(mode);
      }
      for (int c = 0; c < 48 && r_a > 0; ++c) {
        b.mean_transfer.push_back(c % 16 == 0 ? 0.3f : 0.02f);
        for (int k = 0; k < r_a; ++k) {
          b.U_a[(48 * v + static_cast<std::size_t>(c)) * static_cast<std::size_t>(r_a) +
                static_cast<std::size_t>(k)] = float(0.01 * std::cos((k + 1) * kPi * x + c));
        }
      }
    }
  }
  b.deformable.assign(S, 1);
  b.attached.assign(S, 1);
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const auto a = static_cast<std::uint32_t>(j * n + i), c = a + static_cast<std::uint32_t>(n);
      b.triangles.insert(b.triangles.end(), {a, a + 1, c + 1, a, c + 1, c});
    }
  }
  b.camera = std::array<float, 10>{0.5f, 0.5f, 1.6f, 0.5f, 0.5f, 0.0f, 0.0f, 1.0f, 0.0f, 40.0f};
  return b;
}

// `rotating`: the support turns every frame (a door opening), so the light
// in the support frame changes and the transfer is re-dotted each frame.
FrameState frame(int t, int r_u, int r_a, bool rotating) {
  FrameState f;
  f.frame = static_cast<std::uint64_t>(t);
  for (int k = 0; k < r_u; ++k) f.q_u.push_back(float(0.5 * std::sin(0.1 * t + k)));
  for (int k = 0; k < r_a; ++k) f.q_a.push_back(float(std::cos(0.07 * t + k)));
  const float a = rotating ? float(0.3 * std::sin(0.02 * t)) : 0.2f;
  f.support = {std::cos(a), 0, std::sin(a), 0, 0, 1, 0, 0, -std::sin(a), 0, std::cos(a), 0};
  return f;
}

// llvmpipe compiles a program's code for the state of its first draws: time
// that belongs to no frame, so each benchmark draws this many before its clock runs.
constexpr int kUntimedFrames = 3;

std::string backend_name() {
  const char* name = std::getenv("PHASECAST_BENCH_BACKEND");
  return name ? name : "osmesa";
}

// Layout argument: 0 point rows, 1 point tiles, 2 the backend's default.
std::optional<BasisLayout> layout_arg(std::int64_t arg) {
  if (arg == 2) return std::nullopt;
  return arg == 1 ? BasisLayout::point_tiles : BasisLayout::point_rows;
}

std::string layout_label(const LowRankRenderer& renderer) {
  return std::string(", ") + basis_layout_name(renderer.basis_layout());
}

// Args: grid side, width, height, mode (0: low-rank with the per-point pass
// by transform feedback, 1: low-rank evaluated inside the triangle draw, 2:
// static mesh, 3: low-rank with the per-point pass as a compute shader), read
// back pixels (0/1), support rotating every frame (0/1), basis layout (layout_arg).
void BM_Render(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0)), w = static_cast<int>(state.range(1)),
            h = static_cast<int>(state.range(2));
  const int mode = static_cast<int>(state.range(3));
  const bool static_mesh = mode == 2, read_back = state.range(4) != 0, rotating = state.range(5) != 0;
  const int r_u = 12, r_a = 7;
  const ClientBasis basis = grid_scene(n, r_u, r_a);
  auto backend = make_render_backend(backend_name(), w, h);
  LowRankRenderer renderer(*backend, basis, w, h, BasisPrecision::float32, layout_arg(state.range(6)));
  const Evaluation paths[] = {Evaluation::per_point_pass, Evaluation::in_draw, Evaluation::per_point_pass,
                              Evaluation::compute_pass};
  renderer.set_evaluation(paths[mode]);
  if (static_mesh) renderer.set_static_mesh(renderer.evaluate(frame(0, r_u, r_a, false)));
  int t = 0;
  auto draw_one = [&] {
    if (static_mesh) {
      renderer.draw_static();
    } else {
      renderer.draw(frame(t++, r_u, r_a, rotating));
    }
    if (read_back) {
      benchmark::DoNotOptimize(renderer.read_pixels());
    } else {
      renderer.finish();
    }
  };
  for (int i = 0; i < kUntimedFrames; ++i) draw_one();
  for (auto _ : state) draw_one();
  state.counters["fps"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["points"] = basis.points;
  state.counters["triangles"] = basis.triangle_count();
  const char* names[] = {"low-rank 12+7, per-point pass", "low-rank 12+7, in draw", "static mesh",
                         "low-rank 12+7, compute pass"};
  state.SetLabel(std::string(names[mode]) + (read_back ? " + read back" : "") +
                 (rotating && !static_mesh ? ", support rotating" : "") +
                 (static_mesh ? "" : layout_label(renderer)) + " | " + backend_name());
}

// The share of pixels the last frame drew on (not the clear colour): what
// the rasterizer's cost follows, so that a static and a low-rank row are seen
// to draw the same picture.
double coverage(const Image& image) {
  std::size_t drawn = 0;
  const std::size_t pixels = image.rgba.size() / 4;
  for (std::size_t i = 0; i < pixels; ++i) {
    const std::uint8_t* p = &image.rgba[4 * i];
    if (p[0] != image.rgba[0] || p[1] != image.rgba[1] || p[2] != image.rgba[2]) ++drawn;
  }
  return static_cast<double>(drawn) / static_cast<double>(pixels);
}

// The timed loop of the instance and large-plate benchmarks: frames_at(t)
// drawn low-rank, or frames_at(0) drawn as static meshes every iteration,
// waited for each time, after kUntimedFrames; then the frames/s and
// coverage counters.
template <class Frames>
void draw_frames(benchmark::State& state, LowRankRenderer& renderer, bool static_mesh,
                 const Frames& frames_at) {
  if (static_mesh) renderer.set_static_mesh(renderer.evaluate(frames_at(0)));
  int t = 0;
  auto draw_one = [&] {
    if (static_mesh) {
      renderer.draw_static();
    } else {
      renderer.draw(frames_at(t++));
    }
    renderer.finish();
  };
  for (int i = 0; i < kUntimedFrames; ++i) draw_one();
  for (auto _ : state) draw_one();
  state.counters["fps"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["coverage"] = coverage(renderer.read_pixels());
}

// Many instances of the demo cloth's size (58^2 = 3.4k points, 12+7) in one
// view on the default grid, each at its own point of the motion: one
// instanced draw of low-rank evaluation against the same instances drawn as
// static meshes. Args: instances, width, height, mode (0: low-rank, 2:
// static), support rotating (0/1), basis layout (layout_arg), compute reads
// (0 storage buffers, 1 buffer textures, 2 the backend's default).
void BM_Instances(benchmark::State& state) {
  const int count = static_cast<int>(state.range(0)), w = static_cast<int>(state.range(1)),
            h = static_cast<int>(state.range(2));
  const bool static_mesh = state.range(3) == 2, rotating = state.range(4) != 0;
  const int r_u = 12, r_a = 7;
  const ClientBasis basis = grid_scene(58, r_u, r_a);
  auto backend = make_render_backend(backend_name(), w, h);
  LowRankRenderer renderer(*backend, basis, w, h, BasisPrecision::float32, layout_arg(state.range(5)));
  if (state.range(6) != 2)
    renderer.set_compute_reads(state.range(6) == 1 ? ComputeReads::buffer_textures
                                                   : ComputeReads::storage_buffers);
  const auto placements = grid_placements(rest_bounds(basis), count);
  renderer.set_placements(placements);
  renderer.set_camera(group_camera(scene_camera(basis), rest_bounds(basis), placements));
  auto frames_at = [&](int t) {
    std::vector<FrameState> frames;
    for (int i = 0; i < count; ++i) frames.push_back(frame(t + 7 * i, r_u, r_a, rotating));
    return frames;
  };
  draw_frames(state, renderer, static_mesh, frames_at);
  state.counters["points"] = static_cast<double>(count) * basis.points;
  state.SetLabel(
      std::string(static_mesh ? "static meshes" : "low-rank 12+7, one instanced draw, default path") +
      (rotating && !static_mesh ? ", supports rotating" : "") + (static_mesh ? "" : layout_label(renderer)) +
      (static_mesh || renderer.evaluation() != Evaluation::compute_pass
           ? ""
           : std::string(", ") + compute_reads_name(renderer.compute_reads())) +
      " | " + backend_name());
}

// The 1 M-point plate (1000 x 1000, r_u = 30, no appearance) at
// 1920x1080, static vs low-rank on the default path, no read-back. Its
// bases take 0.4 GB and a minute to build, so it runs only with
// PHASECAST_BENCH_LARGE=1 (bench/gpu/run sets it). Args: mode (0 low-rank, 2 static).
void BM_LargePlate(benchmark::State& state) {
  if (!std::getenv("PHASECAST_BENCH_LARGE")) {
    state.SkipWithError("set PHASECAST_BENCH_LARGE=1 to build the 1 M-point plate");
    return;
  }
  const bool static_mesh = state.range(0) == 2;
  const ClientBasis basis = grid_scene(1000, 30, 0);
  auto backend = make_render_backend(backend_name(), 1920, 1080);
  LowRankRenderer renderer(*backend, basis, 1920, 1080);
  auto frame_at = [](int t) { return frame(t, 30, 0, false); };
  draw_frames(state, renderer, static_mesh, frame_at);
  state.counters["blocks"] = renderer.point_blocks();
  state.SetLabel(std::string(static_mesh ? "static mesh" : "low-rank r_u = 30, default path") + " | " +
                 backend_name());
}

// Paper-sized meshes: 158^2 = 25k points / 49k triangles, 58^2 = 3.4k / 6.5k.
void Arguments(benchmark::internal::Benchmark* b) {
  for (int n : {158, 58}) {
    for (auto [w, h] : {std::pair{512, 512}, std::pair{1280, 720}}) {
      b->Args({n, w, h, 2, 0, 0, 2});  // static reference
      b->Args({n, w, h, 0, 0, 0, 2});  // low-rank, support still
      b->Args({n, w, h, 0, 0, 1, 2});  // low-rank, support rotating
      b->Args({n, w, h, 1, 0, 0, 2});  // low-rank inside the draw
      b->Args({n, w, h, 3, 0, 0, 2});  // low-rank, the per-point pass as a compute shader
      b->Args({n, w, h, 0, 1, 0, 2});  // with pixel read-back (what PNG output costs)
      for (int layout : {0, 1}) {      // each layout on the paths that read the bases most
        b->Args({n, w, h, 1, 0, 0, layout});
        b->Args({n, w, h, 3, 0, 0, layout});
        b->Args({n, w, h, 0, 0, 1, layout});
      }
    }
  }
}

BENCHMARK(BM_Render)
    ->Apply(Arguments)
    ->ArgNames({"side", "w", "h", "mode", "readback", "rotating", "layout"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

BENCHMARK(BM_LargePlate)->Arg(2)->Arg(0)->ArgNames({"mode"})->UseRealTime()->Unit(benchmark::kMillisecond);

BENCHMARK(BM_Instances)
    ->ArgsProduct({{1, 16, 64}, {1280}, {720}, {2, 0}, {0}, {2}, {2}})
    ->ArgsProduct({{16, 64}, {1280}, {720}, {0}, {0, 1}, {0, 1}, {2}})
    ->ArgsProduct({{16, 64}, {1280}, {720}, {0}, {0, 1}, {0}, {0}})  // storage buffers: the reads' baseline
    ->ArgNames({"instances", "w", "h", "mode", "rotating", "layout", "reads"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace phasecast::client

BENCHMARK_MAIN();
