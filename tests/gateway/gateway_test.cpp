// The real phasecast-gateway between a real phasecast-server and WebSocket
// pages on loopback: the frames a page receives are the server's own bytes,
// impulses from a page change the stream, and bad, oversized or slow pages
// affect only themselves.

#include "page_client.h"
#include "run_tool.h"
#include "server_process.h"
#include "synthetic_package.h"

#include "phasecast/core/package.h"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <thread>

namespace phasecast::testing {
namespace {

using namespace std::chrono_literals;

// SIGSTOP is delivered asynchronously: kill() returns while the server's
// threads may still run (and answer) for a moment, the more so on a loaded
// machine (CI once saw the "silent" server answer). Waits until every thread
// of the process shows the stopped state in /proc.
bool pause_process(pid_t pid) {
  if (::kill(pid, SIGSTOP) != 0) return false;
  const auto task = std::filesystem::path("/proc") / std::to_string(pid) / "task";
  for (int attempt = 0; attempt < 500; ++attempt) {
    bool all_stopped = true;
    for (const auto& thread : std::filesystem::directory_iterator(task)) {
      std::ifstream stat(thread.path() / "stat");
      std::string line;
      std::getline(stat, line);
      const auto close = line.rfind(')');  // the name may hold spaces and parentheses
      all_stopped &= close != std::string::npos && close + 2 < line.size() &&
                     (line[close + 2] == 'T' || line[close + 2] == 't');
    }
    if (all_stopped) return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

std::filesystem::path plate_package(const std::string& test) {
  const auto path = scratch_dir("gateway_" + test) / "plate.h5";
  core::write_package(make_plate_package(), path);
  return path;
}

// The next frame event (skipping other events), or nothing.
std::optional<v1::Frame> next_frame(PageClient& page) {
  for (int i = 0; i < 100; ++i) {
    const auto e = page.next();
    if (!e) return std::nullopt;
    if (e->has_frame()) return e->frame();
  }
  return std::nullopt;
}

nlohmann::json gateway_stats(const GatewayProcess& gateway) {
  return nlohmann::json::parse(http_get(gateway.port(), "/stats").body);
}

v1::Request list_scenes() {
  v1::Request r;
  r.mutable_list_scenes();
  return r;
}

TEST(Gateway, APageGetsHelloRepliesAndTheServersOwnFrameBytes) {
  ServerProcess server({plate_package("frames").string(), "--instances", "2", "--rate", "200"});
  // A queue no scheduling pause can fill: this page must see every frame.
  GatewayProcess gateway(server.cmd(), {"--frame-queue", "100000"});
  PageClient page("127.0.0.1", gateway.port());
  const auto hello = page.next();
  ASSERT_TRUE(hello && hello->has_hello());
  EXPECT_EQ(hello->hello().protocol_version(), 1u);
  EXPECT_EQ(hello->hello().server(), server.cmd());

  const auto scenes = page.call(list_scenes());
  ASSERT_TRUE(scenes.ok()) << scenes.error();
  ASSERT_EQ(scenes.scenes().scenes_size(), 1);
  EXPECT_EQ(scenes.scenes().scenes(0).name(), "plate");

  // A second, independent reader of the same stream: the frames through the
  // gateway must be byte for byte the ones the server published.
  zmq::context_t ctx;
  Subscriber direct(ctx, server.pub(), "inst/2/");
  std::map<std::uint64_t, std::string> published;
  page.subscribe({2});
  std::vector<v1::Frame> through_gateway;
  while (through_gateway.size() < 30) {
    const auto f = next_frame(page);
    ASSERT_TRUE(f);
    ASSERT_EQ(f->instance(), 2u) << "a frame of an instance the page does not follow";
    through_gateway.push_back(*f);
  }
  for (int i = 0; i < 200 && published.size() < 200; ++i) {
    const auto f = direct.next();
    ASSERT_TRUE(f);
    published[f->seq()] = f->SerializeAsString();
    if (f->seq() > through_gateway.back().seq() + 5) break;
  }
  int compared = 0;
  for (std::size_t i = 0; i < through_gateway.size(); ++i) {
    if (i > 0) {
      EXPECT_EQ(through_gateway[i].seq(), through_gateway[i - 1].seq() + 1) << "a gap for a reading page";
    }
    const auto it = published.find(through_gateway[i].seq());
    if (it == published.end()) continue;  // published before `direct` connected
    EXPECT_EQ(it->second, through_gateway[i].SerializeAsString());
    ++compared;
  }
  EXPECT_GT(compared, 5);
}

TEST(Gateway, AnImpulseFromAPageChangesTheServedStream) {
  ServerProcess server({plate_package("impulse").string(), "--rate", "200"});
  GatewayProcess gateway(server.cmd());
  PageClient page("127.0.0.1", gateway.port());
  page.subscribe({1});
  v1::Request open;
  open.mutable_impulse()->set_instance(1);
  open.mutable_impulse()->set_name("open");
  const auto reply = page.call(open);
  ASSERT_TRUE(reply.ok()) << reply.error();
  EXPECT_EQ(reply.impulse().palette_index(), 2u);
  bool opened = false;
  for (int i = 0; i < 400 && !opened; ++i) {
    const auto f = next_frame(page);
    ASSERT_TRUE(f);
    opened = f->palette_index() == 2 && f->frame() >= reply.impulse().at_frame();
  }
  EXPECT_TRUE(opened) << "no frame played 'open' after the page's impulse";

  v1::Request unknown;
  unknown.mutable_impulse()->set_instance(1);
  unknown.mutable_impulse()->set_name("fly");
  const auto refused = page.call(unknown);
  EXPECT_FALSE(refused.ok());
  EXPECT_NE(refused.error().find("fly"), std::string::npos) << refused.error();
}

TEST(Gateway, RequestsThatPagesMayNotSendAreRefusedByName) {
  ServerProcess server({plate_package("refused").string()});
  GatewayProcess gateway(server.cmd());
  PageClient page("127.0.0.1", gateway.port());
  v1::Request create;
  create.mutable_create_instance()->set_scene("plate");
  const auto reply = page.call(create);
  EXPECT_FALSE(reply.ok());
  EXPECT_NE(reply.error().find("create_instance is not allowed through the gateway"), std::string::npos)
      << reply.error();
  v1::Request stats;
  stats.mutable_stats();
  const auto server_stats = page.call(stats);
  ASSERT_TRUE(server_stats.ok());
  EXPECT_EQ(server_stats.stats().instances_size(), 1) << "the refused create reached the server";
}

TEST(Gateway, GarbageAndTextMessagesGetAnErrorAndThePageStays) {
  ServerProcess server({plate_package("garbage").string()});
  GatewayProcess gateway(server.cmd());
  PageClient page("127.0.0.1", gateway.port());
  ASSERT_TRUE(page.next());  // hello
  page.send_raw(std::string("\xff\xff\xff\xff\x0f garbage", 13));
  auto e = page.next();
  ASSERT_TRUE(e && e->has_error());
  EXPECT_NE(e->error().error().find("a message of 13 bytes is not a PageMessage"), std::string::npos)
      << e->error().error();
  page.send_raw("{\"request\": 1}", true);
  e = page.next();
  ASSERT_TRUE(e && e->has_error());
  EXPECT_NE(e->error().error().find("a text message"), std::string::npos);
  EXPECT_TRUE(page.call(list_scenes()).ok()) << "the page was disturbed by its own bad messages";
  EXPECT_EQ(gateway_stats(gateway)["bad_messages"], 2);
}

TEST(Gateway, AnOversizedMessageClosesOnlyItsOwnPage) {
  ServerProcess server({plate_package("oversized").string(), "--rate", "200"});
  GatewayProcess gateway(server.cmd(), {"--max-message-bytes", "1024", "--frame-queue", "100000"});
  PageClient other("127.0.0.1", gateway.port());
  other.subscribe({1});
  ASSERT_TRUE(next_frame(other));
  PageClient hostile("127.0.0.1", gateway.port());
  ASSERT_TRUE(hostile.next());  // hello
  hostile.send_raw(std::string(4096, 'x'));
  while (hostile.next()) {
  }
  EXPECT_EQ(hostile.close_code(), 1009)
      << "expected the close code 'message too big', got: " << hostile.last_error();
  const auto first = next_frame(other);
  ASSERT_TRUE(first) << "the other page stopped receiving frames";
  std::uint64_t last = first->seq();
  for (int i = 0; i < 50; ++i) {
    const auto f = next_frame(other);
    ASSERT_TRUE(f) << "the other page stopped receiving frames";
    EXPECT_EQ(f->seq(), last + 1);
    last = f->seq();
  }
  EXPECT_EQ(gateway_stats(gateway)["oversized_messages"], 1);
}

// Frames lost to seq gaps, per instance, over everything a page read.
struct GapCounter {
  std::map<std::uint32_t, std::uint64_t> last;
  std::uint64_t frames = 0, missed = 0;
  void take(const v1::Frame& f) {
    if (last.contains(f.instance())) missed += f.seq() - last[f.instance()] - 1;
    last[f.instance()] = f.seq();
    ++frames;
  }
  // Unsubscribes the page and reads what was queued for it: the reply to a
  // request sent after the unsubscribe comes behind every frame the gateway
  // still holds for the page. (A pause in the stream is no sign of its end:
  // a sender whose window was shut for seconds probes it only now and then.)
  void drain(PageClient& page) {
    page.subscribe({});
    ASSERT_TRUE(page.call(list_scenes(), [this](const v1::Frame& f) { take(f); }).ok());
  }
};

std::uint64_t dropped_for_page(const GatewayProcess& gateway, int page) {
  return gateway_stats(gateway)["open_pages"][std::to_string(page)]["frames_dropped"].get<std::uint64_t>();
}

TEST(Gateway, ASlowPageLosesFramesItSeesAsGapsAndNoOtherPageWaits) {
  ServerProcess server({plate_package("slow").string(), "--instances", "8", "--rate", "200"});
  GatewayProcess gateway(server.cmd(), {"--frame-queue", "64"});
  const std::vector<std::uint32_t> all = {1, 2, 3, 4, 5, 6, 7, 8};
  PageClient reader("127.0.0.1", gateway.port());  // page 1
  reader.subscribe(all);
  ASSERT_TRUE(reader.next());                          // hello: page 1 is registered before page 2
  PageClient slow("127.0.0.1", gateway.port(), 4096);  // page 2, stops reading
  slow.subscribe(all);
  // The slow page's small socket buffer fills and its queue overflows while
  // the reader takes every frame it can for 4 s.
  GapCounter read_by_reader, read_by_slow;
  const auto until = std::chrono::steady_clock::now() + 4s;
  while (std::chrono::steady_clock::now() < until) {
    const auto f = next_frame(reader);
    ASSERT_TRUE(f) << "the reading page stopped receiving frames";
    read_by_reader.take(*f);
  }
  read_by_reader.drain(reader);
  read_by_slow.drain(slow);
  // Every frame lost shows as a seq gap, and the gaps add up to what the
  // gateway dropped for that page (its queue holds the last 8 ticks of all
  // 8 instances, so every drop lies before a frame that arrives).
  const auto dropped_slow = dropped_for_page(gateway, 2), dropped_reader = dropped_for_page(gateway, 1);
  EXPECT_GT(dropped_slow, 0u) << "the slow page lost nothing: the test did not make it slow";
  EXPECT_EQ(read_by_slow.missed, dropped_slow);
  EXPECT_EQ(read_by_reader.missed, dropped_reader);
  // The reader was not held up by the slow page: it took at least a second's
  // worth of frames and lost far fewer than the slow page (none, unless this
  // machine paused the gateway for longer than 64 frames).
  EXPECT_GT(read_by_reader.frames, 8u * 200u);
  EXPECT_LT(4 * dropped_reader, dropped_slow);
}

TEST(Gateway, RequestsBeyondTheInFlightBoundWaitUnreadAndAreAllAnswered) {
  ServerProcess server({plate_package("in_flight").string()});
  GatewayProcess gateway(server.cmd(), {"--max-requests-in-flight", "4"});
  PageClient page("127.0.0.1", gateway.port());
  ASSERT_TRUE(page.next());                     // hello, written: it no longer counts
  ASSERT_TRUE(pause_process(server.pid()));     // a server that does not answer for now
  for (std::uint64_t id = 1; id <= 12; ++id) {  // all at once, before reading anything
    v1::PageMessage m;
    m.mutable_request()->set_id(id);
    m.mutable_request()->mutable_list_scenes();
    page.send(m);
  }
  // The gateway forwards the first 4 however slowly this machine runs; then it
  // has had half a second to read past the bound, if it would.
  const auto forwarded = [&] { return gateway_stats(gateway)["requests_forwarded"].get<int>(); };
  for (int i = 0; i < 1000 && forwarded() < 4; ++i) std::this_thread::sleep_for(10ms);
  std::this_thread::sleep_for(500ms);
  EXPECT_EQ(forwarded(), 4) << "the gateway read past the in-flight bound";
  ASSERT_EQ(::kill(server.pid(), SIGCONT), 0);
  std::set<std::uint64_t> answered;
  while (answered.size() < 12) {
    const auto e = page.next();
    ASSERT_TRUE(e) << "the page lost its connection after " << answered.size()
                   << " replies: " << page.last_error();
    if (!e->has_reply()) continue;
    EXPECT_TRUE(e->reply().ok()) << e->reply().error();
    answered.insert(e->reply().id());
  }
  EXPECT_EQ(*answered.begin(), 1u);
  EXPECT_EQ(*answered.rbegin(), 12u);
}

TEST(Gateway, ServesThePagesFilesAndNothingOutsideTheirFolder) {
  ServerProcess server({plate_package("http").string()});
  const auto root = scratch_dir("gateway_http_root");
  std::ofstream(root / "index.html") << "<!doctype html><title>phasecast</title>";
  std::ofstream(root.parent_path() / "secret.txt") << "not for pages";
  GatewayProcess gateway(server.cmd(), {"--web-root", root.string()});
  const auto index = http_get(gateway.port(), "/");
  EXPECT_EQ(index.status, 200);
  EXPECT_EQ(index.body, "<!doctype html><title>phasecast</title>");
  EXPECT_EQ(index.content_type, "text/html; charset=utf-8");
  EXPECT_EQ(http_get(gateway.port(), "/../secret.txt").status, 400);
  EXPECT_EQ(http_get(gateway.port(), "/%2e%2e/secret.txt").status, 400);
  EXPECT_EQ(http_get(gateway.port(), "/missing.js").status, 404);
  std::filesystem::create_directory(root / "assets");
  EXPECT_EQ(http_get(gateway.port(), "/assets").status, 404) << "a directory is no file";
  const auto head = http_get(gateway.port(), "/", {}, true);
  EXPECT_EQ(head.status, 200);
  EXPECT_EQ(head.content_length, std::to_string(index.body.size()));
  EXPECT_EQ(http_get(gateway.port(), "/").body, index.body) << "the gateway stopped serving after a HEAD";
  // Another site's page may not open the WebSocket (no same-origin rule for
  // WebSockets); the gateway's own page may.
  const std::vector<std::pair<std::string, std::string>> upgrade = {
      {"Connection", "Upgrade"},
      {"Upgrade", "websocket"},
      {"Sec-WebSocket-Version", "13"},
      {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="}};
  auto foreign = upgrade;
  foreign.emplace_back("Origin", "http://evil.example");
  const auto refused = http_get(gateway.port(), "/ws", foreign);
  EXPECT_EQ(refused.status, 403);
  EXPECT_NE(refused.body.find("http://evil.example"), std::string::npos) << refused.body;
  auto own = upgrade;
  own.emplace_back("Origin", "http://127.0.0.1:" + std::to_string(gateway.port()));
  EXPECT_EQ(http_get(gateway.port(), "/ws", own).status, 101);
  const auto stats = gateway_stats(gateway);
  EXPECT_EQ(stats["pages"], 0);
}

TEST(Gateway, WithoutAServerItExitsWithOneLineNamingIt) {
  const auto r = run_tool("phasecast-gateway", {"--connect", "tcp://127.0.0.1:9", "--listen", "127.0.0.1:0",
                                                "--connect-timeout", "0.3"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("tcp://127.0.0.1:9"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
}

TEST(Gateway, ASilentServerTimesRequestsOutAndAGoneOneRefusesThemAtOnce) {
  ServerProcess server({plate_package("timeout").string()});
  GatewayProcess gateway(server.cmd(), {"--request-timeout", "0.5"});
  PageClient page("127.0.0.1", gateway.port());
  ASSERT_TRUE(page.call(list_scenes()).ok());
  ASSERT_TRUE(pause_process(server.pid()));  // connected, but silent
  auto reply = page.call(list_scenes());
  EXPECT_FALSE(reply.ok());
  EXPECT_NE(reply.error().find("did not answer within 0.5 s"), std::string::npos) << reply.error();
  EXPECT_EQ(gateway_stats(gateway)["requests_timed_out"], 1);
  // Gone: nothing is queued for a server that may come back later.
  ASSERT_EQ(server.stop(SIGKILL), 128 + SIGKILL);
  // Once ZeroMQ has seen the connection close (a request sent before that
  // times out instead), requests are refused at once.
  for (int attempt = 0; attempt < 20; ++attempt) {
    reply = page.call(list_scenes());
    if (reply.error().find("did not answer") == std::string::npos) break;
  }
  EXPECT_FALSE(reply.ok());
  EXPECT_NE(reply.error().find("is not connected; the request was not sent"), std::string::npos)
      << reply.error();
}

}  // namespace
}  // namespace phasecast::testing
