// phasecast-render in local mode as a user runs it: golden image of a
// replayed recording, vertex dumps against the CPU, one-line errors.

#include "phasecast/client/client_basis.h"
#include "phasecast/client/frame_output.h"
#include "phasecast/client/frame_sources.h"
#include "phasecast/client/image_io.h"
#include "phasecast/client/low_rank_renderer.h"
#include "phasecast/core/hash.h"
#include "run_tool.h"
#include "source_tree.h"
#include "synthetic_package.h"
#include "test_peer.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cstdio>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace phasecast::client {
namespace {

using ::testing::HasSubstr;

const std::filesystem::path kGoldenDir = phasecast::testing::source_dir() / "tests/client/golden";

class RenderCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(std::string("render_cli_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
    package_ = testing::make_plate_package();
    core::write_package(package_, dir_ / "plate.h5");
    hash_ = core::file_content_hash(dir_ / "plate.h5");
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  // Runs the tool and expects failure with exactly one line on stderr.
  std::string one_line_error(const std::vector<std::string>& args) const {
    const auto r = testing::run_tool("phasecast-render", args);
    EXPECT_NE(r.exit_code, 0) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    return r.err;
  }

  std::filesystem::path dir_;
  core::ScenePackage package_;
  std::uint64_t hash_ = 0;
};

// Golden image: frame 45 of a recording of IRF 4, under the "sun" light,
// without the backdrop (the golden image checks the scene's evaluation).
// Tolerance: PSNR >= 40 dB or max channel difference <= 2/255 (llvmpipe
// versions differ by rounding). PHASECAST_UPDATE_GOLDEN=1 rewrites it.
TEST_F(RenderCli, ReplayedRecordingMatchesGoldenImage) {
  testing::write_recording(dir_ / "s.rec", "plate", "plate.h5", hash_, testing::irf_stream(package_, 4));
  const auto r = testing::run_tool(
      "phasecast-render", {"--replay", path("s.rec"), "--package", path("plate.h5"), "--light", "sun",
                           "--size", "160x120", "--backdrop", "off", "--out", path("out")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("90 frames at 160x120"));
  const auto rendered = dir_ / "out" / "frame_000045.png";
  const auto golden = kGoldenDir / "plate_irf4_sun_frame_000045.png";
  if (std::getenv("PHASECAST_UPDATE_GOLDEN")) {
    std::filesystem::create_directories(kGoldenDir);
    std::filesystem::copy_file(rendered, golden, std::filesystem::copy_options::overwrite_existing);
  }
  const Image a = read_png(rendered), b = read_png(golden);
  const double p = psnr(a, b);
  const int diff = max_channel_difference(a, b);
  EXPECT_TRUE(p >= 40 || diff <= 2) << "PSNR " << p << " dB, max channel difference " << diff;
  // The frames differ over time: the cloth moves and the door turns.
  EXPECT_GT(max_channel_difference(read_png(dir_ / "out" / "frame_000000.png"), a), 20);
}

TEST_F(RenderCli, VertexDumpsEqualCpuPositions) {
  for (const std::string format : {"npy", "csv"}) {
    const auto file = path("dump." + format);
    const auto r = testing::run_tool("phasecast-render", {"--package", path("plate.h5"), "--play-irf", "2",
                                                          "--size", "64x64", "--dump-vertices", "17", file});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::vector<float> table;
    if (format == "npy") {
      std::ifstream in(file, std::ios::binary);
      std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      ASSERT_EQ(all.substr(0, 6), "\x93NUMPY");
      const auto header_len = static_cast<std::size_t>(static_cast<unsigned char>(all[8])) +
                              256 * static_cast<std::size_t>(static_cast<unsigned char>(all[9]));
      EXPECT_THAT(all.substr(10, header_len), HasSubstr("'shape': (85, 6)"));
      table.resize((all.size() - 10 - header_len) / 4);
      std::memcpy(table.data(), all.data() + 10 + header_len, table.size() * 4);
    } else {
      std::ifstream in(file);
      std::string line;
      std::getline(in, line);
      EXPECT_EQ(line, "x,y,z,r,g,b");
      while (std::getline(in, line)) {
        std::stringstream row(line);
        std::string cell;
        while (std::getline(row, cell, ',')) table.push_back(std::stof(cell));
      }
    }
    ASSERT_EQ(table.size(), 85u * 6);
    const auto f = portrait_frames(package_, 2)[17];
    const auto cpu = cpu_positions(basis_from_package(package_, 0), f.q_u, f.support);
    for (std::size_t v = 0; v < 85; ++v) {
      for (std::size_t c = 0; c < 3; ++c) {
        EXPECT_NEAR(table[6 * v + c], cpu[3 * v + c], 1e-5 * (std::abs(cpu[3 * v + c]) + 1))
            << format << " " << v;
      }
    }
  }
}

// --backdrop on (the default) adds a floor behind the scene and changes
// nothing else: the scene's pixels are those of --backdrop off, which draws
// the plain picture of the golden image, and the vertex dumps are the same bytes.
TEST_F(RenderCli, BackdropFramesTheSceneAndLeavesItAlone) {
  auto render = [&](const std::string& out, std::vector<std::string> extra) {
    std::vector<std::string> args = {"--package", path("plate.h5"), "--play-irf", "4", "--light", "sun"};
    args.insert(args.end(), {"--size", "160x120", "--frames", "46", "--out", path(out)});
    args.insert(args.end(), {"--dump-vertices", "45", path(out + ".npy")});
    args.insert(args.end(), extra.begin(), extra.end());
    const auto r = testing::run_tool("phasecast-render", args);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return read_png(dir_ / out / "frame_000045.png");
  };
  const Image framed = render("on", {}), explicit_on = render("explicit_on", {"--backdrop", "on"}),
              plain = render("off", {"--backdrop", "off"});
  EXPECT_EQ(max_channel_difference(framed, explicit_on), 0);
  EXPECT_EQ(testing::read_file(dir_ / "on.npy"), testing::read_file(dir_ / "off.npy"));
  const Image golden = read_png(kGoldenDir / "plate_irf4_sun_frame_000045.png");
  EXPECT_TRUE(psnr(plain, golden) >= 40 || max_channel_difference(plain, golden) <= 2);

  auto at = [](const Image& image, std::size_t i) {
    return std::array<int, 3>{image.rgba[4 * i], image.rgba[4 * i + 1], image.rgba[4 * i + 2]};
  };
  auto display = [](const std::array<float, 3>& colour) {  // clear colours are written as they are
    return std::array<int, 3>{static_cast<int>(std::lround(255 * colour[0])),
                              static_cast<int>(std::lround(255 * colour[1])),
                              static_cast<int>(std::lround(255 * colour[2]))};
  };
  const auto plain_background = display(kPlainBackground), background = display(kBackdropBackground);
  std::size_t scene = 0, floor_below = 0;
  const std::size_t pixels = 160 * 120;
  for (std::size_t i = 0; i < pixels; ++i) {
    if (at(plain, i) != plain_background) {
      ++scene;
      EXPECT_EQ(at(framed, i), at(plain, i)) << "scene pixel " << i % 160 << ", " << i / 160;
    } else if (i / 160 >= 100 && at(framed, i) != background) {
      ++floor_below;  // the bottom rows: neither background nor scene
    }
  }
  EXPECT_GT(scene, pixels / 20);
  EXPECT_GT(floor_below, 160 * 20 / 2) << "the bottom rows should show the floor around the plate";
  EXPECT_EQ(at(framed, 0), background) << "top left: the flat background";
}

TEST_F(RenderCli, HelpDescribesTheModes) {
  const auto r = testing::run_tool("phasecast-render", {"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("--connect"));
  EXPECT_THAT(r.out, HasSubstr("--dump-vertices"));
  EXPECT_THAT(r.out, HasSubstr("osmesa, egl, window"));
  EXPECT_THAT(r.out, HasSubstr("--backdrop"));
}

// Local mode draws --count copies of the IRF in one view, each further on
// in it: the dump holds every copy's points, each copy the single-instance
// frame moved to its place on the grid.
TEST_F(RenderCli, CountDrawsCopiesOfTheIrfSideBySide) {
  const auto file = path("copies.csv");
  const auto r =
      testing::run_tool("phasecast-render", {"--package", path("plate.h5"), "--play-irf", "2", "--count", "3",
                                             "--size", "64x64", "--dump-vertices", "0", file});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr(", 3 instances"));
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  std::vector<std::vector<float>> rows;
  while (std::getline(in, line)) {
    std::stringstream row(line);
    std::string cell;
    auto& values = rows.emplace_back();
    while (std::getline(row, cell, ',')) values.push_back(std::stof(cell));
  }
  ASSERT_EQ(rows.size(), 3u * 85);
  const auto frames = portrait_frames(package_, 2);
  const auto basis = basis_from_package(package_, 0);
  const std::size_t stagger = frames.size() / 3;
  const auto placements = grid_placements(rest_bounds(basis), 3);
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& f = frames[i * stagger];
    const auto cpu = cpu_positions(basis, f.q_u, f.support);
    for (std::size_t v = 0; v < 85; ++v) {
      for (int c = 0; c < 3; ++c) {
        const double want = cpu[3 * v + static_cast<std::size_t>(c)] + placements[i](c, 3);
        EXPECT_NEAR(rows[85 * i + v][static_cast<std::size_t>(c)], want, 1e-5 * (std::abs(want) + 1))
            << "copy " << i << ", point " << v;
      }
    }
  }
}

// --layout places each copy where the file says: moved, and turned about y.
TEST_F(RenderCli, LayoutPlacesEachInstanceWhereTheFileSays) {
  const auto layout = path("layout.json");
  std::ofstream(layout) << R"({"placements": [{"translate": [3, 0, 0]},
                                              {"translate": [-1, 0, 0.5], "rotate_y_deg": 90}]})";
  const auto file = path("placed.csv");
  const auto r = testing::run_tool(
      "phasecast-render", {"--package", path("plate.h5"), "--play-irf", "2", "--count", "2", "--layout",
                           layout, "--size", "64x64", "--dump-vertices", "0", file});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  std::vector<std::array<double, 3>> rows;
  while (std::getline(in, line)) {
    std::array<double, 3> p{};
    std::sscanf(line.c_str(), "%lf,%lf,%lf", &p[0], &p[1], &p[2]);
    rows.push_back(p);
  }
  ASSERT_EQ(rows.size(), 2u * 85);
  const auto frames = portrait_frames(package_, 2);
  const auto basis = basis_from_package(package_, 0);
  const auto first = cpu_positions(basis, frames[0].q_u, frames[0].support);
  const auto second = cpu_positions(basis, frames[frames.size() / 2].q_u, frames[frames.size() / 2].support);
  for (std::size_t v = 0; v < 85; ++v) {
    EXPECT_NEAR(rows[v][0], first[3 * v] + 3, 1e-5) << v;
    EXPECT_NEAR(rows[v][2], first[3 * v + 2], 1e-5) << v;
    // A quarter turn about y: (x, y, z) -> (z, y, -x).
    EXPECT_NEAR(rows[85 + v][0], second[3 * v + 2] - 1, 1e-5) << v;
    EXPECT_NEAR(rows[85 + v][1], second[3 * v + 1], 1e-5) << v;
    EXPECT_NEAR(rows[85 + v][2], -second[3 * v] + 0.5, 1e-5) << v;
  }
  std::ofstream(path("short.json")) << R"({"placements": [{}]})";
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--count", "2", "--layout", path("short.json")}),
            "phasecast-render: --layout " + path("short.json") +
                ": places 1 instances, 2 are drawn (expected an entry for each)\n");
  std::ofstream(path("typo.json")) << R"({"placements": [{"translat": [1, 2, 3]}]})";
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--layout", path("typo.json")}),
            "phasecast-render: --layout " + path("typo.json") +
                ": placements[0] has an unknown key 'translat' (expected translate, rotate_y_deg)\n");
  std::ofstream(path("nan.json")) << R"({"placements": [{"translate": [1, "x", 3]}]})";
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--layout", path("nan.json")}),
            "phasecast-render: --layout " + path("nan.json") +
                ": placements[0].translate[1] is not a finite number\n");
}

// The window's pacing: frame k shown at start + k period; a renderer that
// fell behind by more than a period starts again from then, not rushing.
TEST(FramePacer, ShowsFramesAtTheStreamsRateAndDoesNotRushAfterAStall) {
  using namespace std::chrono_literals;
  FramePacer pacer(0.02);
  const FramePacer::Clock::time_point t0{};
  EXPECT_EQ(pacer.wait(t0), 0ms) << "the first frame at once";
  EXPECT_EQ(pacer.wait(t0 + 5ms), 15ms) << "the second 20 ms after the first";
  EXPECT_EQ(pacer.wait(t0 + 21ms), 19ms) << "the third at 40 ms";
  EXPECT_EQ(pacer.wait(t0 + 45ms), 15ms) << "due at 60 ms";
  EXPECT_EQ(pacer.wait(t0 + 200ms), 0ms) << "late by more than a period: shown now";
  EXPECT_EQ(pacer.wait(t0 + 201ms), 19ms) << "and paced from there, not caught up in a burst";
}

TEST_F(RenderCli, BadInputsGiveOneLineErrors) {
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--backend", "vulkan"}),
            "phasecast-render: render backend 'vulkan' is unknown (expected one of osmesa, egl, window)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--light", "moon"}),
            "phasecast-render: light probe 'moon' is unknown (expected one of grace, sky, sun, white)\n");
  EXPECT_EQ(one_line_error({"--connect", "tcp://127.0.0.1:1", "--instances", "1,x"}),
            "phasecast-render: --instances '1,x' is invalid at 'x' (expected all, or instance ids each once: "
            "1,2,3)\n");
  EXPECT_EQ(one_line_error({"--connect", "tcp://127.0.0.1:1", "--instances", "2,2"}),
            "phasecast-render: --instances '2,2' is invalid at '2' (expected all, or instance ids each once: "
            "1,2,3)\n");
  EXPECT_EQ(one_line_error({"--connect", "tcp://127.0.0.1:1", "--instances", "1,2", "--create", "plate"}),
            "phasecast-render: give --instances, --instance or --create, one of them\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--instances", "1,2"}),
            "phasecast-render: --instances needs --connect tcp://host:5555 or --replay stream.rec\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--count", "0"}),
            "phasecast-render: --count 0 is invalid (expected 1..4096 instances)\n");
  EXPECT_EQ(one_line_error({"--connect", "tcp://127.0.0.1:1", "--count", "4"}),
            "phasecast-render: --count needs --create SCENE (network) or local mode (--package p.h5)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--backdrop", "maybe"}),
            "phasecast-render: --backdrop 'maybe' is invalid (expected on or off)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--size", "big"}),
            "phasecast-render: --size 'big' is invalid (expected WIDTHxHEIGHT, e.g. 1280x720)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--play-irf", "7"}),
            "phasecast-render: --play-irf 7 is out of range (expected 0..5: the package has 6 IRFs)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--dump-vertices", "3", path("d.txt")}),
            fmt::format(
                "phasecast-render: --dump-vertices file '{}' has an unknown format (expected a .npy or .csv "
                "name)\n",
                path("d.txt")));
  EXPECT_EQ(
      one_line_error({"--package", path("plate.h5"), "--dump-vertices", "x3", path("d.csv")}),
      "phasecast-render: --dump-vertices frame 'x3' is invalid (expected a frame number, then out.npy or "
      "out.csv)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--dump-vertices", "500", path("d.csv")}),
            "phasecast-render: --dump-vertices 500: no such frame (expected 0..89)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--eye", "1,2"}),
            "phasecast-render: --eye '1,2' is invalid (expected three finite numbers x,y,z)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--frame-timeout", "0"}),
            "phasecast-render: --frame-timeout 0 is invalid (expected a positive number of seconds)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--exposure", "-1"}),
            "phasecast-render: --exposure -1 is invalid (expected a positive number)\n");
  EXPECT_EQ(
      one_line_error({"--package", path("plate.h5"), "--connect", "tcp://127.0.0.1:9"}),
      "phasecast-render: choose one frame source (expected --connect tcp://host:5555, --replay stream.rec "
      "--package p.h5, or --package p.h5 [--play-irf I])\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--create", "plate"}),
            "phasecast-render: --create needs --connect tcp://host:5555\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--instance", "2"}),
            "phasecast-render: --instance needs --connect tcp://host:5555 or --replay stream.rec\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--fov", "180"}),
            "phasecast-render: --fov 180 is invalid (expected degrees in (0, 180))\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--eye", "0.5,0.5,0", "--target", "0.5,0.5,0"}),
            "phasecast-render: camera eye and target coincide (expected distinct --eye and --target)\n");
  EXPECT_EQ(
      one_line_error({"--package", path("plate.h5"), "--up", "0,0,1"}),
      "phasecast-render: camera --up is parallel to the view direction (expected a vector across it)\n");
  EXPECT_EQ(one_line_error({"--replay", path("s.rec"), "--package", path("plate.h5"), "--play-irf", "1"}),
            "phasecast-render: --play-irf is for local mode (--package without --replay or --connect)\n");
  EXPECT_EQ(one_line_error({"--package", path("plate.h5"), "--frames", "many"}),
            "phasecast-render: Could not convert: --frames = many (see --help)\n");
  EXPECT_THAT(one_line_error({"--package", path("plate.h5"), "--colour"}), HasSubstr("--colour"));
  EXPECT_EQ(one_line_error({"--replay", path("s.rec")}),
            "phasecast-render: --replay needs --package p.h5: a recording holds frames, not the bases\n");
  EXPECT_EQ(
      one_line_error({}),
      "phasecast-render: choose one frame source (expected --connect tcp://host:5555, --replay stream.rec "
      "--package p.h5, or --package p.h5 [--play-irf I])\n");
  EXPECT_THAT(one_line_error({"--package", path("missing.h5")}), HasSubstr("missing.h5"));
}

TEST_F(RenderCli, RecordingOfAnotherPackageIsRejected) {
  testing::write_recording(dir_ / "s.rec", "plate", "plate.h5", hash_ + 1, testing::irf_stream(package_, 0));
  EXPECT_EQ(
      one_line_error({"--replay", path("s.rec"), "--package", path("plate.h5")}),
      fmt::format(
          "phasecast-render: recording {}: scene 'plate' was recorded with package hash {:016x}, but {} "
          "has hash {:016x} (expected the same package file)\n",
          path("s.rec"), hash_ + 1, path("plate.h5"), hash_));
  testing::write_recording(dir_ / "u.rec", "dashboard", "dash.h5", hash_, testing::irf_stream(package_, 0));
  EXPECT_EQ(
      one_line_error({"--replay", path("u.rec"), "--package", path("plate.h5")}),
      fmt::format("phasecast-render: recording {}: no scene 'plate' (expected the scene of {}; it records "
                  "'dashboard')\n",
                  path("u.rec"), path("plate.h5")));
  // Only the package's scene counts: instance 3 of another scene is not offered.
  auto two_scenes = testing::irf_stream(package_, 1, 3);
  for (auto& f : two_scenes) f.set_scene("dashboard");
  const auto plate = testing::irf_stream(package_, 2, 1);
  two_scenes.insert(two_scenes.end(), plate.begin(), plate.end());
  testing::write_recording(dir_ / "v.rec", "plate", "plate.h5", hash_, two_scenes);
  EXPECT_EQ(one_line_error({"--replay", path("v.rec"), "--package", path("plate.h5"), "--instance", "3"}),
            fmt::format("phasecast-render: recording {}: no frames of instance 3 (expected one of 1: the "
                        "instances of scene 'plate' it holds)\n",
                        path("v.rec")));
  auto stream = testing::irf_stream(package_, 0);
  stream[3].add_q_u(1.0f);
  testing::write_recording(dir_ / "t.rec", "plate", "plate.h5", hash_, stream);
  EXPECT_EQ(one_line_error({"--replay", path("t.rec"), "--package", path("plate.h5")}),
            fmt::format("phasecast-render: recording {}: frame 3: q_u has 5 values (expected r_u = 4)\n",
                        path("t.rec")));
}

TEST_F(RenderCli, VideoNeedsFfmpegOrSaysSo) {
  const auto r = testing::run_tool("phasecast-render", {"--package", path("plate.h5"), "--frames", "12",
                                                        "--size", "64x48", "--video", path("v.mp4")});
  if (find_ffmpeg().empty()) {
    EXPECT_NE(r.exit_code, 0);
    EXPECT_THAT(r.err, HasSubstr("ffmpeg is not installed"));
  } else {
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_GT(std::filesystem::file_size(path("v.mp4")), 100u);
  }
}

}  // namespace
}  // namespace phasecast::client
