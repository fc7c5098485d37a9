// phasecast-console driving a real phasecast-server: impulses land in the
// frames the script names, server errors surface as Lua errors with file:line,
// exit codes, and the example scripts run unattended.

#include "phasecast/core/package.h"
#include "run_tool.h"
#include "server_process.h"
#include "source_tree.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <map>

namespace phasecast {
namespace {

using ::testing::HasSubstr;

class ConsoleSession : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch_dir(std::string("console_") +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
    core::write_package(testing::make_plate_package(), dir_ / "plate.h5");
    server_ = std::make_unique<testing::ServerProcess>(
        std::vector<std::string>{(dir_ / "plate.h5").string(), "--record-dir", dir_.string()});
  }

  testing::ToolResult console(std::vector<std::string> args) {
    args.insert(args.begin(), {"--connect", server_->cmd()});
    return testing::run_tool("phasecast-console", args);
  }

  std::filesystem::path dir_;
  std::unique_ptr<testing::ServerProcess> server_;
};

TEST_F(ConsoleSession, ImpulseLandsInTheTargetFrame) {
  zmq::context_t context;
  testing::Subscriber frames(context, server_->pub(), "inst/1/");
  ASSERT_TRUE(frames.next());  // subscribed and flowing
  const auto r = console({"-e",
                          "target = state(1).frame + 30\n"
                          "assert(impulse(1, 'open', {at = target}) == target)\n"
                          "reached = wait_frames(40, 1)\n"
                          "assert(reached >= target + 10, 'wait_frames returned early')\n"
                          "s = state(1)\n"
                          "print(target, s.entry)"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::uint64_t target = 0;
  std::string entry;
  {
    std::istringstream in(r.out);
    in >> target >> entry;
  }
  EXPECT_EQ(entry, "open");
  std::map<std::uint64_t, int> palette_at;
  while (auto f = frames.next()) {
    palette_at[f->frame()] = f->palette_index();
    if (f->frame() > target) break;
  }
  ASSERT_TRUE(palette_at.count(target - 1) && palette_at.count(target))
      << "frames around the target were not seen";
  EXPECT_EQ(palette_at[target - 1], -1);  // at rest until the target frame
  EXPECT_EQ(palette_at[target], 2);       // "open" lands exactly there
}

TEST_F(ConsoleSession, ServerErrorsAreLuaErrorsWithTheLine) {
  const auto r = console({"-e", "x = 1\nimpulse(1, 'opn')"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("phasecast-console: (command line):2: impulse(1, \"opn\"): server refused: "));
  EXPECT_THAT(r.err, HasSubstr("opn"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST_F(ConsoleSession, PcallCatchesServerErrors) {
  const auto r = console({"-e", "ok, e = pcall(impulse, 99, 'open')\nassert(not ok)\nprint(e)"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("99"));
}

TEST_F(ConsoleSession, RefusedTransitionCarriesTheServerMessage) {
  // Door rules of the fixture: "stop" is not allowed from rest.
  const auto r = console({"-e", "impulse(1, 'stop')"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("server refused"));
  EXPECT_THAT(r.err, HasSubstr("stop"));
}

TEST_F(ConsoleSession, ScriptsDriveSeveralInstances) {
  std::ofstream(dir_ / "two.lua") << "a = create('plate')\n"
                                     "b = create('plate')\n"
                                     "impulse(a, 'open')\n"
                                     "impulse(b, 2)  -- by index: open\n"
                                     "wait_frames(5, b)\n"
                                     "print(#instances(), state(a).entry, state(b).entry)\n"
                                     "destroy(a)\n"
                                     "print(#instances())\n";
  const auto r = console({(dir_ / "two.lua").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "3\topen\topen\n2\n");
}

TEST_F(ConsoleSession, ScriptErrorExitsWithFileAndLine) {
  std::ofstream(dir_ / "bad.lua") << "print('fine')\nlocal x = nil + 1\n";
  const auto r = console({(dir_ / "bad.lua").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("bad.lua:2:"));
  std::ofstream(dir_ / "syntax.lua") << "impulse(1, 'open'\n";
  const auto s = console({(dir_ / "syntax.lua").string()});
  EXPECT_EQ(s.exit_code, 1);
  EXPECT_THAT(s.err, HasSubstr("syntax.lua:"));
}

TEST_F(ConsoleSession, RecordsTheStream) {
  const auto r = console(
      {"-e", "record('session.phcrec')\nimpulse(1, 'open')\nwait_frames(10, 1)\nprint(stop_record())"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_GE(std::stoi(r.out), 10);
  EXPECT_GT(std::filesystem::file_size(dir_ / "session.phcrec"), 100u);
}

TEST_F(ConsoleSession, ExampleDoorScriptRunsUnattended) {
  ::setenv("SWINGS", "1", 1);
  const auto r = console({(phasecast::testing::scenes_dir() / "scripts/door_open_close.lua").string()});
  ::unsetenv("SWINGS");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("swing 1: open at frame"));
  EXPECT_THAT(r.out, HasSubstr("door session done"));
}

// -e chunks run before the script file, each on its own (the file is not a chunk).
TEST_F(ConsoleSession, CodeChunksRunBeforeTheScript) {
  std::ofstream(dir_ / "after.lua") << "print('script', x)\n";
  const auto r = console({"-e", "x = 1", "-e", "x = x + 1", (dir_ / "after.lua").string()});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "script\t2\n");
}

// --stats-out: the server's figures after the script, as JSON with proto field names.
TEST_F(ConsoleSession, StatsOutWritesTheServersStatsAsJson) {
  const auto path = dir_ / "stats.json";
  const auto r = console({"--stats-out", path.string(), "-e",
                          "impulse(1, 'open')\nwait_frames(5, 1)\n"
                          "local s = stats()\nprint(s.impulses_applied, s.recording)"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, "1\tfalse\n");
  std::ifstream in(path);
  const std::string json{std::istreambuf_iterator<char>(in), {}};
  EXPECT_THAT(json, HasSubstr("\"impulses_applied\": \"1\""));
  EXPECT_THAT(json, HasSubstr("\"frames_published\""));
  EXPECT_THAT(json, HasSubstr("\"max_tick_seconds\""));
}

TEST_F(ConsoleSession, ScriptOnStandardInput) {
  std::ofstream(dir_ / "stdin.lua") << "print(scenes()[1].name, #scenes()[1].palette)\n";
  const std::string cmd =
      fmt::format("{} --connect {} < {}", testing::tool_path("phasecast-console").string(), server_->cmd(),
                  (dir_ / "stdin.lua").string());
  FILE* p = ::popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  char buffer[256] = {};
  const size_t n = std::fread(buffer, 1, sizeof buffer - 1, p);
  EXPECT_EQ(::pclose(p), 0);
  EXPECT_EQ(std::string(buffer, n), "plate\t3\n");
}

// The pot and dashboard example scripts against tiny packages made by the real
// precompute (seeds chosen so that every palette entry has sampled IRFs).
struct ExampleScene {
  const char* scene;
  const char* script;
  const char* seed;
  const char* irfs;
  const char* done;
};

class ConsoleExample : public ::testing::TestWithParam<ExampleScene> {};

TEST_P(ConsoleExample, RunsUnattendedAgainstAPrecomputedPackage) {
  const auto& e = GetParam();
  const auto dir = testing::scratch_dir(std::string("console_example_") + e.scene);
  const auto package = dir / (std::string(e.scene) + ".h5");
  // The tiny plant's leaves turn about its stem: run's rest trials report it (docs/limitations.md).
  const auto pre =
      testing::run_tool("phasecast-precompute",
                        {"run", phasecast::testing::scenes_dir().string() + "/tiny/" + e.scene + ".toml",
                         "-o", package.string(), "--chains", "1", "--irfs-per-chain", e.irfs, "--seed",
                         e.seed, "--allow-rest-problems"});
  ASSERT_EQ(pre.exit_code, 0) << pre.err;
  testing::ServerProcess server({package.string()});
  ::setenv("PUSHES", "1", 1);
  const auto r = testing::run_tool(
      "phasecast-console",
      {"--connect", server.cmd(), (phasecast::testing::scenes_dir() / "scripts" / e.script).string()});
  ::unsetenv("PUSHES");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr(e.done));
}

INSTANTIATE_TEST_SUITE_P(Scripts, ConsoleExample,
                         ::testing::Values(ExampleScene{"plant_pot", "pot_left_right.lua", "5", "9",
                                                        "pot session done"},
                                           ExampleScene{"toy_dashboard", "dashboard_jolts.lua", "4", "10",
                                                        "dashboard session done"}),
                         [](const auto& p) { return std::string(p.param.scene); });

TEST(ConsoleOffline, ServerDownIsAClearError) {
  const auto r = testing::run_tool("phasecast-console", {"--connect", "tcp://127.0.0.1:9", "--timeout", "100",
                                                         "--attempts", "2", "-e", "scenes()"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("tcp://127.0.0.1:9"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST(ConsoleOffline, HelpListsTheFlags) {
  const auto r = testing::run_tool("phasecast-console", {"--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("--connect"));
  EXPECT_THAT(r.out, HasSubstr("-e"));
}

}  // namespace
}  // namespace phasecast
