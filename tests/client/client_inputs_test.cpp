// Rejection paths of the client's inputs: bases, frames, recordings, sizes,
// camera overrides, endpoints; and the small helpers (sequence gaps, PSNR).

#include "error_of.h"
#include "phasecast/client/camera.h"
#include "phasecast/client/client_basis.h"
#include "phasecast/client/frame_sources.h"
#include "phasecast/client/frame_state.h"
#include "phasecast/client/image_io.h"
#include "phasecast/client/network.h"
#include "phasecast/client/render_backend.h"
#include "phasecast/core/curve_keys.h"
#include "phasecast/core/recording.h"
#include "run_tool.h"
#include "synthetic_package.h"
#include "test_peer.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>

namespace phasecast::client {
namespace {

using phasecast::testing::error_of;

using ::testing::HasSubstr;

class ClientInputs : public ::testing::Test {
 protected:
  core::ScenePackage package_ = testing::make_plate_package();
  ClientBasis basis_ = basis_from_package(package_, 42);
};

TEST_F(ClientInputs, PackageBasesAreValid) {
  EXPECT_NO_THROW(basis_.validate("plate"));
  EXPECT_EQ(basis_.points, 85);
  EXPECT_EQ(basis_.rank_u, package_.rank_u());
  EXPECT_TRUE(basis_.has_transfer());
}

TEST_F(ClientInputs, BasisWithWrongUuSizeIsRejected) {
  basis_.U_u.pop_back();
  EXPECT_EQ(error_of([&] { basis_.validate("server"); }),
            "server: basis part U_u has 1019 values (expected 1020 = 3S x r_u)");
}

TEST_F(ClientInputs, BasisWithNaNIsRejected) {
  basis_.mean_transfer[7] = NAN;
  EXPECT_EQ(
      error_of([&] { basis_.validate("server"); }),
      "server: basis part mean_transfer has a non-finite value nan at index 7 (expected finite float32)");
}

TEST_F(ClientInputs, BasisWithTriangleOutOfRangeIsRejected) {
  basis_.triangles[4] = 85;
  EXPECT_EQ(error_of([&] { basis_.validate("server"); }),
            "server: basis part triangles refers to point 85 (expected indices < S = 85)");
}

TEST_F(ClientInputs, BasisWithRankButNoTransferIsRejected) {
  basis_.mean_transfer.clear();
  EXPECT_EQ(error_of([&] { basis_.validate("server"); }),
            fmt::format("server: r_a = {} but basis part mean_transfer is missing (expected 48S values)",
                        basis_.rank_a));
}

TEST_F(ClientInputs, FramesOfTheWrongShapeOrWithNaNAreRejected) {
  FrameState f = portrait_frames(package_, 0)[3];
  EXPECT_NO_THROW(validate_frame(f, basis_, "stream"));
  auto short_q = f;
  short_q.q_u.pop_back();
  EXPECT_EQ(error_of([&] { validate_frame(short_q, basis_, "stream"); }),
            "stream: frame 3: q_u has 3 values (expected r_u = 4)");
  auto bad_support = f;
  bad_support.support.resize(9);
  EXPECT_EQ(error_of([&] { validate_frame(bad_support, basis_, "stream"); }),
            "stream: frame 3: support has 9 values (expected 12, a 3x4 row-major transform)");
  auto nan = f;
  nan.q_a[1] = NAN;
  EXPECT_EQ(error_of([&] { validate_frame(nan, basis_, "stream"); }),
            "stream: frame 3: q_a[1] is nan (expected a finite number)");
}

TEST_F(ClientInputs, PortraitFramesFollowTheIrf) {
  const auto frames = portrait_frames(package_, 2);
  ASSERT_EQ(frames.size(), 90u);
  const int node = package_.portrait.irf_start[2] + 5;
  EXPECT_EQ(frames[5].frame, 5u);
  EXPECT_EQ(frames[5].q_u[1], package_.portrait.q_u(node, 1));
  EXPECT_EQ(frames[5].support[2], package_.portrait.support(node, 2));
  EXPECT_EQ(error_of([&] { portrait_frames(package_, 6); }),
            "--play-irf 6 is out of range (expected 0..5: the package has 6 IRFs)");
}

TEST_F(ClientInputs, RecordingRoundTripsAndStopsAtATruncatedRecord) {
  const auto dir = testing::scratch_dir("client_recording");
  const auto stream = testing::irf_stream(package_, 1);
  testing::write_recording(dir / "s.rec", "plate", "plate.h5", 99, stream);
  Recording rec = core::read_recording_file(dir / "s.rec");
  EXPECT_FALSE(rec.truncated);
  EXPECT_EQ(rec.header().scenes(0).content_hash(), 99u);
  auto frames = recorded_frames(rec, std::nullopt, "s.rec").frames;
  ASSERT_EQ(frames.size(), stream.size());
  EXPECT_EQ(frames[7].q_u[0], stream[7].q_u(0));

  // Cut the file inside its last record: that record is dropped and flagged.
  const auto size = std::filesystem::file_size(dir / "s.rec");
  std::filesystem::resize_file(dir / "s.rec", size - 5);
  rec = core::read_recording_file(dir / "s.rec");
  EXPECT_TRUE(rec.truncated);
  EXPECT_EQ(recorded_frames(rec, std::nullopt, "s.rec").frames.size(), stream.size() - 1);
  EXPECT_EQ(error_of([&] { recorded_frames(rec, 5u, "s.rec"); }),
            "recording s.rec: no frames of instance 5 (expected one of 1: the instances it holds)");
}

// A recording of two scenes: instance 3 of "dashboard" comes first, then
// instances 1 and 2 of the plate. The scene filter (phasecast-render --replay
// and phasecast-export both pass the package's scene) picks the plate's.
TEST_F(ClientInputs, RecordedFramesOfOneScene) {
  const auto dir = testing::scratch_dir("client_recording_scenes");
  auto other = testing::irf_stream(package_, 0, 3);
  for (auto& f : other) f.set_scene("dashboard");
  auto frames = other;
  const auto first = testing::irf_stream(package_, 1, 1), second = testing::irf_stream(package_, 2, 2);
  frames.insert(frames.end(), first.begin(), first.end());
  frames.insert(frames.end(), second.begin(), second.end());
  frames.back().clear_scene();  // an empty scene field counts as the scene asked for
  testing::write_recording(dir / "s.rec", "plate", "plate.h5", 42, frames);
  const Recording rec = core::read_recording_file(dir / "s.rec");

  EXPECT_EQ(recorded_frames(rec, std::nullopt, "s.rec").instance, 3u);  // no filter: the first frame's
  const auto plate = recorded_frames(rec, std::nullopt, "s.rec", std::string("plate"));
  EXPECT_EQ(plate.instance, 1u);
  ASSERT_EQ(plate.frames.size(), first.size());
  EXPECT_EQ(plate.frames[4].q_u[0], first[4].q_u(0));
  EXPECT_EQ(recorded_frames(rec, 2u, "s.rec", std::string("plate")).frames.size(), second.size());
  EXPECT_EQ(
      error_of([&] { recorded_frames(rec, 3u, "s.rec", std::string("plate")); }),
      "recording s.rec: no frames of instance 3 (expected one of 1, 2: the instances of scene 'plate' it "
      "holds)");
  testing::write_recording(dir / "d.rec", "plate", "plate.h5", 42, other);  // only the dashboard's frames
  const Recording dashboard = core::read_recording_file(dir / "d.rec");
  EXPECT_EQ(error_of([&] { recorded_frames(dashboard, std::nullopt, "d.rec", std::string("plate")); }),
            "recording d.rec: no frames of scene 'plate' (expected frames of the package's scene)");
}

// The header must name the package's scene with the package file's hash.
TEST_F(ClientInputs, RecordingOfAnotherPackageOrSceneIsRejected) {
  const auto dir = testing::scratch_dir("client_recording_package");
  testing::write_recording(dir / "s.rec", "plate", "plate.h5", 42, testing::irf_stream(package_, 0));
  const Recording rec = core::read_recording_file(dir / "s.rec");
  EXPECT_NO_THROW(expect_recorded_with(rec, basis_, "s.rec", "plate.h5"));
  ClientBasis rebuilt = basis_;
  rebuilt.content_hash = 43;
  EXPECT_EQ(
      error_of([&] { expect_recorded_with(rec, rebuilt, "s.rec", "new.h5"); }),
      "recording s.rec: scene 'plate' was recorded with package hash 000000000000002a, but new.h5 has hash "
      "000000000000002b (expected the same package file)");
  ClientBasis cube = basis_;
  cube.scene = "cube";
  EXPECT_EQ(error_of([&] { expect_recorded_with(rec, cube, "s.rec", "cube.h5"); }),
            "recording s.rec: no scene 'cube' (expected the scene of cube.h5; it records 'plate')");
}

// The full set of rejections is in tests/server/recording_test.cpp; these are
// the ones --replay meets most, through the same core reader.
TEST_F(ClientInputs, RecordingsThatAreNotRecordingsAreRejected) {
  const auto dir = testing::scratch_dir("client_bad_recording");
  auto read = [](const std::filesystem::path& p) { return error_of([&] { core::read_recording_file(p); }); };
  std::ofstream(dir / "bad.rec") << "PHCREC2\nxxxx";
  EXPECT_EQ(read(dir / "bad.rec"),
            fmt::format("recording '{}': not a Phasecast recording (expected the magic \"PHCREC1\\n\")",
                        (dir / "bad.rec").string()));
  EXPECT_EQ(read(dir / "missing.rec"), fmt::format("recording '{}': cannot open: No such file or directory",
                                                   (dir / "missing.rec").string()));
  {
    std::ofstream out(dir / "noheader.rec", std::ios::binary);
    v1::RecordEntry e;
    e.mutable_frame()->set_instance(1);
    const auto bytes = e.SerializeAsString();
    out << "PHCREC1\n" << static_cast<char>(bytes.size()) << bytes;
  }
  EXPECT_EQ(read(dir / "noheader.rec"),
            fmt::format("recording '{}': expected a RecordingHeader as the first record",
                        (dir / "noheader.rec").string()));
  {
    std::ofstream out(dir / "garbage.rec", std::ios::binary);
    out << "PHCREC1\n" << static_cast<char>(3) << "\xff\xff\xff";
  }
  EXPECT_EQ(read(dir / "garbage.rec"),
            fmt::format("recording '{}': record 0 at byte 8 does not parse as a RecordEntry",
                        (dir / "garbage.rec").string()));
}

TEST(ClientParsing, SizesAndVectors) {
  EXPECT_EQ(parse_size("1280x720"), (std::array<int, 2>{1280, 720}));
  EXPECT_EQ(error_of([] { parse_size("1280*720"); }),
            "--size '1280*720' is invalid (expected WIDTHxHEIGHT, e.g. 1280x720)");
  EXPECT_EQ(error_of([] { parse_size("0x720"); }),
            "--size '0x720' is invalid (expected WIDTHxHEIGHT, e.g. 1280x720)");
  EXPECT_TRUE(parse_vector3("1,2.5,-3", "--eye").isApprox(Eigen::Vector3f(1, 2.5f, -3)));
  EXPECT_EQ(error_of([] { parse_vector3("1,2", "--eye"); }),
            "--eye '1,2' is invalid (expected three finite numbers x,y,z)");
  EXPECT_EQ(error_of([] { parse_vector3("1,nan,2", "--up"); }),
            "--up '1,nan,2' is invalid (expected three finite numbers x,y,z)");
}

TEST(ClientBackends, UnknownBackendNameListsTheKnownOnes) {
  EXPECT_EQ(error_of([] { make_render_backend("vulkan", 64, 64); }),
            "render backend 'vulkan' is unknown (expected one of osmesa, egl, window)");
  EXPECT_EQ(error_of([] { make_render_backend("osmesa", 0, 64); }),
            "render size 0x64 is invalid (expected 1..16384 pixels per side)");
}

TEST(ClientBackends, WindowWithoutDisplaySaysWhatToUseInstead) {
  ::unsetenv("DISPLAY");
  ::unsetenv("WAYLAND_DISPLAY");
  EXPECT_THAT(error_of([] { make_render_backend("window", 64, 64); }),
              ::testing::AllOf(HasSubstr("window backend: GLFW could not start"),
                               HasSubstr("use --backend osmesa or egl on machines without a display")));
}

TEST(ClientNetwork, SequenceGapsAndRestartsAreCounted) {
  SequenceTracker t;
  std::vector<bool> restarted;
  for (std::uint64_t s : {0, 1, 2, 5, 6, 9, 0, 1}) restarted.push_back(t.observe(s));
  EXPECT_EQ(t.gaps, 2u);
  EXPECT_EQ(t.missed, 4u);
  EXPECT_EQ(t.restarts, 1u);
  EXPECT_EQ(restarted, (std::vector<bool>{false, false, false, false, false, false, true, false}));
}

TEST(ClientNetwork, FramesOfARestartedServerGetTheirOwnFileNames) {
  EXPECT_EQ(frame_file_name(7, 0), "frame_000007.png");
  EXPECT_EQ(frame_file_name(7, 1), "restart01_frame_000007.png");
  EXPECT_EQ(frame_file_name(1234567, 12), "restart12_frame_1234567.png");
}

// --server-key / --client-key as both clients read them (load_curve_client_keys).
class CurveKeyOptions : public ::testing::Test {
 protected:
  void SetUp() override {
    // One folder per test: ctest runs the cases as parallel processes that would
    // otherwise rewrite each other's key files mid-read.
    dir_ = testing::scratch_dir(std::string("curve_key_options_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
    core::write_key_files(dir_ / "server", {kServerPublic, kServerSecret});
    core::write_key_files(dir_ / "client", {kClientPublic, kClientSecret});
    std::ofstream(dir_ / "bad.pub") << "public = not-a-key\n";
  }
  std::filesystem::path file(const std::string& name) const { return dir_ / name; }

  // Any 40 characters of the Z85 alphabet are well-formed keys.
  static constexpr const char* kServerPublic = "rq:rM>}U?@Lns47E1%kR.o@n%FcmmsL/@{H8]yf7";
  static constexpr const char* kServerSecret = "JTKVSB%%)wK0E.X)V>+}o?pNmC{O&4W4b!Ni{Lh6";
  static constexpr const char* kClientPublic = "Yne@$w-vo<fVvi]a<NY6T1ed:M$fCG*[IaLV{hID";
  static constexpr const char* kClientSecret = "D:)Q[IlAW!ahhC2ac:9*A}h:p?([4%wOTJ%JR%cs";
  std::filesystem::path dir_;
};

TEST_F(CurveKeyOptions, NoKeysMeansNoCurve) {
  EXPECT_FALSE(load_curve_client_keys({}, {}).enabled());
}

TEST_F(CurveKeyOptions, KeyFilesAreRead) {
  const auto keys = load_curve_client_keys(file("server.pub"), file("client.key"));
  EXPECT_TRUE(keys.enabled());
  EXPECT_EQ(keys.server_public, kServerPublic);
  EXPECT_EQ(keys.client_public, kClientPublic);
  EXPECT_EQ(keys.client_secret, kClientSecret);
}

TEST_F(CurveKeyOptions, ServerKeyAloneMakesAFreshEphemeralPair) {
  const auto a = load_curve_client_keys(file("server.pub"), {});
  const auto b = load_curve_client_keys(file("server.pub"), {});
  EXPECT_EQ(a.server_public, kServerPublic);
  EXPECT_TRUE(core::is_z85_key(a.client_public));
  EXPECT_TRUE(core::is_z85_key(a.client_secret));
  EXPECT_NE(a.client_public, b.client_public);  // never a key shared between runs
}

TEST_F(CurveKeyOptions, ErrorsNameTheOptionAndTheFile) {
  EXPECT_EQ(
      error_of<std::invalid_argument>([&] { load_curve_client_keys({}, file("client.key")); }),
      fmt::format("--client-key {} needs --server-key FILE (the server's public key; CURVE authenticates "
                  "both sides)",
                  file("client.key").string()));
  EXPECT_EQ(error_of<std::invalid_argument>([&] { load_curve_client_keys(file("none.pub"), {}); }),
            fmt::format("--server-key: key file '{}' cannot be read: No such file or directory",
                        file("none.pub").string()));
  EXPECT_THAT(error_of<std::invalid_argument>([&] { load_curve_client_keys(file("bad.pub"), {}); }),
              ::testing::StartsWith(
                  fmt::format("--server-key: key file '{}' line 1: expected", file("bad.pub").string())));
  // The public file given where this client's secret one belongs.
  EXPECT_THAT(error_of<std::invalid_argument>(
                  [&] { load_curve_client_keys(file("server.pub"), file("client.pub")); }),
              ::testing::StartsWith(fmt::format("--client-key: key file '{}' is not a secret key file",
                                                file("client.pub").string())));
}

TEST(ClientNetwork, WildcardPubHostTakesTheCommandHost) {
  EXPECT_EQ(resolve_pub_endpoint("tcp://0.0.0.0:5556", "tcp://render-host:5555"), "tcp://render-host:5556");
  EXPECT_EQ(resolve_pub_endpoint("tcp://*:5556", "tcp://10.0.0.2:5555"), "tcp://10.0.0.2:5556");
  EXPECT_EQ(resolve_pub_endpoint("tcp://127.0.0.1:7000", "tcp://10.0.0.2:5555"), "tcp://127.0.0.1:7000");
  EXPECT_EQ(error_of([] { resolve_pub_endpoint("", "tcp://h:1"); }),
            "list_scenes: the server sent no pub_endpoint (expected e.g. tcp://host:5556)");
}

TEST(ClientImages, PsnrAndMaxDifference) {
  Image a{2, 1, {10, 20, 30, 255, 40, 50, 60, 255}};
  Image b = a;
  EXPECT_TRUE(std::isinf(psnr(a, b)));
  b.rgba[1] = 22;
  EXPECT_EQ(max_channel_difference(a, b), 2);
  EXPECT_NEAR(psnr(a, b), 10 * std::log10(255.0 * 255.0 / (4.0 / 6.0)), 1e-9);
  Image c{1, 1, {0, 0, 0, 255}};
  EXPECT_EQ(error_of([&] { psnr(a, c); }), "image sizes differ: 2x1 vs 1x1 (expected equal sizes)");
  EXPECT_EQ(frame_file_name(123), "frame_000123.png");
}

}  // namespace
}  // namespace phasecast::client
