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
#include <fstream>
#include <map>
#include <set>
#include <thread>

namespace phasecast::testing {
namespace {

using namespace std::chrono_literals;

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
  GatewayProcess gateway(server.cmd());
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
  GatewayProcess gateway(server.cmd(), {"--max-message-bytes", "1024"});
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
  std::uint64_t last = next_frame(other)->seq();
  for (int i = 0; i < 50; ++i) {
    const auto f = next_frame(other);
    ASSERT_TRUE(f) << "the other page stopped receiving frames";
    EXPECT_EQ(f->seq(), last + 1);
    last = f->seq();
  }
  EXPECT_EQ(gateway_stats(gateway)["oversized_messages"], 1);
}

TEST(Gateway, ASlowPageLosesFramesItSeesAsGapsAndNoOtherPageWaits) {
  ServerProcess server({plate_package("slow").string(), "--instances", "8", "--rate", "200"});
  GatewayProcess gateway(server.cmd(), {"--frame-queue", "16"});
  const std::vector<std::uint32_t> all = {1, 2, 3, 4, 5, 6, 7, 8};
  PageClient reader("127.0.0.1", gateway.port());
  reader.subscribe(all);
  PageClient slow("127.0.0.1", gateway.port(), 4096);
  slow.subscribe(all);
  // The slow page stops reading; its socket's small buffer fills, the
  // gateway's queue for it overflows. The reading page must see no gap.
  std::map<std::uint32_t, std::uint64_t> last;
  std::uint64_t received = 0;
  const auto take = [&](const v1::Frame& f) {
    if (last.contains(f.instance())) {
      EXPECT_EQ(f.seq(), last[f.instance()] + 1)
          << "the reading page lost frames of instance " << f.instance() << " after " << received
          << " frames; dropped " << gateway_stats(gateway).dump();
    }
    last[f.instance()] = f.seq();
    ++received;
  };
  const auto until = std::chrono::steady_clock::now() + 4s;
  while (std::chrono::steady_clock::now() < until) {
    const auto f = next_frame(reader);
    ASSERT_TRUE(f);
    take(*f);
  }
  EXPECT_GT(received, 8u * 200u * 3u) << "the reading page was slowed down";
  // The reader unsubscribes and reads to the end: no gap up to its last frame.
  reader.subscribe({});
  while (const auto e = reader.next(500ms)) {
    if (e->has_frame()) take(e->frame());
  }
  const auto dropped = gateway_stats(gateway)["frames_dropped"].get<std::uint64_t>();
  EXPECT_GT(dropped, 0u) << "the slow page lost nothing: the test did not make it slow";

  // The slow page is let go: it unsubscribes and reads what was queued.
  // Every frame it lost shows as a seq gap, and the gaps add up to what the
  // gateway dropped (the queue of 16 holds the last two ticks of all 8
  // instances, so every drop lies before a frame that arrives).
  slow.subscribe({});
  std::map<std::uint32_t, std::uint64_t> seen;
  std::uint64_t missed = 0;
  for (int n = 0; n < 100000; ++n) {
    const auto e = slow.next(2s);
    if (!e) break;
    if (!e->has_frame()) continue;
    const auto& f = e->frame();
    if (seen.contains(f.instance())) missed += f.seq() - seen[f.instance()] - 1;
    seen[f.instance()] = f.seq();
  }
  EXPECT_GT(missed, 0u);
  EXPECT_EQ(missed, gateway_stats(gateway)["frames_dropped"].get<std::uint64_t>());
}

TEST(Gateway, RequestsBeyondTheInFlightBoundWaitAndAreAllAnswered) {
  ServerProcess server({plate_package("in_flight").string()});
  GatewayProcess gateway(server.cmd(), {"--max-requests-in-flight", "4"});
  PageClient page("127.0.0.1", gateway.port());
  for (std::uint64_t id = 1; id <= 12; ++id) {  // all at once, before reading anything
    v1::PageMessage m;
    m.mutable_request()->set_id(id);
    m.mutable_request()->mutable_list_scenes();
    page.send(m);
  }
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

TEST(Gateway, ARequestTheServerNeverAnswersFailsWithinTheTimeout) {
  ServerProcess server({plate_package("timeout").string()});
  GatewayProcess gateway(server.cmd(), {"--request-timeout", "0.5"});
  PageClient page("127.0.0.1", gateway.port());
  ASSERT_TRUE(page.call(list_scenes()).ok());
  ASSERT_EQ(server.stop(SIGKILL), 128 + SIGKILL);
  const auto reply = page.call(list_scenes());
  EXPECT_FALSE(reply.ok());
  EXPECT_NE(reply.error().find("did not answer within 0.5 s"), std::string::npos) << reply.error();
  EXPECT_EQ(gateway_stats(gateway)["requests_timed_out"], 1);
}

}  // namespace
}  // namespace phasecast::testing
