// Who gets in (issue 18, defect 5): loopback binds by default, CURVE keys
// from phasecast-keygen, and an allow-list that leaves unknown clients with
// nothing — neither replies nor frames.

#include "phasecast/core/curve_keys.h"
#include "phasecast/server/server.h"
#include "run_tool.h"
#include "server_process.h"
#include "synthetic_package.h"

#include <gtest/gtest.h>

#include <fstream>

namespace phasecast::testing {
namespace {

using namespace std::chrono_literals;

class ServerSecurity : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = scratch_dir(std::string("server_security_") +
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    pkg_ = (dir_ / "plate.h5").string();
    core::write_package(make_plate_package(), pkg_);
  }

  // phasecast-keygen NAME in the scratch dir; returns its pair.
  core::CurveKeyPair keygen(const std::string& name) {
    const auto r = run_tool("phasecast-keygen", {(dir_ / name).string()});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return core::read_secret_key_file(dir_ / (name + ".key"));
  }

  ClientCurve curve_for(const core::CurveKeyPair& server, const core::CurveKeyPair& client) {
    return {server.public_z85, client.public_z85, client.secret_z85};
  }

  std::filesystem::path dir_;
  std::string pkg_;
  zmq::context_t ctx_;
};

TEST(ServerDefaults, BindLoopbackUnlessToldOtherwise) {
  const server::ServerOptions o;
  EXPECT_EQ(o.cmd_endpoint.rfind("tcp://127.0.0.1:", 0), 0u) << o.cmd_endpoint;
  EXPECT_EQ(o.pub_endpoint.rfind("tcp://127.0.0.1:", 0), 0u) << o.pub_endpoint;
  const auto help = run_tool("phasecast-server", {"--help"});
  EXPECT_NE(help.out.find("tcp://127.0.0.1:5555"), std::string::npos);
}

TEST_F(ServerSecurity, KeygenWritesAPairAndNeverReplacesIt) {
  const auto keys = keygen("server");
  EXPECT_TRUE(core::is_z85_key(keys.public_z85));
  EXPECT_TRUE(core::is_z85_key(keys.secret_z85));
  EXPECT_EQ(core::read_public_key_file(dir_ / "server.pub"), keys.public_z85);
  EXPECT_EQ(std::filesystem::status(dir_ / "server.key").permissions() & std::filesystem::perms::others_read,
            std::filesystem::perms::none);
  const auto again = run_tool("phasecast-keygen", {(dir_ / "server").string()});
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.err.find("existing keys are never replaced"), std::string::npos) << again.err;
  EXPECT_EQ(core::read_secret_key_file(dir_ / "server.key").secret_z85, keys.secret_z85);
}

TEST_F(ServerSecurity, BadKeyFilesAreRefusedWithTheFileNamed) {
  keygen("server");
  std::ofstream(dir_ / "junk.key") << "public = not a key\n";
  auto r = run_tool("phasecast-server", {pkg_, "--curve-secret-key", (dir_ / "junk.key").string()});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("junk.key' line 1: expected 'public = <key>'"), std::string::npos) << r.err;
  r = run_tool("phasecast-server", {pkg_, "--curve-secret-key", (dir_ / "server.pub").string()});
  EXPECT_NE(r.err.find("is not a secret key file"), std::string::npos) << r.err;
  r = run_tool("phasecast-server", {pkg_, "--allow-clients", (dir_ / "server.pub").string()});
  EXPECT_NE(r.err.find("--allow-clients needs --curve-secret-key"), std::string::npos) << r.err;
  r = run_tool("phasecast-server", {pkg_, "--curve-secret-key", (dir_ / "server.key").string(),
                                    "--allow-clients", (dir_ / "server.key").string()});
  EXPECT_NE(r.err.find("holds a secret key"), std::string::npos) << r.err;
}

// An allowed key is served on both sockets; an unknown key and a client
// without CURVE get nothing at all.
TEST_F(ServerSecurity, OnlyAllowedKeysGetRepliesAndFrames) {
  const auto server_keys = keygen("server");
  const auto friend_keys = keygen("friend");
  const auto stranger_keys = keygen("stranger");
  ServerProcess server({pkg_, "--instances", "1", "--curve-secret-key", (dir_ / "server.key").string(),
                        "--allow-clients", (dir_ / "friend.pub").string()});

  const auto friendly = curve_for(server_keys, friend_keys);
  CommandClient ok(ctx_, server.cmd(), &friendly);
  const auto reply = ok.call(stats_request());
  EXPECT_TRUE(reply.ok()) << reply.error();
  Subscriber frames(ctx_, server.pub(), "inst/", &friendly);
  EXPECT_TRUE(frames.next());

  const auto strange = curve_for(server_keys, stranger_keys);
  CommandClient stranger(ctx_, server.cmd(), &strange);
  stranger.send_raw({"", stats_request().SerializeAsString()});
  EXPECT_FALSE(stranger.receive(1500ms)) << "an unknown key gets no reply";
  Subscriber stranger_frames(ctx_, server.pub(), "inst/", &strange);
  EXPECT_FALSE(stranger_frames.next(1500ms)) << "an unknown key gets no frames";

  CommandClient plain(ctx_, server.cmd());
  plain.send_raw({"", stats_request().SerializeAsString()});
  EXPECT_FALSE(plain.receive(1000ms)) << "a client without CURVE gets no reply";

  EXPECT_TRUE(ok.call(stats_request()).ok()) << "the allowed client is still served";
  EXPECT_EQ(server.stop(), 0);
  EXPECT_NE(server.out().find("handshakes refused"), std::string::npos);
  EXPECT_EQ(server.out().find(" 0 handshakes refused"), std::string::npos) << server.out();
}

// Instances per client are counted by CURVE key, so reconnecting does not
// reset a client's count.
TEST_F(ServerSecurity, PerClientLimitFollowsTheKeyAcrossConnections) {
  const auto server_keys = keygen("server");
  const auto friend_keys = keygen("friend");
  ServerProcess server({pkg_, "--instances", "0", "--max-instances-per-client", "1", "--curve-secret-key",
                        (dir_ / "server.key").string(), "--allow-clients", (dir_ / "friend.pub").string()});
  const auto friendly = curve_for(server_keys, friend_keys);
  v1::Request create;
  create.mutable_create_instance()->set_scene("plate");
  {
    CommandClient first(ctx_, server.cmd(), &friendly);
    EXPECT_TRUE(first.call(create).ok());
  }
  CommandClient second(ctx_, server.cmd(), &friendly);
  const auto refused = second.call(create);
  EXPECT_FALSE(refused.ok());
  EXPECT_NE(refused.error().find("see --max-instances-per-client"), std::string::npos) << refused.error();
}

}  // namespace
}  // namespace phasecast::testing
