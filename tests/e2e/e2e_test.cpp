// End to end: the real phasecast-server on loopback, real phasecast-render
// processes that hold no package (they download the bases, paper §5.3), and
// impulses sent from the test through a DEALER.

#include "child_process.h"
#include "phasecast/client/image_io.h"
#include "phasecast/core/package.h"
#include "run_tool.h"
#include "server_process.h"
#include "source_tree.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>
#include <zmq.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <set>
#include <thread>

namespace phasecast::testing {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// Frame numbers of the frame_%06d.png files in `dir`, sorted.
std::vector<std::uint64_t> frame_numbers(const fs::path& dir) {
  std::vector<std::uint64_t> frames;
  if (!fs::exists(dir)) return frames;
  for (const auto& e : fs::directory_iterator(dir)) {
    const auto name = e.path().filename().string();
    if (name.rfind("frame_", 0) == 0 && e.path().extension() == ".png") {
      frames.push_back(std::stoull(name.substr(6, name.size() - 10)));
    }
  }
  std::sort(frames.begin(), frames.end());
  return frames;
}

client::Image frame_image(const fs::path& dir, std::uint64_t frame) {
  return client::read_png(dir / client::frame_file_name(frame));
}

// Pixels where some channel differs by more than 8 (of 255).
int changed_pixels(const client::Image& a, const client::Image& b) {
  int n = 0;
  for (size_t i = 0; i + 3 < a.rgba.size(); i += 4) {
    for (size_t c = 0; c < 3; ++c) {
      if (std::abs(int(a.rgba[i + c]) - int(b.rgba[i + c])) > 8) {
        ++n;
        break;
      }
    }
  }
  return n;
}

// Pixels brighter than the clear colour (0.02, 0.02, 0.025): the scene.
std::vector<std::array<int, 3>> object_pixels(const client::Image& image) {
  std::vector<std::array<int, 3>> pixels;
  for (size_t i = 0; i + 3 < image.rgba.size(); i += 4) {
    const std::array<int, 3> p{image.rgba[i], image.rgba[i + 1], image.rgba[i + 2]};
    if (*std::max_element(p.begin(), p.end()) > 40) pixels.push_back(p);
  }
  return pixels;
}

std::vector<std::string> render_args(const std::string& cmd, const fs::path& out, int frames,
                                     const std::string& light) {
  return {"--connect", cmd,     "--instance", "1",   "--frames", std::to_string(frames),
          "--size",    "96x72", "--light",    light, "--out",    out.string()};
}

// No renderer gets a package (or any other file): everything it draws came over the sockets.
void expect_no_package(const std::vector<std::string>& args) {
  for (const auto& a : args) {
    EXPECT_NE(a, "--package");
    EXPECT_FALSE(fs::is_regular_file(a)) << a;
  }
}

// Waits until every renderer wrote a frame; fails with the stderr of one that ended.
void wait_for_first_frames(const std::vector<ChildProcess*>& renderers, const std::vector<fs::path>& dirs) {
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  for (;;) {
    bool all = true;
    for (size_t i = 0; i < dirs.size(); ++i) {
      if (frame_numbers(dirs[i]).empty()) all = false;
      if (renderers[i]->wait(0ms)) FAIL() << "renderer ended early: " << renderers[i]->err();
    }
    if (all) return;
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "renderers wrote no frame within 60 s";
    std::this_thread::sleep_for(20ms);
  }
}

// The first frame the subscriber sees, then frames until `last`.
std::vector<v1::Frame> frames_until(Subscriber& sub, std::uint64_t last) {
  std::vector<v1::Frame> frames;
  while (frames.empty() || frames.back().frame() < last) {
    auto f = sub.next(10s);
    if (!f) throw std::runtime_error("the server stopped publishing");
    frames.push_back(*f);
  }
  return frames;
}

double max_abs_difference(const google::protobuf::RepeatedField<float>& a,
                          const google::protobuf::RepeatedField<float>& b) {
  double d = 0;
  for (int i = 0; i < std::min(a.size(), b.size()); ++i) d = std::max(d, double(std::abs(a[i] - b[i])));
  return d;
}

TEST(EndToEnd, TwoRenderersOfOneInstanceWriteTheSameImagesAndSeeTheImpulse) {
  const auto dir = scratch_dir("e2e_two_renderers");
  core::write_package(make_plate_package(), dir / "plate.h5");
  ServerProcess server({(dir / "plate.h5").string(), "--instances", "1", "--rate", "30"});

  constexpr int kFrames = 120;
  const auto args_a = render_args(server.cmd(), dir / "a", kFrames, "sun");
  const auto args_b = render_args(server.cmd(), dir / "b", kFrames, "sun");
  expect_no_package(args_a);
  ChildProcess a("phasecast-render", args_a, dir / "render_a");
  ChildProcess b("phasecast-render", args_b, dir / "render_b");
  ASSERT_NO_FATAL_FAILURE(wait_for_first_frames({&a, &b}, {dir / "a", dir / "b"}));

  zmq::context_t context;
  CommandClient commands(context, server.cmd());
  Subscriber sub(context, server.pub(), "inst/1/");
  const auto rest = sub.next(10s);  // also waits out ZeroMQ's slow-joiner window
  ASSERT_TRUE(rest);
  const auto open = commands.call(impulse_request(1, "open"));
  ASSERT_TRUE(open.ok()) << open.error();
  const std::uint64_t impulse_frame = open.impulse().at_frame();
  const auto stream = frames_until(sub, impulse_frame + 30);

  ASSERT_EQ(a.wait(120s), 0) << a.err();
  ASSERT_EQ(b.wait(120s), 0) << b.err();
  EXPECT_NE(a.out().find("downloading the bases"), std::string::npos) << a.out();

  // Deformation and support motion in the stream after the impulse (eq. 12 switch to an IRF).
  double support_moved = 0, q_u_moved = 0;
  for (const auto& f : stream) {
    if (f.frame() <= impulse_frame) continue;
    support_moved = std::max(support_moved, max_abs_difference(f.support(), rest->support()));
    q_u_moved = std::max(q_u_moved, max_abs_difference(f.q_u(), rest->q_u()));
  }
  EXPECT_GT(support_moved, 0.05);
  EXPECT_GT(q_u_moved, 1e-3);

  // Each renderer wrote kFrames consecutive frames; the overlap is the same files.
  const auto fa = frame_numbers(dir / "a"), fb = frame_numbers(dir / "b");
  ASSERT_EQ(fa.size(), size_t(kFrames));
  ASSERT_EQ(fb.size(), size_t(kFrames));
  EXPECT_EQ(fa.back() - fa.front(), std::uint64_t(kFrames - 1));
  EXPECT_EQ(fb.back() - fb.front(), std::uint64_t(kFrames - 1));
  const std::uint64_t first = std::max(fa.front(), fb.front()), last = std::min(fa.back(), fb.back());
  ASSERT_GE(last, impulse_frame + 20) << "renderers too far apart to compare the impulse";
  ASSERT_LT(first, impulse_frame);
  for (std::uint64_t f = first; f <= last; ++f) {
    // Golden-image tolerance of tests/client: max channel difference <= 2/255.
    EXPECT_LE(client::max_channel_difference(frame_image(dir / "a", f), frame_image(dir / "b", f)), 2)
        << "frame " << f;
  }

  // At rest before the impulse: nothing moves. After it, the picture changes.
  const auto before = frame_image(dir / "a", impulse_frame - 1);
  for (std::uint64_t f = first; f < impulse_frame; ++f) {
    EXPECT_EQ(changed_pixels(before, frame_image(dir / "a", f)), 0) << "frame " << f;
  }
  int most_changed = 0;
  for (std::uint64_t f = impulse_frame; f <= std::min(last, impulse_frame + 30); ++f) {
    most_changed = std::max(most_changed, changed_pixels(before, frame_image(dir / "a", f)));
  }
  EXPECT_GT(most_changed, 96 * 72 / 50) << "the impulse is not visible in the images";
}

// A package without /appearance is drawn with the grey (rho = 0.7) diffuse
// transfer of the rest normals; under the white furnace every lit point has
// exit radiance 0.7, i.e. sRGB 0.7 -> 218 of 255.
TEST(EndToEnd, PackageWithoutAppearanceIsShadedFromRestNormals) {
  const auto dir = scratch_dir("e2e_no_appearance");
  PlateOptions options;
  options.appearance = false;
  core::write_package(make_plate_package(options), dir / "plate.h5");
  ServerProcess server({(dir / "plate.h5").string(), "--instances", "1", "--rate", "30"});
  auto args = render_args(server.cmd(), dir / "frames", 10, "white");
  args.insert(args.end(), {"--backdrop", "off"});  // every lit pixel is the plate's
  expect_no_package(args);
  ChildProcess render("phasecast-render", args, dir / "render");
  ASSERT_EQ(render.wait(120s), 0) << render.err();
  // The scene has no appearance bases to download: only the geometry parts and U_u.
  EXPECT_NE(render.out().find("U_u "), std::string::npos) << render.out();
  EXPECT_EQ(render.out().find("U_a "), std::string::npos) << render.out();

  const auto frames = frame_numbers(dir / "frames");
  ASSERT_EQ(frames.size(), 10u);
  const auto pixels = object_pixels(frame_image(dir / "frames", frames.back()));
  ASSERT_GT(pixels.size(), size_t(96 * 72 / 20)) << "the plate is not in the picture";
  const auto off = std::count_if(pixels.begin(), pixels.end(), [](const std::array<int, 3>& p) {
    return std::any_of(p.begin(), p.end(), [](int c) { return std::abs(c - 218) > 3; });
  });
  EXPECT_EQ(off, 0) << "of " << pixels.size() << " lit pixels, these are not grey sRGB(0.7) = 218";
}

// A package straight from the precompute pipeline, served and rendered.
TEST(EndToEnd, PrecomputedTinyClothDoorIsServedAndRendered) {
  const auto dir = scratch_dir("e2e_tiny_cloth_door");
  const auto package = dir / "tiny.h5";
  const auto run =
      run_tool("phasecast-precompute",
               {"run", (phasecast::testing::source_dir() / "scenes/tiny/cloth_door.toml").string(), "-o",
                package.string(), "--chains", "2", "--irfs-per-chain", "3"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto scene = core::read_package(package);

  ServerProcess server({package.string(), "--instances", "1", "--rate", "30"});
  const auto args = render_args(server.cmd(), dir / "frames", 60, "sun");
  expect_no_package(args);
  ChildProcess render("phasecast-render", args, dir / "render");
  ASSERT_NO_FATAL_FAILURE(wait_for_first_frames({&render}, {dir / "frames"}));
  zmq::context_t context;
  CommandClient commands(context, server.cmd());
  const auto open = commands.call(impulse_request(1, "open"));
  ASSERT_TRUE(open.ok()) << open.error();
  ASSERT_EQ(render.wait(120s), 0) << render.err();

  const auto frames = frame_numbers(dir / "frames");
  ASSERT_EQ(frames.size(), 60u);
  const std::uint64_t impulse_frame = open.impulse().at_frame();
  ASSERT_GT(impulse_frame, frames.front());
  ASSERT_LE(impulse_frame + 20, frames.back());
  const auto before = frame_image(dir / "frames", impulse_frame - 1);
  EXPECT_GT(object_pixels(before).size(), size_t(96 * 72 / 50)) << "the cloth door is not in the picture";
  int most_changed = 0;
  for (std::uint64_t f = impulse_frame; f <= impulse_frame + 20; ++f) {
    most_changed = std::max(most_changed, changed_pixels(before, frame_image(dir / "frames", f)));
  }
  EXPECT_GT(most_changed, 96 * 72 / 100)
      << "opening the door is not visible (scene " << scene.attributes.scene << ")";
}

}  // namespace
}  // namespace phasecast::testing
