#include "server_process.h"

#include "run_tool.h"

#include <zmq_addon.hpp>

#include <algorithm>
#include <iterator>
#include <sstream>
#include <stdexcept>

namespace phasecast::testing {
namespace {

// Finds the complete line "... listening cmd=<cmd> pub=<pub>" in `out`.
bool parse_listening(const std::string& out, std::string& cmd, std::string& pub) {
  const auto at = out.find("listening cmd=");
  if (at == std::string::npos) return false;
  const auto end = out.find('\n', at);
  if (end == std::string::npos) return false;
  std::istringstream line(out.substr(at, end - at));
  std::string word, c, p;
  while (line >> word) {
    if (word.rfind("cmd=", 0) == 0) c = word.substr(4);
    if (word.rfind("pub=", 0) == 0) p = word.substr(4);
  }
  if (c.empty() || p.empty()) return false;
  cmd = c;
  pub = p;
  return true;
}

std::vector<std::string> server_argv(const std::vector<std::string>& args) {
  std::vector<std::string> argv{tool_path("phasecast-server").string()};
  argv.insert(argv.end(), args.begin(), args.end());
  argv.insert(argv.end(), {"--cmd", "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*"});
  return argv;
}

}  // namespace

ServerProcess::ServerProcess(const std::vector<std::string>& args, const std::vector<std::string>& env)
    : process_(server_argv(args), env,
               [this](const std::string& out) { return parse_listening(out, cmd_, pub_); }) {}

namespace {

void apply_curve(zmq::socket_t& s, const ClientCurve* curve) {
  if (!curve) return;
  s.set(zmq::sockopt::curve_serverkey, curve->server_public);
  s.set(zmq::sockopt::curve_publickey, curve->client_public);
  s.set(zmq::sockopt::curve_secretkey, curve->client_secret);
}

}  // namespace

CommandClient::CommandClient(zmq::context_t& context, const std::string& endpoint, const ClientCurve* curve)
    : socket_(context, zmq::socket_type::dealer) {
  socket_.set(zmq::sockopt::linger, 0);
  apply_curve(socket_, curve);
  socket_.connect(endpoint);
}

void CommandClient::send_raw(const std::vector<std::string>& parts) {
  std::vector<zmq::const_buffer> bufs;
  for (const auto& p : parts) bufs.push_back(zmq::buffer(p));
  zmq::send_multipart(socket_, bufs);
}

std::optional<v1::Reply> CommandClient::receive(std::chrono::milliseconds timeout) {
  zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
  if (zmq::poll(&item, 1, timeout) == 0) return std::nullopt;
  std::vector<zmq::message_t> parts;
  if (!zmq::recv_multipart(socket_, std::back_inserter(parts))) return std::nullopt;
  v1::Reply reply;
  if (parts.size() != 2 || !reply.ParseFromArray(parts[1].data(), static_cast<int>(parts[1].size()))) {
    throw std::runtime_error("malformed reply from the server");
  }
  return reply;
}

v1::Reply CommandClient::call(v1::Request request, std::chrono::milliseconds timeout) {
  request.set_id(next_id_++);
  send_raw({"", request.SerializeAsString()});
  auto reply = receive(timeout);
  if (!reply) throw std::runtime_error("no reply from the server within the timeout");
  if (reply->id() != request.id()) throw std::runtime_error("reply id does not match the request");
  return *reply;
}

Subscriber::Subscriber(zmq::context_t& context, const std::string& endpoint, const std::string& topic,
                       const ClientCurve* curve)
    : socket_(context, zmq::socket_type::sub) {
  socket_.set(zmq::sockopt::linger, 0);
  apply_curve(socket_, curve);
  socket_.set(zmq::sockopt::subscribe, topic);
  socket_.connect(endpoint);
}

std::optional<v1::Frame> Subscriber::next(std::chrono::milliseconds timeout) {
  zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
  if (zmq::poll(&item, 1, timeout) == 0) return std::nullopt;
  std::vector<zmq::message_t> parts;
  if (!zmq::recv_multipart(socket_, std::back_inserter(parts))) return std::nullopt;
  v1::Frame f;
  if (parts.size() != 2 || !f.ParseFromArray(parts[1].data(), static_cast<int>(parts[1].size()))) {
    throw std::runtime_error("malformed frame message");
  }
  if (parts[0].to_string() != "inst/" + std::to_string(f.instance()) + "/") {
    throw std::runtime_error("frame topic does not name its instance");
  }
  return f;
}

v1::Request impulse_request(std::uint32_t instance, const std::string& entry) {
  v1::Request r;
  r.mutable_impulse()->set_instance(instance);
  r.mutable_impulse()->set_name(entry);
  return r;
}

v1::Request stats_request() {
  v1::Request r;
  r.mutable_stats();
  return r;
}

}  // namespace phasecast::testing
