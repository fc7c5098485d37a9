// phasecast-render --connect against the in-test peer (test_peer.h) on
// loopback: basis download without a package file, PNGs named by the
// server's frame numbers equal to local rendering, two clients agree,
// sequence gaps, reconnect with the content-hash re-check, refused requests.

#include "child_process.h"
#include "phasecast/client/image_io.h"
#include "real_server.h"
#include "run_tool.h"
#include "synthetic_package.h"
#include "test_peer.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>

#include <chrono>
#include <csignal>
#include <fstream>
#include <regex>
#include <thread>

extern char** environ;

namespace phasecast::client {
namespace {

using ::testing::HasSubstr;

// Runs phasecast-render in the background (two clients at once).
class BackgroundTool {
 public:
  // Its stdout and stderr both go to `log`.
  BackgroundTool(const std::vector<std::string>& args, const std::filesystem::path& log) {
    std::vector<std::string> argv = {testing::tool_path("phasecast-render").string()};
    argv.insert(argv.end(), args.begin(), args.end());
    std::vector<char*> raw;
    for (auto& a : argv) raw.push_back(a.data());
    raw.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 2, 1);
    if (posix_spawn(&pid_, raw[0], &actions, nullptr, raw.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  int wait() {
    int status = 0;
    if (pid_ <= 0 || ::waitpid(pid_, &status, 0) != pid_) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }

 private:
  pid_t pid_ = -1;
};

std::size_t files_in(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::exists(dir, ec)) return 0;
  return static_cast<std::size_t>(std::distance(std::filesystem::directory_iterator(dir), {}));
}

class NetworkRender : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(std::string("network_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
    package_ = testing::make_plate_package();
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::vector<std::string> client_args(const testing::TestPeer& peer, const std::string& out,
                                       int frames) const {
    return {"--connect", peer.cmd_endpoint(),
            "--frames",  std::to_string(frames),
            "--size",    "96x72",
            "--light",   "sun",
            "--out",     path(out)};
  }

  std::filesystem::path dir_;
  core::ScenePackage package_;
};

// A renderer pointed at the server's PUB port (an easy slip: both ports are
// printed) is told so, instead of only being sent to look at CURVE keys.
TEST_F(NetworkRender, ThePubPortIsNamedAsTheLikelySlip) {
  core::write_package(package_, dir_ / "plate.h5");
  testing::RealServer server(dir_ / "plate.h5", "tcp://127.0.0.1:*", "tcp://127.0.0.1:*", dir_ / "server");
  const auto r =
      testing::run_tool("phasecast-render", {"--connect", server.pub(), "--frames", "1", "--size", "32x32",
                                             "--request-timeout", "0.5", "--out", path("pub")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("is this its command endpoint, --cmd, not its --pub port?")) << r.err;
}

// The scene's [view] reaches a network client through SceneInfo.view: drawn
// without --light, --exposure and --backdrop, a frame equals the one drawn
// with the view's own flags, and differs from the one drawn with the defaults.
TEST_F(NetworkRender, TheScenesViewReachesTheClient) {
  package_.attributes.light = "sun";
  package_.attributes.exposure = 1.3f;
  package_.attributes.floor = false;
  core::write_package(package_, dir_ / "plate.h5");
  testing::RealServer server(dir_ / "plate.h5", "tcp://127.0.0.1:*", "tcp://127.0.0.1:*", dir_ / "server");
  const auto first_frame = [&](const std::string& out, std::vector<std::string> flags) {
    std::vector<std::string> a = {"--connect", server.cmd(), "--frames", "1",
                                  "--size",    "96x72",      "--out",    path(out)};
    a.insert(a.end(), flags.begin(), flags.end());
    const auto r = testing::run_tool("phasecast-render", a);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return read_png(std::filesystem::directory_iterator(dir_ / out)->path());
  };
  const Image viewed = first_frame("viewed", {});
  const Image flagged = first_frame("flagged", {"--light", "sun", "--exposure", "1.3", "--backdrop", "off"});
  const Image defaults = first_frame("defaults", {"--light", "grace", "--exposure", "1", "--backdrop", "on"});
  EXPECT_EQ(max_channel_difference(viewed, flagged), 0);
  EXPECT_GT(max_channel_difference(viewed, defaults), 20);
}

// Four instances of a real server in one view, listed in any order, through
// one subscription to the scene's batches: an impulse sent to instance 2
// (the grid's right column, front row: the grid is in id order) changes the
// picture there and nowhere on the left.
TEST_F(NetworkRender, FourInstancesInOneViewAndAnImpulseChangesOnlyItsOwn) {
  core::write_package(package_, dir_ / "plate.h5");
  testing::RealServer server(dir_ / "plate.h5", "tcp://127.0.0.1:*", "tcp://127.0.0.1:*", dir_ / "server",
                             {"--instances", "4"});
  BackgroundTool tool({"--connect", server.cmd(), "--instances", "4,2,1,3", "--frames", "90", "--size",
                       "120x90", "--light", "sun", "--out", path("four")},
                      dir_ / "four.log");
  for (int i = 0; i < 6000 && files_in(dir_ / "four") < 10; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const auto impulse =
      testing::run_tool("phasecast-console", {"--connect", server.cmd(), "-e", "impulse(2, 'open')"});
  ASSERT_EQ(impulse.exit_code, 0) << impulse.err;
  ASSERT_EQ(tool.wait(), 0) << testing::read_file(dir_ / "four.log");
  const auto log = testing::read_file(dir_ / "four.log");
  EXPECT_THAT(log, HasSubstr("following 4 instances (1, 2, 3, 4) of 'plate'"));
  std::vector<std::filesystem::path> frames;
  for (const auto& e : std::filesystem::directory_iterator(dir_ / "four")) frames.push_back(e.path());
  std::sort(frames.begin(), frames.end());
  ASSERT_EQ(frames.size(), 90u);
  const Image first = read_png(frames.front()), last = read_png(frames.back());
  int left = 0, right = 0;
  for (int y = 0; y < first.height; ++y) {
    for (int x = 0; x < first.width; ++x) {
      const auto at = static_cast<std::size_t>(4 * (y * first.width + x));
      if (!std::equal(&first.rgba[at], &first.rgba[at + 3], &last.rgba[at]))
        ++(2 * x < first.width ? left : right);
    }
  }
  EXPECT_GT(right, 30) << "instance 2 turned";
  EXPECT_EQ(left, 0) << "instances 1 and 3 stood still";
}

TEST_F(NetworkRender, RendersServerFramesWithoutAPackageFile) {
  testing::PeerOptions options;
  options.irf = 4;
  testing::TestPeer peer(package_, options);
  const auto r = testing::run_tool("phasecast-render", client_args(peer, "net", 25));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("downloading the bases of 'plate'"));
  EXPECT_THAT(r.out, HasSubstr("25 frames at 96x72"));
  EXPECT_GT(peer.basis_requests(), 6u);  // small chunks: several requests per large part

  // Each PNG is named by the server's frame number and equals local
  // rendering of the same state node (same bases, same GPU code).
  core::write_package(package_, dir_ / "plate.h5");
  const auto local =
      testing::run_tool("phasecast-render", {"--package", path("plate.h5"), "--play-irf", "4", "--size",
                                             "96x72", "--light", "sun", "--out", path("local")});
  ASSERT_EQ(local.exit_code, 0) << local.err;
  int compared = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir_ / "net")) {
    const auto frame = std::stoull(entry.path().stem().string().substr(6));
    const auto local_file = dir_ / "local" / frame_file_name(frame % 90);
    EXPECT_EQ(max_channel_difference(read_png(entry.path()), read_png(local_file)), 0) << entry.path();
    ++compared;
  }
  EXPECT_EQ(compared, 25);
}

TEST_F(NetworkRender, TwoClientsOnOneInstanceRenderTheSameFrames) {
  testing::PeerOptions options;
  options.irf = 2;
  options.period_ms = 15;
  options.hold_until_downloads = 2;  // both clients see the stream from its first frame
  testing::TestPeer peer(package_, options);
  BackgroundTool a(client_args(peer, "a", 30), dir_ / "a.log");
  BackgroundTool b(client_args(peer, "b", 30), dir_ / "b.log");
  ASSERT_EQ(a.wait(), 0) << testing::read_file(dir_ / "a.log");
  ASSERT_EQ(b.wait(), 0) << testing::read_file(dir_ / "b.log");
  int common = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir_ / "a")) {
    const auto other = dir_ / "b" / entry.path().filename();
    if (!std::filesystem::exists(other)) continue;
    EXPECT_EQ(max_channel_difference(read_png(entry.path()), read_png(other)), 0) << entry.path().filename();
    ++common;
  }
  EXPECT_GE(common, 20);
}

TEST_F(NetworkRender, SequenceGapsAreCountedAndReported) {
  // Every frame with seq % 10 == 7 is dropped: wherever the client joins,
  // 30 frames span at least two single-frame gaps.
  testing::PeerOptions options;
  for (std::uint64_t s = 7; s < 5000; s += 10) options.skip_seq.insert(s);
  testing::TestPeer peer(package_, options);
  const auto r = testing::run_tool("phasecast-render", {"--connect", peer.cmd_endpoint(), "--frames", "30",
                                                        "--size", "32x32", "--out", path("gaps")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.out, m, std::regex(R"(sequence gaps (\d+) \((\d+) frames missed\))")))
      << r.out;
  EXPECT_GE(std::stoi(m[1]), 2);
  EXPECT_EQ(m[1], m[2]);
  for (const auto& entry : std::filesystem::directory_iterator(dir_ / "gaps")) {
    EXPECT_NE(std::stoull(entry.path().stem().string().substr(6)) % 10, 7u) << entry.path();
  }
}

TEST_F(NetworkRender, MalformedFramesAreSkippedAndReported) {
  testing::PeerOptions options;
  for (std::uint64_t s = 3; s < 5000; s += 10) options.corrupt_seq.insert(s);
  testing::TestPeer peer(package_, options);
  const auto r = testing::run_tool("phasecast-render", {"--connect", peer.cmd_endpoint(), "--frames", "25",
                                                        "--size", "32x32", "--out", path("bad")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      r.out, m, std::regex(R"(skipped instance 1: frame (\d+): q_u has 5 values \(expected r_u = 4\))")))
      << r.out;
  EXPECT_EQ(std::stoull(m[1]) % 10, 3u);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "bad" / frame_file_name(std::stoull(m[1]))));
  ASSERT_TRUE(std::regex_search(r.out, m, std::regex(R"(rejected frames (\d+))")));
  EXPECT_GE(std::stoi(m[1]), 2);
}

TEST_F(NetworkRender, ReconnectsAfterTheServerRestartsAndRechecksTheBases) {
  testing::PeerOptions options;
  options.period_ms = 20;  // slow enough that the client cannot finish before the peer goes away
  auto peer = std::make_unique<testing::TestPeer>(package_, options);
  const std::string cmd = peer->cmd_endpoint(), pub = peer->pub_endpoint();
  BackgroundTool tool({"--connect", cmd, "--frames", "60", "--size", "32x32", "--out", path("re"),
                       "--frame-timeout", "0.5", "--request-timeout", "0.3", "--give-up-after", "30"},
                      dir_ / "re.log");
  // Let the client render a while, then the server goes away...
  for (int i = 0; i < 3000 && files_in(dir_ / "re") < 15; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  peer.reset();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto before = files_in(dir_ / "re");
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  EXPECT_EQ(files_in(dir_ / "re"), before);  // nothing new while it is gone
  // ...and comes back on the same endpoints with another package.
  options.cmd_endpoint = cmd;
  options.pub_endpoint = pub;
  options.content_hash = 0x5678;
  peer = std::make_unique<testing::TestPeer>(package_, options);
  ASSERT_EQ(tool.wait(), 0) << testing::read_file(dir_ / "re.log");
  const auto log = testing::read_file(dir_ / "re.log");
  EXPECT_THAT(log, HasSubstr("no frames for 0.5 s; reconnecting"));
  EXPECT_THAT(log, HasSubstr("bases changed (hash 0000000000001234 -> 0000000000005678); downloading again"));
  EXPECT_THAT(log, HasSubstr("60 frames at 32x32"));
  EXPECT_THAT(log, HasSubstr("sequence gaps 0 (0 frames missed), stream restarts 0, reconnects 1"));
  EXPECT_GT(peer->basis_requests(), 0u);
}

TEST_F(NetworkRender, ReconnectWithUnchangedBasesDoesNotDownloadAgain) {
  testing::PeerOptions options;
  options.period_ms = 20;  // slow enough that the client cannot finish before the peer goes away
  auto peer = std::make_unique<testing::TestPeer>(package_, options);
  const std::string cmd = peer->cmd_endpoint(), pub = peer->pub_endpoint();
  BackgroundTool tool({"--connect", cmd, "--frames", "40", "--size", "32x32", "--out", path("same"),
                       "--frame-timeout", "0.4", "--request-timeout", "0.3", "--give-up-after", "30"},
                      dir_ / "same.log");
  for (int i = 0; i < 3000 && files_in(dir_ / "same") < 10; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  peer.reset();
  std::this_thread::sleep_for(std::chrono::milliseconds(900));
  options.cmd_endpoint = cmd;
  options.pub_endpoint = pub;
  peer = std::make_unique<testing::TestPeer>(package_, options);
  ASSERT_EQ(tool.wait(), 0) << testing::read_file(dir_ / "same.log");
  const auto log = testing::read_file(dir_ / "same.log");
  EXPECT_THAT(log, HasSubstr("reconnected; bases unchanged (hash 0000000000001234)"));
  EXPECT_EQ(peer->basis_requests(), 0u);
}

// --give-up-after bounds the time without a rendered frame in every state:
// a renderer that never exits fails these tests by running into the limit.
class GiveUp : public NetworkRender {
 protected:
  // Runs the renderer against `peer`; its exit code, stdout and stderr.
  testing::ToolResult run_until_it_gives_up(const testing::TestPeer& peer, const std::string& name) const {
    testing::ChildProcess tool("phasecast-render",
                               {"--connect", peer.cmd_endpoint(), "--size", "32x32", "--frame-timeout", "0.5",
                                "--request-timeout", "0.3", "--give-up-after", "2"},
                               dir_ / name);
    const auto code = tool.wait(std::chrono::seconds(60));
    if (!code) tool.stop(SIGKILL);
    return {code.value_or(-1), tool.out(), tool.err()};
  }
};

TEST_F(GiveUp, WhenEveryFrameIsRejected) {
  // A server whose frames never fit the bases it serves (the flood of the
  // issue: it used to print every frame and never exit).
  testing::PeerOptions options;
  for (std::uint64_t s = 0; s < 100000; ++s) options.corrupt_seq.insert(s);
  testing::TestPeer peer(package_, options);
  const auto r = run_until_it_gives_up(peer, "rejected");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_THAT(
      r.err, ::testing::MatchesRegex(
                 "phasecast-render: no frame rendered for 2 s \\(--give-up-after\\): every frame was "
                 "rejected \\(last: instance 1: frame [0-9]+: q_u has 5 values \\(expected r_u = 4\\)\\)\n"));
  // Once per event, not once per frame: only the first rejected frame is printed.
  std::size_t skipped = 0;
  for (auto at = r.out.find("skipped instance 1"); at != std::string::npos;
       at = r.out.find("skipped", at + 1))
    ++skipped;
  EXPECT_EQ(skipped, 1u) << r.out;
}

TEST_F(GiveUp, WhenNoFramesCome) {
  testing::PeerOptions options;
  options.hold_until_downloads = 1000;  // answers every request, publishes nothing
  testing::TestPeer peer(package_, options);
  const auto r = run_until_it_gives_up(peer, "silent");
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_THAT(r.err,
              ::testing::StartsWith("phasecast-render: no frame rendered for 2 s (--give-up-after): no "
                                    "frames of instance 1 came from tcp://127.0.0.1:"));
  EXPECT_THAT(r.out, HasSubstr("no frames for 0.5 s; reconnecting"));
}

TEST_F(GiveUp, WhenTheServerIsGone) {
  auto peer = std::make_unique<testing::TestPeer>(package_, testing::PeerOptions{});
  testing::ChildProcess tool("phasecast-render",
                             {"--connect", peer->cmd_endpoint(), "--size", "32x32", "--out", path("gone"),
                              "--frame-timeout", "0.5", "--request-timeout", "0.3", "--give-up-after", "2"},
                             dir_ / "gone");
  for (int i = 0; i < 3000 && files_in(dir_ / "gone") < 5; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  peer.reset();
  const auto code = tool.wait(std::chrono::seconds(60));
  if (!code) tool.stop(SIGKILL);
  EXPECT_EQ(code, std::optional<int>(1)) << tool.out();
  EXPECT_THAT(tool.err(),
              ::testing::MatchesRegex("phasecast-render: no frame rendered for 2 s \\(--give-up-after\\): "
                                      "server at tcp://127.0.0.1:[0-9]+ gone: list_scenes: no reply .*\n"));
}

TEST_F(NetworkRender, RefusedAndUnansweredRequestsGiveOneLineErrors) {
  testing::TestPeer peer(package_, {});
  auto r = testing::run_tool("phasecast-render", {"--connect", peer.cmd_endpoint(), "--create", "pot"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err,
            "phasecast-render: create_instance pot: server refused: create_instance: unknown scene 'pot' "
            "(expected one of plate)\n");
  r = testing::run_tool("phasecast-render", {"--connect", peer.cmd_endpoint(), "--instance", "9"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err,
            fmt::format("phasecast-render: --instance 9: the server at {} has no such instance (it has 1)\n",
                        peer.cmd_endpoint()));
  r = testing::run_tool("phasecast-render", {"--connect", "tcp://127.0.0.1:1", "--request-timeout", "0.1"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(r.err,
            "phasecast-render: list_scenes: no reply from tcp://127.0.0.1:1 after 3 attempts of 100 ms (is "
            "phasecast-server running?)\n");
  r = testing::run_tool("phasecast-render", {"--connect", "nonsense"});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_THAT(r.err, HasSubstr("--connect 'nonsense' is not a usable ZeroMQ endpoint"));
}

}  // namespace
}  // namespace phasecast::client
