#include "server_process.h"

#include "run_tool.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zmq_addon.hpp>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace phasecast::testing {
namespace {

// Reads what is available on `fd` within `ms`; false at end of file or timeout.
bool read_some(int fd, std::string& into, int ms) {
  pollfd p{fd, POLLIN, 0};
  if (::poll(&p, 1, ms) <= 0) return false;
  char buf[4096];
  const ssize_t n = ::read(fd, buf, sizeof buf);
  if (n <= 0) return false;
  into.append(buf, static_cast<size_t>(n));
  return true;
}

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

}  // namespace

ServerProcess::ServerProcess(const std::vector<std::string>& args, const std::vector<std::string>& env) {
  static int counter = 0;
  err_path_ = (std::filesystem::temp_directory_path() /
               ("phasecast_server_err_" + std::to_string(::getpid()) + "_" + std::to_string(counter++)))
                  .string();
  std::vector<std::string> argv_s{tool_path("phasecast-server").string()};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  argv_s.insert(argv_s.end(), {"--cmd", "tcp://127.0.0.1:*", "--pub", "tcp://127.0.0.1:*"});
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error("pipe failed");
  // Everything the child needs is made before fork: between fork and exec a
  // child of a threaded process may only make async-signal-safe calls (an
  // allocation there deadlocked under ASan).
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<std::string> env_s = env;
  for (char** e = environ; *e; ++e) {
    const std::string_view entry(*e);
    const auto name = entry.substr(0, entry.find('=') + 1);
    if (std::none_of(env.begin(), env.end(), [&](const std::string& x) { return x.starts_with(name); }))
      env_s.emplace_back(entry);
  }
  std::vector<char*> envp;
  for (auto& e : env_s) envp.push_back(e.data());
  envp.push_back(nullptr);
  pid_ = ::fork();
  if (pid_ == 0) {
    ::dup2(fds[1], 1);
    const int err = ::open(err_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(err, 2);
    ::close(fds[0]);
    ::execve(argv[0], argv.data(), envp.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  out_fd_ = fds[0];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (!parse_listening(out_, cmd_, pub_)) {
    if (std::chrono::steady_clock::now() > deadline || !read_some(out_fd_, out_, 1000)) {
      if (std::chrono::steady_clock::now() > deadline || ::waitpid(pid_, nullptr, WNOHANG) != 0) {
        const int code = stop(SIGKILL);
        throw std::runtime_error("phasecast-server did not announce its endpoints (exit " +
                                 std::to_string(code) + "): " + err());
      }
    }
  }
}

ServerProcess::~ServerProcess() {
  if (pid_ > 0) stop(SIGKILL);
  if (out_fd_ >= 0) ::close(out_fd_);
  std::filesystem::remove(err_path_);
}

int ServerProcess::stop(int signal) {
  if (pid_ <= 0) return -1;
  ::kill(pid_, signal);
  int status = 0;
  ::waitpid(pid_, &status, 0);
  pid_ = -1;
  while (read_some(out_fd_, out_, 100)) {
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string ServerProcess::out() {
  while (read_some(out_fd_, out_, 0)) {
  }
  return out_;
}

std::string ServerProcess::err() {
  std::ifstream in(err_path_);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

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
