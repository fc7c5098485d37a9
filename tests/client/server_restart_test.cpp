// phasecast-render and phasecast-console while a real phasecast-server
// restarts on the same ports (issue 18, defect 6): the server comes back,
// with another package or the same one, inside --frame-timeout. The renderer
// must notice, re-check the content hash, download the new bases, draw on
// with them, say so once (no line per frame), and never replace a PNG it
// wrote before the restart. Every wait is on a condition with a generous
// limit; no test asserts a duration.

#include "phasecast/client/image_io.h"
#include "phasecast/core/hash.h"
#include "phasecast/core/package.h"
#include "real_server.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <regex>
#include <thread>

namespace phasecast::client {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using testing::ChildProcess;
using ::testing::HasSubstr;
using testing::kPatience;
using testing::RealServer;
using testing::wait_until;

// PNG files in `dir` whose names start with `prefix`.
std::vector<fs::path> pngs(const fs::path& dir, const std::string& prefix) {
  std::vector<fs::path> files;
  if (!fs::exists(dir)) return files;
  for (const auto& e : fs::directory_iterator(dir)) {
    const auto name = e.path().filename().string();
    if (name.rfind(prefix, 0) == 0 && e.path().extension() == ".png") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

std::size_t occurrences(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// The largest frame number of the first session's PNGs (frame_%06d.png).
std::uint64_t last_frame_written(const fs::path& dir) {
  std::uint64_t last = 0;
  for (const auto& file : pngs(dir, "frame_")) {
    last = std::max<std::uint64_t>(last, std::stoull(file.stem().string().substr(6)));
  }
  return last;
}

// The frame count of the renderer's summary line.
std::uint64_t rendered_frames(const std::string& log) {
  std::smatch m;
  if (!std::regex_search(log, m, std::regex(R"(phasecast-render: (\d+) frames at)"))) return 0;
  return std::stoull(m[1]);
}

class ServerRestart : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(std::string("client_restart_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
    out_ = dir_ / "out";
  }

  // The first server ticks fast and the second slowly, so that the second
  // one's frame numbers stay below the first one's for many seconds: what the
  // renderer writes after the restart is its restart01_ session, however long
  // it takes to come back (frame numbers that do not go back need no session).
  std::unique_ptr<RealServer> first_server(const fs::path& package) const {
    return std::make_unique<RealServer>(package, "tcp://127.0.0.1:*", "tcp://127.0.0.1:*", dir_ / "first",
                                        std::vector<std::string>{"--rate", "60"});
  }
  std::unique_ptr<RealServer> second_server(const fs::path& package, const RealServer& first,
                                            std::vector<std::string> extra = {}) const {
    extra.insert(extra.end(), {"--rate", "10"});
    return std::make_unique<RealServer>(package, first.cmd(), first.pub(), dir_ / "second", extra);
  }

  // A renderer of instance 1 into out_ whose --frame-timeout outlasts every
  // restart here: only the reconnect itself can tell it the server changed.
  // Returns once it wrote frames up to 120 (2 s of the first server).
  std::unique_ptr<ChildProcess> start_renderer(const std::string& cmd) const {
    auto renderer = std::make_unique<ChildProcess>(
        "phasecast-render",
        std::vector<std::string>{"--connect", cmd, "--instance", "1", "--size", "32x32", "--light", "sun",
                                 "--out", out_.string(), "--frame-timeout", "300", "--give-up-after", "600"},
        dir_ / "render");
    EXPECT_TRUE(wait_until([&] { return last_frame_written(out_) >= 120; }, *renderer)) << renderer->err();
    return renderer;
  }

  // Waits for 10 frames of the second server, stops the renderer and returns its log.
  std::string render_after_restart(ChildProcess& renderer) const {
    EXPECT_TRUE(wait_until([&] { return pngs(out_, "restart01_frame_").size() >= 10; }, renderer))
        << renderer.out() << renderer.err();
    EXPECT_EQ(renderer.stop(SIGTERM), 0) << renderer.err();
    return renderer.out();
  }

  // Every PNG rendered is still there: none replaced another.
  void expect_one_file_per_rendered_frame(const std::string& log) const {
    const auto all = pngs(out_, "");
    EXPECT_EQ(all.size(), rendered_frames(log)) << log;
    EXPECT_GE(pngs(out_, "frame_").size(), 10u);
    EXPECT_EQ(pngs(out_, "restart01_frame_").size() + pngs(out_, "frame_").size(), all.size());
  }

  fs::path dir_, out_;
};

TEST_F(ServerRestart, RendererFollowsAServerThatComesBackWithAnotherPackage) {
  core::write_package(testing::make_plate_package(), dir_ / "a.h5");
  testing::PlateOptions other;
  other.rank_u = 6;  // frames of this package do not fit the first one's bases
  other.seed = 11;
  core::write_package(testing::make_plate_package(other), dir_ / "b.h5");
  const auto first = first_server(dir_ / "a.h5");
  const auto renderer = start_renderer(first->cmd());
  ASSERT_FALSE(HasFailure());

  first->stop(SIGKILL);  // a crash: nothing is said on any socket
  const auto second = second_server(dir_ / "b.h5", *first, {"--record", (dir_ / "b.phcrec").string()});
  const std::string log = render_after_restart(*renderer);
  ASSERT_FALSE(HasFailure());
  ASSERT_EQ(second->stop(SIGTERM), 0);

  EXPECT_EQ(occurrences(log, fmt::format("bases changed (hash {:016x} -> {:016x}); downloading again",
                                         core::file_content_hash(dir_ / "a.h5"),
                                         core::file_content_hash(dir_ / "b.h5"))),
            1u)
      << log;
  EXPECT_LE(occurrences(log, "skipped instance"), 1u) << log;  // one line per event, not per frame
  expect_one_file_per_rendered_frame(log);

  // The frames after the restart were drawn with the new bases: they equal
  // the recording of the second server rendered locally with its package.
  const auto local = testing::run_tool(
      "phasecast-render", {"--replay", (dir_ / "b.phcrec").string(), "--package", (dir_ / "b.h5").string(),
                           "--size", "32x32", "--light", "sun", "--out", (dir_ / "local").string()});
  ASSERT_EQ(local.exit_code, 0) << local.err;
  int compared = 0;
  for (const auto& file : pngs(out_, "restart01_frame_")) {
    const auto frame = std::stoull(file.stem().string().substr(std::string("restart01_frame_").size()));
    EXPECT_EQ(max_channel_difference(read_png(file), read_png(dir_ / "local" / frame_file_name(frame))), 0)
        << file;
    ++compared;
  }
  EXPECT_GE(compared, 10);
}

TEST_F(ServerRestart, SamePackageAgainKeepsEveryFrameFile) {
  core::write_package(testing::make_plate_package(), dir_ / "a.h5");
  const auto first = first_server(dir_ / "a.h5");
  const auto renderer = start_renderer(first->cmd());
  ASSERT_FALSE(HasFailure());

  ASSERT_EQ(first->stop(SIGTERM), 0);  // a clean restart: frame numbers start at 0 again
  const auto second = second_server(dir_ / "a.h5", *first);
  const std::string log = render_after_restart(*renderer);
  ASSERT_FALSE(HasFailure());

  EXPECT_EQ(occurrences(log, "downloading the bases"), 1u) << log;  // the hash is the same: no download
  EXPECT_THAT(log, HasSubstr(fmt::format("reconnected; bases unchanged (hash {:016x})",
                                         core::file_content_hash(dir_ / "a.h5"))));
  EXPECT_EQ(occurrences(log, "PNGs from now on: restart01_frame_"), 1u) << log;
  expect_one_file_per_rendered_frame(log);
}

// The console re-reads the scenes after a reconnect and says once that the
// packages changed; a wait across the restart ends (counted in the new frame
// numbers) instead of waiting for the old ones.
TEST_F(ServerRestart, ConsoleNoticesAServerThatComesBackWithAnotherPackage) {
  core::write_package(testing::make_plate_package(), dir_ / "a.h5");
  testing::PlateOptions other;
  other.seed = 11;
  core::write_package(testing::make_plate_package(other), dir_ / "c.h5");
  const auto first = first_server(dir_ / "a.h5");
  const auto go = dir_ / "restarted";
  const std::string script = fmt::format(
      "wait_frames(3, 1)\n"
      "print('waiting'); io.stdout:flush()\n"
      "while not io.open('{}') do wait(0.05) end\n"
      "print('reached', wait_frames(30, 1))\n"
      "show(state(1))\n",
      go.string());
  ChildProcess console("phasecast-console", {"--connect", first->cmd(), "-e", script}, dir_ / "console");
  ASSERT_TRUE(wait_until([&] { return console.out().find("waiting") != std::string::npos; }, console))
      << console.err();
  ASSERT_EQ(first->stop(SIGTERM), 0);
  const auto second = second_server(dir_ / "c.h5", *first);
  std::ofstream(go).put('\n');
  ASSERT_EQ(console.wait(kPatience), 0) << console.err();

  EXPECT_EQ(
      occurrences(console.err(), fmt::format("came back with other packages (plate: hash {:016x} -> {:016x})",
                                             core::file_content_hash(dir_ / "a.h5"),
                                             core::file_content_hash(dir_ / "c.h5"))),
      1u)
      << console.err();
  EXPECT_THAT(console.out(), HasSubstr("reached"));
}

}  // namespace
}  // namespace phasecast::client
