// The wire messages survive serialization, and unknown/garbage bytes are
// rejected by the parser rather than crashing it.

#include "phasecast/proto/phasecast.pb.h"

#include <gtest/gtest.h>

namespace phasecast {
namespace {

TEST(Proto, FrameRoundTrip) {
  v1::Frame f;
  f.set_instance(3);
  f.set_seq(41);
  f.set_frame(1234);
  f.set_sim_time(1234.0 / 60.0);
  for (int i = 0; i < 12; ++i) f.add_q_u(0.1f * static_cast<float>(i));
  for (int i = 0; i < 7; ++i) f.add_q_a(-0.5f * static_cast<float>(i));
  for (int i = 0; i < 12; ++i) f.add_support(i % 4 == 0 ? 1.0f : 0.0f);
  f.set_palette_index(2);
  f.set_irf(17);
  f.set_irf_t(55);
  f.set_scene("plate");
  const std::string bytes = f.SerializeAsString();
  v1::Frame g;
  ASSERT_TRUE(g.ParseFromString(bytes));
  EXPECT_EQ(g.SerializeAsString(), bytes);
  EXPECT_EQ(g.q_u_size(), 12);
  EXPECT_FLOAT_EQ(g.q_u(11), 1.1f);
  EXPECT_EQ(g.irf_t(), 55u);
  // Packed floats: the reduced state costs 4 bytes per coordinate plus small tags.
  EXPECT_LT(bytes.size(), 4u * (12 + 7 + 12) + 40u);
}

TEST(Proto, RequestOneofAndOptionalFrame) {
  v1::Request r;
  r.set_id(9);
  r.mutable_impulse()->set_instance(1);
  r.mutable_impulse()->set_name("open");
  v1::Request parsed;
  ASSERT_TRUE(parsed.ParseFromString(r.SerializeAsString()));
  ASSERT_EQ(parsed.body_case(), v1::Request::kImpulse);
  EXPECT_EQ(parsed.impulse().entry_case(), v1::Impulse::kName);
  EXPECT_FALSE(parsed.impulse().has_at_frame());
  parsed.mutable_impulse()->set_at_frame(0);
  EXPECT_TRUE(parsed.impulse().has_at_frame());  // frame 0 is a real target, not "unset"
  parsed.mutable_impulse()->set_index(2);
  EXPECT_EQ(parsed.impulse().entry_case(), v1::Impulse::kIndex);
}

TEST(Proto, ReplyCarriesErrorOrResult) {
  v1::Reply ok;
  ok.set_id(5);
  ok.set_ok(true);
  auto* chunk = ok.mutable_basis();
  chunk->set_part(v1::U_U);
  chunk->set_offset(65536);
  chunk->set_total_bytes(1 << 20);
  chunk->set_data(std::string(1024, '\x01'));
  v1::Reply parsed;
  ASSERT_TRUE(parsed.ParseFromString(ok.SerializeAsString()));
  EXPECT_EQ(parsed.result_case(), v1::Reply::kBasis);
  EXPECT_EQ(parsed.basis().data().size(), 1024u);

  v1::Reply err;
  err.set_id(6);
  err.set_error("impulse: unknown palette entry 'opn' for instance 1 (expected close, stop, open)");
  ASSERT_TRUE(parsed.ParseFromString(err.SerializeAsString()));
  EXPECT_FALSE(parsed.ok());
  EXPECT_EQ(parsed.result_case(), v1::Reply::RESULT_NOT_SET);
}

TEST(Proto, GarbageIsRejectedNotCrashing) {
  v1::Request r;
  EXPECT_FALSE(r.ParseFromString(std::string("\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\x01", 11)));
  EXPECT_FALSE(r.ParseFromString(std::string("\x0a\x7f", 2)));  // length past the end
}

TEST(Proto, RecordEntryCarriesFramesAndImpulses) {
  v1::RecordEntry e;
  e.mutable_header()->set_format_version(1);
  auto* s = e.mutable_header()->add_scenes();
  s->set_scene("plate");
  s->set_content_hash(0x1234abcdull);
  v1::RecordEntry parsed;
  ASSERT_TRUE(parsed.ParseFromString(e.SerializeAsString()));
  EXPECT_EQ(parsed.entry_case(), v1::RecordEntry::kHeader);
  EXPECT_EQ(parsed.header().scenes(0).content_hash(), 0x1234abcdull);
}

}  // namespace
}  // namespace phasecast
