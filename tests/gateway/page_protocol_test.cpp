// The gateway's policy without sockets: what pages may send, how frames are
// wrapped, how a slow page's queue drops frames, the per-page request rate,
// and which HTTP targets map to files.

#include "phasecast/gateway/page_protocol.h"
#include "phasecast/gateway/static_files.h"

#include <gtest/gtest.h>

namespace phasecast::gateway {
namespace {

v1::Request request_with(void (*set)(v1::Request&)) {
  v1::Request r;
  set(r);
  return r;
}

TEST(PageProtocol, PagesMayListDownloadReadStatsAndSendImpulsesOnly) {
  EXPECT_EQ(refusal(request_with([](v1::Request& r) { r.mutable_impulse()->set_name("open"); })), "");
  EXPECT_EQ(refusal(request_with([](v1::Request& r) { r.mutable_list_scenes(); })), "");
  EXPECT_EQ(refusal(request_with([](v1::Request& r) { r.mutable_list_instances(); })), "");
  EXPECT_EQ(refusal(request_with([](v1::Request& r) { r.mutable_basis(); })), "");
  EXPECT_EQ(refusal(request_with([](v1::Request& r) { r.mutable_stats(); })), "");
  EXPECT_NE(refusal(request_with([](v1::Request& r) {
              r.mutable_create_instance();
            })).find("create_instance is not allowed"),
            std::string::npos);
  EXPECT_NE(refusal(request_with([](v1::Request& r) { r.mutable_record_start(); })).find("record_start"),
            std::string::npos);
  EXPECT_NE(refusal(v1::Request()).find("no body"), std::string::npos);
}

TEST(PageProtocol, FrameEventIsTheServersFrameInsideAPageEvent) {
  v1::Frame f;
  f.set_instance(7);
  f.set_seq(300);                                                         // multi-byte varints in the frame
  for (int i = 0; i < 100; ++i) f.add_q_u(0.5f * static_cast<float>(i));  // > 127 bytes: a 2-byte length
  const std::string bytes = f.SerializeAsString();
  ASSERT_GT(bytes.size(), 127u);
  v1::PageEvent event;
  ASSERT_TRUE(event.ParseFromString(frame_event(bytes)));
  ASSERT_TRUE(event.has_frame());
  EXPECT_EQ(event.frame().SerializeAsString(), bytes);
}

TEST(PageProtocol, OtherEventsDecode) {
  v1::PageEvent e;
  ASSERT_TRUE(e.ParseFromString(error_event("bad")));
  EXPECT_EQ(e.error().error(), "bad");
  v1::Reply r;
  r.set_id(9);
  ASSERT_TRUE(e.ParseFromString(reply_event(r)));
  EXPECT_EQ(e.reply().id(), 9u);
}

TEST(PageProtocol, TopicsNameTheirInstance) {
  EXPECT_EQ(topic_instance("inst/0/"), 0u);
  EXPECT_EQ(topic_instance("inst/4294967295/"), 4294967295u);
  EXPECT_FALSE(topic_instance("inst/4294967296/"));
  EXPECT_FALSE(topic_instance("inst//"));
  EXPECT_FALSE(topic_instance("inst/1"));
  EXPECT_FALSE(topic_instance("inst/1x/"));
  EXPECT_FALSE(topic_instance("other/1/"));
}

PageOutbox::Bytes bytes(const std::string& s) {
  return std::make_shared<const std::string>(s);
}

TEST(PageOutbox, ASlowPageLosesItsOldestWaitingFramesButNoReply) {
  PageOutbox box(2);
  box.push(PageOutbox::Kind::frame, bytes("f1"));
  EXPECT_EQ(*box.start_write(), "f1");  // on the wire: never dropped
  box.push(PageOutbox::Kind::frame, bytes("f2"));
  box.push(PageOutbox::Kind::reply, bytes("r1"));
  box.push(PageOutbox::Kind::frame, bytes("f3"));
  box.push(PageOutbox::Kind::frame, bytes("f4"));  // f2 goes
  box.push(PageOutbox::Kind::frame, bytes("f5"));  // f3 goes
  EXPECT_EQ(box.dropped_frames(), 2u);
  EXPECT_EQ(box.start_write(), nullptr);  // one write at a time
  std::vector<std::string> order;
  for (;;) {
    box.finish_write();
    const auto next = box.start_write();
    if (!next) break;
    order.push_back(*next);
  }
  EXPECT_EQ(order, (std::vector<std::string>{"r1", "f4", "f5"}));
}

TEST(RequestRate, AllowsABurstThenTheRate) {
  RequestRate rate(10, 3);
  EXPECT_TRUE(rate.take(0));
  EXPECT_TRUE(rate.take(0));
  EXPECT_TRUE(rate.take(0));
  EXPECT_FALSE(rate.take(0));
  EXPECT_FALSE(rate.take(0.05));  // half a token
  EXPECT_TRUE(rate.take(0.1));
  EXPECT_TRUE(rate.take(10));
  EXPECT_TRUE(rate.take(10));
  EXPECT_TRUE(rate.take(10));
  EXPECT_FALSE(rate.take(10));  // the burst does not grow with idle time
}

TEST(StaticFiles, TargetsMapInsideTheRootOnly) {
  const std::filesystem::path root = "/srv/web";
  EXPECT_EQ(resolve_static(root, "/"), root / "index.html");
  EXPECT_EQ(resolve_static(root, "/app.js?v=2"), root / "app.js");
  EXPECT_EQ(resolve_static(root, "/assets/a-b_c.css"), root / "assets/a-b_c.css");
  for (const char* bad :
       {"/../etc/passwd", "/a/../../b", "/.env", "//etc/passwd", "/%2e%2e/x", "/a\\b", "x", "/dir/", ""}) {
    EXPECT_FALSE(resolve_static(root, bad)) << bad;
  }
  EXPECT_EQ(content_type("index.html"), "text/html; charset=utf-8");
  EXPECT_EQ(content_type("app.js"), "text/javascript; charset=utf-8");
  EXPECT_EQ(content_type("blob.bin"), "application/octet-stream");
}

}  // namespace
}  // namespace phasecast::gateway
