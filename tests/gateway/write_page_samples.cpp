// Writes PageEvents encoded by the C++ protobuf library, with the values
// they carry as JSON, so that the page's JavaScript decoder (web/test) is
// checked against the encoder the gateway uses:
//   write_page_samples DIR  ->  DIR/{hello,frame,basis_reply}.bin, DIR/samples.json

#include "phasecast/gateway/page_protocol.h"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

namespace {

using namespace phasecast;

void write(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

std::string base64(const std::string& in) {
  static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(in[i]) << 16) |
                       (static_cast<unsigned char>(in[i + 1]) << 8) | static_cast<unsigned char>(in[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out += table[(v >> s) & 63];
  }
  if (i < in.size()) {
    unsigned v = static_cast<unsigned char>(in[i]) << 16;
    if (i + 1 < in.size()) v |= static_cast<unsigned char>(in[i + 1]) << 8;
    out += table[(v >> 18) & 63];
    out += table[(v >> 12) & 63];
    out += i + 1 < in.size() ? table[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: write_page_samples DIR\n";
    return 2;
  }
  const std::filesystem::path dir = argv[1];
  std::filesystem::create_directories(dir);
  nlohmann::json expected;

  v1::GatewayHello hello;
  hello.set_protocol_version(1);
  hello.set_server("tcp://127.0.0.1:5555");
  hello.set_max_message_bytes(65536);
  hello.set_max_requests_in_flight(4);
  hello.set_frame_queue(8);
  write(dir / "hello.bin", gateway::hello_event(hello));
  expected["hello"] = {{"protocol_version", 1},
                       {"server", hello.server()},
                       {"max_message_bytes", 65536},
                       {"max_requests_in_flight", 4},
                       {"frame_queue", 8}};

  v1::Frame f;
  f.set_instance(3);
  f.set_seq(1234567890123ull);  // above 2^32: a 64-bit varint
  f.set_frame(4321);
  f.set_sim_time(4321.0 / 60.0);
  std::vector<float> q_u = {0.5f, -1.25f, 3.0e-7f, 1.0e6f}, q_a = {-0.125f, 2.5f}, support;
  for (int i = 0; i < 12; ++i) support.push_back(i % 5 == 0 ? 1.0f : 0.1f * static_cast<float>(i));
  for (float v : q_u) f.add_q_u(v);
  for (float v : q_a) f.add_q_a(v);
  for (float v : support) f.add_support(v);
  f.set_palette_index(-1);
  f.set_irf(-1);
  f.set_irf_t(17);
  f.set_scene("cloth_door");
  write(dir / "frame.bin", gateway::frame_event(f.SerializeAsString()));
  expected["frame"] = {{"instance", 3},
                       {"seq", "1234567890123"},
                       {"frame", 4321},
                       {"sim_time", f.sim_time()},
                       {"q_u", q_u},
                       {"q_a", q_a},
                       {"support", support},
                       {"palette_index", -1},
                       {"irf", -1},
                       {"irf_t", 17},
                       {"scene", "cloth_door"}};

  v1::Reply reply;
  reply.set_id(42);
  reply.set_ok(true);
  auto* chunk = reply.mutable_basis();
  chunk->set_scene("cloth_door");
  chunk->set_part(v1::U_U);
  chunk->set_offset(1048576);
  chunk->set_total_bytes(3000000);
  std::string data;
  for (int i = 0; i < 1000; ++i) data.push_back(static_cast<char>((i * 37) & 0xff));
  chunk->set_data(data);
  chunk->set_content_hash(0xfedcba9876543210ull);
  chunk->mutable_info()->set_part(v1::U_U);
  chunk->mutable_info()->set_dtype("float32");
  chunk->mutable_info()->add_shape(1827);
  chunk->mutable_info()->add_shape(12);
  chunk->mutable_info()->set_total_bytes(3000000);
  write(dir / "basis_reply.bin", gateway::reply_event(reply));
  // Shaped as the message: field names of proto/phasecast.proto, 64-bit
  // integers as decimal strings, bytes as base64, enums by name.
  expected["basis_reply"] = {
      {"id", 42},
      {"ok", true},
      {"basis",
       {{"scene", "cloth_door"},
        {"part", "U_U"},
        {"offset", 1048576},
        {"total_bytes", 3000000},
        {"data", base64(data)},
        {"content_hash", "18364758544493064720"},
        {"info", {{"part", "U_U"}, {"dtype", "float32"}, {"shape", {1827, 12}}, {"total_bytes", 3000000}}}}}};
  std::ofstream(dir / "samples.json") << expected.dump(2) << "\n";
  return 0;
}
