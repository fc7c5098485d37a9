// The real phasecast-server process on loopback: frames to subscribers,
// impulses from other clients, listings, basis download, instances, stats,
// recordings with --replay-check, and clean shutdown.

#include "phasecast/core/basis.h"
#include "phasecast/core/hash.h"
#include "phasecast/core/package.h"
#include "run_tool.h"
#include "server_process.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>
#include <zmq_addon.hpp>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

namespace phasecast::testing {
namespace {

using namespace std::chrono_literals;

std::filesystem::path fixture(const std::string& test) {
  const auto dir = scratch_dir("server_it_" + test);
  const auto path = dir / "plate.h5";
  core::write_package(make_plate_package(), path);
  return path;
}

// The first frame of `instance` whose palette entry is `entry`.
v1::Frame frame_with_entry(Subscriber& sub, std::uint32_t instance, int entry) {
  for (int i = 0; i < 2000; ++i) {
    auto f = sub.next();
    if (!f) break;
    if (f->instance() == instance && f->palette_index() == entry) return *f;
  }
  throw std::runtime_error("no frame with the entry arrived");
}

TEST(ServerProcessTest, SubscriberDecodesConsecutiveFramesOfEveryInstance) {
  const auto pkg = fixture("stream");
  ServerProcess server({pkg.string(), "--instances", "2", "--rate", "200"});
  zmq::context_t ctx;
  Subscriber sub(ctx, server.pub());
  std::map<std::uint32_t, std::uint64_t> last_seq;
  for (int i = 0; i < 40; ++i) {
    const auto f = sub.next();
    ASSERT_TRUE(f);
    EXPECT_EQ(f->scene(), "plate");
    EXPECT_EQ(f->q_u_size(), 4);
    EXPECT_EQ(f->support_size(), 12);
    EXPECT_EQ(f->seq(), f->frame());
    EXPECT_DOUBLE_EQ(f->sim_time(), static_cast<double>(f->frame()) / 60.0);
    if (last_seq.count(f->instance())) {
      EXPECT_EQ(f->seq(), last_seq[f->instance()] + 1);
    }
    last_seq[f->instance()] = f->seq();
  }
  EXPECT_EQ(last_seq.size(), 2u);
  EXPECT_EQ(server.stop(SIGINT), 0);
  EXPECT_NE(server.out().find("phasecast-server: stopped after"), std::string::npos);
}

// The next message on `sub` as [topic][FrameBatch], or nothing within 10 s.
std::optional<std::pair<std::string, v1::FrameBatch>> next_batch(zmq::socket_t& sub) {
  zmq::pollitem_t item{sub.handle(), 0, ZMQ_POLLIN, 0};
  if (zmq::poll(&item, 1, 10s) == 0) return std::nullopt;
  std::vector<zmq::message_t> parts;
  if (!zmq::recv_multipart(sub, std::back_inserter(parts)) || parts.size() != 2) return std::nullopt;
  v1::FrameBatch b;
  if (!b.ParseFromArray(parts[1].data(), static_cast<int>(parts[1].size()))) return std::nullopt;
  return std::pair{parts[0].to_string(), b};
}

// One subscription follows every instance of a scene through one message
// per tick, and the server builds Frame messages only once someone wants them.
TEST(ServerProcessTest, SceneBatchesFollowEveryInstanceAndFramesOnlyWhenWanted) {
  const auto pkg = fixture("batches");
  ServerProcess server({pkg.string(), "--instances", "3", "--rate", "200"});
  zmq::context_t ctx;
  zmq::socket_t sub(ctx, zmq::socket_type::sub);
  sub.set(zmq::sockopt::subscribe, "scene/plate/");
  sub.connect(server.pub());
  std::optional<std::uint64_t> last_tick;
  for (int i = 0; i < 20; ++i) {
    const auto b = next_batch(sub);
    ASSERT_TRUE(b);
    EXPECT_EQ(b->first, "scene/plate/0/");
    ASSERT_EQ(b->second.instance_size(), 3);
    EXPECT_EQ(b->second.instance(2), 3u);
    EXPECT_EQ(b->second.q_u_size(), 3 * 4);
    if (last_tick) {
      EXPECT_EQ(b->second.tick(), *last_tick + 1) << "one batch per tick, none lost";
    }
    last_tick = b->second.tick();
  }
  CommandClient client(ctx, server.cmd());
  EXPECT_EQ(client.call(stats_request()).stats().frames_published(), 0u) << "nobody follows one instance";
  Subscriber one(ctx, server.pub(), "inst/2/");
  const auto f = one.next();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->instance(), 2u);
  const auto stats = client.call(stats_request()).stats();
  EXPECT_GT(stats.frames_published(), 0u);
  EXPECT_LT(stats.frames_published(), stats.batches_published()) << "only instance 2's Frames";
}

TEST(ServerProcessTest, ImpulseFromAnotherClientChangesTheStreamWithinOneTick) {
  const auto pkg = fixture("impulse");
  ServerProcess server({pkg.string(), "--rate", "100"});
  zmq::context_t ctx;
  Subscriber sub(ctx, server.pub(), "inst/1/");
  const auto first = sub.next();
  ASSERT_TRUE(first);
  CommandClient client(ctx, server.cmd());
  const auto before = client.call(stats_request()).stats().instances(0).frame();
  const auto reply = client.call(impulse_request(1, "open"));
  ASSERT_TRUE(reply.ok()) << reply.error();
  EXPECT_EQ(reply.impulse().palette_index(), 2u);
  const auto at = reply.impulse().at_frame();
  // Without at_frame the impulse lands in the instance's next frame when it is handled.
  EXPECT_GE(at, before);
  EXPECT_LT(at, before + 100) << "landed more than a second after the previous request";
  v1::Frame prev = *first;
  v1::Frame f;
  for (int i = 0; i < 1000; ++i) {
    const auto next_frame = sub.next();
    ASSERT_TRUE(next_frame);
    if (next_frame->frame() == at) {
      f = *next_frame;
      break;
    }
    prev = *next_frame;
  }
  EXPECT_EQ(prev.frame() + 1, at);
  EXPECT_EQ(prev.palette_index(), -1) << "the frame before the impulse is unchanged";
  EXPECT_EQ(f.frame(), at);
  EXPECT_EQ(f.palette_index(), 2);
  EXPECT_EQ(f.irf_t(), 0u);
  const auto next = sub.next();
  ASSERT_TRUE(next);
  EXPECT_EQ(next->irf_t(), 1u);
}

// The reply to list_scenes, from a fresh DEALER.
v1::Reply list_scenes(const ServerProcess& server) {
  zmq::context_t ctx;
  CommandClient client(ctx, server.cmd());
  v1::Request r;
  r.mutable_list_scenes();
  return client.call(r);
}

// Behind NAT or remapped ports clients are told the public frame endpoint.
TEST(ServerProcessTest, AdvertisedPubEndpointIsAnnounced) {
  ServerProcess server({fixture("advertise").string(), "--advertise-pub", "tcp://frames.example:7556"});
  const auto reply = list_scenes(server);
  ASSERT_TRUE(reply.ok()) << reply.error();
  EXPECT_EQ(reply.scenes().pub_endpoint(), "tcp://frames.example:7556");
}

TEST(ServerProcessTest, ListScenesDescribesThePaletteAndBasisParts) {
  const auto pkg = fixture("list");
  ServerProcess server({pkg.string()});
  const auto reply = list_scenes(server);
  ASSERT_TRUE(reply.ok()) << reply.error();
  const auto& list = reply.scenes();
  EXPECT_EQ(list.pub_endpoint(), server.pub());
  ASSERT_EQ(list.scenes_size(), 1);
  const auto& s = list.scenes(0);
  EXPECT_EQ(s.name(), "plate");
  EXPECT_EQ(s.package(), "plate.h5");
  EXPECT_EQ(s.content_hash(), core::file_content_hash(pkg));
  EXPECT_EQ(s.rank_u(), 4u);
  ASSERT_EQ(s.palette_size(), 3);
  EXPECT_EQ(s.palette(2).name(), "open");
  EXPECT_EQ(s.palette(2).on_end(), 1);
  EXPECT_TRUE(s.palette(2).kinematics().rotational());
  EXPECT_EQ(std::vector<std::uint32_t>(s.allowed_from_rest().begin(), s.allowed_from_rest().end()),
            (std::vector<std::uint32_t>{0, 2}));
  EXPECT_EQ(s.parts_size(), 8);
  EXPECT_EQ(s.camera_size(), 10);
}

TEST(ServerProcessTest, ChunkedBasisDownloadReassemblesEveryPartExactly) {
  const auto pkg_path = fixture("basis");
  const auto pkg = core::read_package(pkg_path);
  ServerProcess server({pkg_path.string()});
  zmq::context_t ctx;
  CommandClient client(ctx, server.cmd());
  for (const auto& part : core::basis_parts(pkg)) {
    std::string bytes;
    std::uint64_t total = 1;
    int chunks = 0;
    while (bytes.size() < total) {
      v1::Request r;
      auto& b = *r.mutable_basis();
      b.set_scene("plate");
      b.set_part(static_cast<v1::BasisPart>(part.id));
      b.set_offset(bytes.size());
      b.set_max_bytes(1000);
      const auto reply = client.call(r);
      ASSERT_TRUE(reply.ok()) << reply.error();
      ASSERT_EQ(reply.basis().offset(), bytes.size());
      ASSERT_LE(reply.basis().data().size(), 1000u);
      EXPECT_EQ(reply.basis().content_hash(), core::file_content_hash(pkg_path));
      EXPECT_EQ(reply.basis().info().dtype(), part.dtype);
      total = reply.basis().total_bytes();
      if (total == 0) break;
      bytes += reply.basis().data();
      ++chunks;
    }
    EXPECT_EQ(bytes.size(), part.bytes.size()) << part.name;
    EXPECT_EQ(0, std::memcmp(bytes.data(), part.bytes.data(), part.bytes.size())) << part.name;
    EXPECT_EQ(chunks, static_cast<int>((part.bytes.size() + 999) / 1000)) << part.name;
  }
}

TEST(ServerProcessTest, InstancesAreCreatedListedAndDestroyed) {
  const auto pkg = fixture("instances");
  ServerProcess server({pkg.string(), "--instances", "0", "--rate", "200"});
  zmq::context_t ctx;
  CommandClient client(ctx, server.cmd());
  v1::Request create;
  create.mutable_create_instance()->set_scene("plate");
  const auto created = client.call(create);
  ASSERT_TRUE(created.ok()) << created.error();
  EXPECT_EQ(created.created().instance(), 1u);
  EXPECT_EQ(created.created().topic(), "inst/1/");
  Subscriber sub(ctx, server.pub(), "inst/1/");
  ASSERT_TRUE(sub.next());
  v1::Request list;
  list.mutable_list_instances();
  const auto listed = client.call(list);
  ASSERT_EQ(listed.instances().instances_size(), 1);
  EXPECT_EQ(listed.instances().instances(0).scene(), "plate");
  v1::Request destroy;
  destroy.mutable_destroy_instance()->set_instance(1);
  ASSERT_TRUE(client.call(destroy).ok());
  while (sub.next(300ms)) {
  }  // frames already in flight
  EXPECT_FALSE(sub.next(300ms)) << "a destroyed instance's topic stops";
  const auto again = client.call(destroy);
  EXPECT_FALSE(again.ok());
  EXPECT_EQ(again.error(), "destroy_instance: unknown instance 1 (expected one of the 0 existing instances)");
}

TEST(ServerProcessTest, SeveralConcurrentClientsAllGetTheirReplies) {
  const auto pkg = fixture("concurrent");
  ServerProcess server({pkg.string(), "--instances", "4"});
  zmq::context_t ctx;
  std::vector<std::thread> clients;
  std::atomic<int> good{0};
  for (int c = 0; c < 4; ++c) {
    clients.emplace_back([&, c] {
      CommandClient client(ctx, server.cmd());
      const auto imp = client.call(impulse_request(static_cast<std::uint32_t>(c + 1), "open"));
      if (imp.ok() && imp.impulse().instance() == static_cast<std::uint32_t>(c + 1)) ++good;
      for (int i = 0; i < 25; ++i) {
        if (client.call(stats_request()).ok()) ++good;
      }
    });
  }
  for (auto& t : clients) t.join();
  EXPECT_EQ(good.load(), 4 * 26);
  CommandClient client(ctx, server.cmd());
  const auto stats = client.call(stats_request()).stats();
  EXPECT_EQ(stats.instances_size(), 4);
  EXPECT_GE(stats.requests(), 4u * 26u);
  EXPECT_EQ(stats.bad_requests(), 0u);
}

TEST(ServerProcessTest, RecordedSessionReplaysBitForBit) {
  const auto pkg = fixture("record");
  const auto rec = pkg.parent_path() / "session.phcrec";
  ServerProcess server({pkg.string(), "--rate", "200", "--record", rec.string(), "--instances", "2"});
  zmq::context_t ctx;
  CommandClient client(ctx, server.cmd());
  Subscriber sub(ctx, server.pub(), "inst/1/");
  ASSERT_TRUE(client.call(impulse_request(1, "open")).ok());
  frame_with_entry(sub, 1, 2);
  ASSERT_TRUE(client.call(impulse_request(1, "stop")).ok());
  ASSERT_TRUE(client.call(impulse_request(2, "open")).ok());
  v1::Request create;
  create.mutable_create_instance()->set_scene("plate");
  ASSERT_TRUE(client.call(create).ok());
  ASSERT_TRUE(client.call(impulse_request(3, "open")).ok());
  frame_with_entry(sub, 1, 1);
  for (int i = 0; i < 20; ++i) sub.next();
  ASSERT_EQ(server.stop(SIGTERM), 0);
  const auto check = run_tool("phasecast-server", {pkg.string(), "--replay-check", rec.string()});
  EXPECT_EQ(check.exit_code, 0) << check.err;
  EXPECT_NE(check.out.find("instances with 4 impulses reproduced bit for bit"), std::string::npos)
      << check.out;

  // The replay is not vacuous: a different package (other IRF phases) fails it.
  const auto other = pkg.parent_path() / "other.h5";
  PlateOptions o;
  o.seed = 99;
  core::write_package(make_plate_package(o), other);
  const auto bad = run_tool("phasecast-server", {other.string(), "--replay-check", rec.string()});
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(
      bad.err.find("phasecast-server: replay-check: scene 'plate' was recorded from plate.h5 with hash"),
      std::string::npos)
      << bad.err;
}

TEST(ServerProcessTest, RecordStartAndStopByRequestStayInsideTheRecordDir) {
  const auto pkg = fixture("record_req");
  const auto dir = pkg.parent_path();
  ServerProcess server({pkg.string(), "--rate", "200", "--record-dir", dir.string()});
  zmq::context_t ctx;
  CommandClient client(ctx, server.cmd());
  v1::Request start;
  start.mutable_record_start()->set_path("../escape.phcrec");
  auto reply = client.call(start);
  EXPECT_FALSE(reply.ok());
  EXPECT_EQ(
      reply.error(),
      "record_start: path '../escape.phcrec' (expected a plain file name ending in .phcrec; recordings go to "
      "the server's --record-dir)");
  start.mutable_record_start()->set_path("req.phcrec");
  reply = client.call(start);
  ASSERT_TRUE(reply.ok()) << reply.error();
  EXPECT_TRUE(reply.record().recording());
  reply = client.call(start);
  EXPECT_FALSE(reply.ok());
  EXPECT_NE(reply.error().find("record_start: already recording to"), std::string::npos) << reply.error();
  ASSERT_TRUE(client.call(impulse_request(1, "open")).ok());
  std::this_thread::sleep_for(200ms);
  v1::Request stop;
  stop.mutable_record_stop();
  reply = client.call(stop);
  ASSERT_TRUE(reply.ok()) << reply.error();
  EXPECT_GT(reply.record().frames_written(), 0u);
  reply = client.call(stop);
  EXPECT_EQ(reply.error(), "record_stop: not recording (expected a record_start first)");
  const auto check =
      run_tool("phasecast-server", {pkg.string(), "--replay-check", (dir / "req.phcrec").string()});
  EXPECT_EQ(check.exit_code, 0) << check.err;
}

TEST(ServerProcessTest, StartFailsWithOneClearLine) {
  const auto dir = scratch_dir("server_start_errors");
  const auto junk = dir / "junk.h5";
  std::ofstream(junk) << "not an HDF5 file";
  auto r = run_tool("phasecast-server",
                    {junk.string(), "--cmd", "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(r.err.rfind("phasecast-server: ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find("junk.h5"), std::string::npos) << r.err;

  r = run_tool("phasecast-server", {(dir / "missing.h5").string()});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("missing.h5"), std::string::npos) << r.err;

  const auto pkg = dir / "plate.h5";
  core::write_package(make_plate_package(), pkg);
  r = run_tool("phasecast-server",
               {pkg.string(), pkg.string(), "--cmd", "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(
      r.err,
      "phasecast-server: scene 'plate' of plate.h5 is already loaded from plate.h5 (expected unique scene "
      "names)\n");
  r = run_tool("phasecast-server", {pkg.string(), "--cmd", "bogus://x", "--pub", "tcp://127.0.0.1:*"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err.rfind("phasecast-server: cannot bind --cmd 'bogus://x': ", 0), 0u) << r.err;
}

}  // namespace
}  // namespace phasecast::testing
