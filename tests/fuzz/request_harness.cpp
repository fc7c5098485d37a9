#include "request_harness.h"

#include "phasecast/core/proto_oneof.h"

#include <fmt/format.h>
#include <google/protobuf/descriptor.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <typeinfo>

namespace phasecast::fuzz {
namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;

// The Reply.result each Request.body is answered with (docs/protocol.md).
// A kind missing here (added after this table) is only checked generically.
const std::map<std::string, std::string>& result_of_body() {
  static const std::map<std::string, std::string> table = {
      {"impulse", "impulse"},         {"list_scenes", "scenes"},         {"list_instances", "instances"},
      {"create_instance", "created"}, {"destroy_instance", "destroyed"}, {"basis", "basis"},
      {"record_start", "record"},     {"record_stop", "record"},         {"stats", "stats"},
  };
  return table;
}

std::string check_basis(const v1::BasisRequest& request, const v1::BasisChunk& chunk) {
  if (chunk.offset() != request.offset() || chunk.data().size() > server::kMaxChunkBytes ||
      chunk.offset() + chunk.data().size() > chunk.total_bytes()) {
    return fmt::format(
        "basis chunk at {} of {} bytes for a request at {} (expected at most {} bytes within {})",
        chunk.offset(), chunk.data().size(), request.offset(), server::kMaxChunkBytes, chunk.total_bytes());
  }
  return "";
}

std::string check_error(const std::string& body, const v1::Reply& reply) {
  const std::string prefix = (body.empty() ? "request" : body) + ": ";
  if (!reply.error().starts_with(prefix)) {
    return fmt::format("error '{}' (expected it to start with '{}')", reply.error(), prefix);
  }
  return "";
}

RequestVerdict thrown(std::string what) {
  RequestVerdict v;
  v.violation = std::move(what);
  v.kind = "exception";
  return v;
}

bool finite(const google::protobuf::RepeatedField<float>& values) {
  return std::all_of(values.begin(), values.end(), [](float v) { return std::isfinite(v); });
}

void varint(Bytes& out, std::uint64_t v) {
  while (v >= 0x80) {
    out += static_cast<char>((v & 0x7f) | 0x80);
    v >>= 7;
  }
  out += static_cast<char>(v);
}

bool valid_utf8(std::string_view s) {
  for (std::size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    const std::size_t n = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : (c >> 3) == 30 ? 4 : 0;
    if (n == 0 || i + n > s.size()) return false;
    for (std::size_t k = 1; k < n; ++k) {
      if ((static_cast<unsigned char>(s[i + k]) >> 6) != 2) return false;
    }
    i += n;
  }
  return true;
}

}  // namespace

// ---- the service under test -------------------------------------------------------

RequestHarness::RequestHarness(const std::vector<std::filesystem::path>& packages,
                               const std::filesystem::path& work_dir)
    : service_(60.0), work_dir_(work_dir) {
  // The request rate limit reads the wall clock; lifted, the run stays
  // deterministic. The per-client instance limits still apply.
  server::ServiceLimits limits;
  limits.max_request_rate = 1e12;
  service_.set_limits(limits);
  service_.set_record_dir(work_dir_ / "recordings");
  for (const auto& p : packages) service_.load_package(p);
  top_up();
}

std::string RequestHarness::top_up() {
  if (!service_.engine().instances().empty()) return "";
  v1::Request create;
  create.set_id(next_id_++);
  create.mutable_create_instance()->set_scene(scene());
  const auto v = run(create.SerializeAsString());
  return v.violation.empty() ? "" : "top_up: " + v.violation;
}

std::string RequestHarness::scene() const {
  return service_.engine().scenes().front().name;
}

RequestVerdict RequestHarness::run(std::string_view bytes, const std::string& client) {
  const server::ServiceStats before = service_.stats();
  v1::Reply reply;
  try {
    reply = service_.handle(bytes, client);
  } catch (const std::exception& e) {
    return thrown(fmt::format("handle() threw {}: {}", typeid(e).name(), e.what()));
  } catch (...) {
    return thrown("handle() threw something that is no std::exception");
  }
  const server::ServiceStats after = service_.stats();
  v1::Request request;
  const bool parsed = request.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()));
  RequestVerdict v;
  v.violation = check(parsed ? &request : nullptr, reply, before, after);
  // docs/protocol.md: "error is one line"; names echoed verbatim can break it.
  if (reply.error().find_first_of("\r\n") != std::string::npos) v.note = "error reply spans several lines";
  v.kind =
      reply.ok() ? "ok " + core::oneof_case(reply, "result") : "error " + kind_of_line(reply.error(), 70);
  return v;
}

std::string RequestHarness::check(const v1::Request* request, const v1::Reply& reply,
                                  const server::ServiceStats& before,
                                  const server::ServiceStats& after) const {
  if (after.requests != before.requests + 1) {
    return fmt::format("{} requests counted for one input (expected exactly one reply)",
                       after.requests - before.requests);
  }
  if (after.bad_requests - before.bad_requests != (reply.ok() ? 0u : 1u)) {
    return fmt::format("bad_requests grew by {} for a reply with ok = {} (expected {})",
                       after.bad_requests - before.bad_requests, reply.ok(), reply.ok() ? 0 : 1);
  }
  if (reply.ok() == !reply.error().empty()) {
    return fmt::format("ok = {} with error '{}' (expected an error exactly when ok is false)", reply.ok(),
                       reply.error());
  }
  if (!request) {
    if (reply.id() == 0 && !reply.ok()) return "";
    return fmt::format("unparsable bytes answered with id {}, ok = {} (expected id 0, ok = false)",
                       reply.id(), reply.ok());
  }
  if (reply.id() != request->id()) {
    return fmt::format("reply id {} for request id {} (expected the request's id)", reply.id(),
                       request->id());
  }
  const std::string body = core::oneof_case(*request, "body");
  if (!reply.ok()) return check_error(body, reply);
  const auto expected = result_of_body().find(body);
  const std::string result = core::oneof_case(reply, "result");
  if (expected != result_of_body().end() && result != expected->second &&
      !(body == "list_instances" && result.empty())) {
    return fmt::format("{} request answered with result '{}' (expected '{}')", body, result,
                       expected->second);
  }
  if (body == "basis") return check_basis(request->basis(), reply.basis());
  if (body == "create_instance" && service_.engine().instances().count(reply.created().instance()) == 0) {
    return fmt::format("created instance {} does not exist", reply.created().instance());
  }
  return "";
}

std::string RequestHarness::tick() {
  const std::size_t instances = service_.engine().instances().size();
  most_instances_ = std::max(most_instances_, instances);
  try {
    const auto& frames = service_.tick();
    if (frames.size() != instances) {
      return fmt::format("tick published {} frames for {} instances (expected one each)", frames.size(),
                         instances);
    }
    v1::Frame f;
    for (const auto& p : frames) {
      if (!f.ParseFromString(p.payload) || p.topic != fmt::format("inst/{}/", f.instance())) {
        return fmt::format("tick published topic '{}' with a frame that does not parse or match it", p.topic);
      }
      if (!finite(f.q_u()) || !finite(f.q_a()) || !finite(f.support())) {
        return fmt::format("tick published a non-finite coordinate for instance {} at frame {}", f.instance(),
                           f.frame());
      }
    }
  } catch (const std::exception& e) {
    return fmt::format("tick() threw {}: {}", typeid(e).name(), e.what());
  }
  return "";
}

std::string RequestHarness::activity() const {
  const server::ServiceStats s = service_.stats();
  return fmt::format("{} frames published, {} impulses applied, {} refused when due, at most {} instances",
                     s.frames_published, s.impulses_applied, s.impulses_refused, most_instances_);
}

std::string RequestHarness::tidy() {
  const auto& instances = service_.engine().instances();
  while (instances.size() > 64) {
    v1::Request destroy;
    destroy.set_id(next_id_++);
    destroy.mutable_destroy_instance()->set_instance(instances.rbegin()->first);
    const std::string bytes = destroy.SerializeAsString();
    if (auto v = run(bytes); !v.violation.empty()) return "tidy: " + v.violation;
  }
  if (service_.recording()) service_.stop_recording();
  std::error_code ec;
  std::filesystem::remove_all(work_dir_ / "recordings", ec);
  return "";
}

std::vector<Bytes> RequestHarness::seeds() const {
  const auto& palette = service_.engine().scenes().front().data->palette;
  std::vector<v1::Request> r;
  const auto add = [&r](auto fill) {
    v1::Request q;
    q.set_id(r.size() + 1);
    fill(q);
    r.push_back(q);
  };
  add([](v1::Request& q) { q.mutable_list_scenes(); });
  add([](v1::Request& q) { q.mutable_list_instances(); });
  add([](v1::Request& q) { q.mutable_stats(); });
  for (const auto& s : service_.engine().scenes()) {
    add([&](v1::Request& q) { q.mutable_create_instance()->set_scene(s.name); });
  }
  add([](v1::Request& q) { q.mutable_create_instance()->set_scene("nope"); });
  add([](v1::Request& q) { q.mutable_destroy_instance()->set_instance(1); });
  add([](v1::Request& q) { q.mutable_destroy_instance()->set_instance(999); });
  for (int d = 0; d < palette.size(); ++d) {
    add([&](v1::Request& q) {
      q.mutable_impulse()->set_instance(1);
      q.mutable_impulse()->set_name(palette.names[static_cast<std::size_t>(d)]);
    });
    add([&](v1::Request& q) {
      q.mutable_impulse()->set_instance(1);
      q.mutable_impulse()->set_index(static_cast<std::uint32_t>(d));
      q.mutable_impulse()->set_at_frame(10);
    });
  }
  add([](v1::Request& q) { q.mutable_impulse()->set_instance(1); });
  for (int part = v1::BasisPart_MIN; part <= v1::BasisPart_MAX; ++part) {
    add([&](v1::Request& q) {
      q.mutable_basis()->set_scene(scene());
      q.mutable_basis()->set_part(static_cast<v1::BasisPart>(part));
    });
  }
  add([&](v1::Request& q) {
    auto& b = *q.mutable_basis();
    b.set_scene(scene());
    b.set_part(v1::U_U);
    b.set_offset(64);
    b.set_max_bytes(16);
  });
  add([](v1::Request& q) { q.mutable_record_start()->set_path("fuzz.phcrec"); });
  add([](v1::Request& q) { q.mutable_record_stop(); });
  add([](v1::Request&) {});  // no body
  std::vector<Bytes> out;
  for (const auto& q : r) out.push_back(q.SerializeAsString());
  return out;
}

std::vector<std::string> RequestHarness::names() const {
  std::vector<std::string> out;
  for (const auto& s : service_.engine().scenes()) {
    out.push_back(s.name);
    for (const auto& n : s.data->palette.names) out.push_back(n);
  }
  return out;
}

std::vector<std::uint64_t> RequestHarness::instance_ids() const {
  std::vector<std::uint64_t> out;
  for (const auto& [id, inst] : service_.engine().instances()) out.push_back(id);
  return out;
}

std::vector<std::uint64_t> RequestHarness::frames() const {
  std::vector<std::uint64_t> out;
  for (const auto& [id, inst] : service_.engine().instances()) out.push_back(inst.frame);
  return out;
}

int RequestHarness::palette_size() const {
  return service_.engine().scenes().front().data->palette.size();
}

// ---- schema-aware mutations -------------------------------------------------------

// Mostly values that mean something for the field (a live instance, a frame
// near the instance's, a palette index), else boundary and random values.
std::uint64_t RequestMutator::number(const std::string& field) {
  static constexpr std::uint64_t kEdges[] = {0,          1,          2,          3,          0x7f,
                                             0x80,       0xffff,     0x7fffffff, 0x80000000, 0xffffffff,
                                             1ull << 32, 1ull << 53, 1ull << 63, ~0ull,      ~0ull - 1};
  const auto any = [this](const std::vector<std::uint64_t>& v) {
    return v.empty() ? 1 : v[random_.below(v.size())];
  };
  if (!random_.one_in(4)) {
    if (field == "instance") return any(harness_.instance_ids());
    if (field == "at_frame") return any(harness_.frames()) + random_.below(200) - 20;
    if (field == "index") return random_.below(static_cast<std::uint64_t>(harness_.palette_size()) + 2);
  }
  switch (random_.below(3)) {
    case 0:
      return random_.pick(kEdges);
    case 1:
      return random_.below(16);
    default:
      return random_.bits() >> random_.below(64);
  }
}

std::string RequestMutator::text() {
  static const char* const kSpecial[] = {"",        ".",           "..",         "fuzz.phcrec",   "a.phcrec",
                                         ".phcrec", "../x.phcrec", "d/x.phcrec", "/tmp/x.phcrec", "x.h5",
                                         "a\nb",    "caf\xc3\xa9", "\xc3\x28",   "\xed\xa0\x80",  "\xff\xfe"};
  switch (random_.below(5)) {
    case 0:
    case 1: {
      const auto known = harness_.names();
      std::string s = known.empty() ? "x" : known[random_.below(known.size())];
      if (random_.one_in(4)) s += static_cast<char>(random_.bits());
      return s;
    }
    case 2:
      return random_.pick(kSpecial);
    case 3: {
      std::string s(1 + random_.below(random_.one_in(8) ? 70000 : 40), 'a');
      if (random_.one_in(2)) s[random_.below(s.size())] = '\0';
      return s;
    }
    default: {
      std::string s(random_.below(12), '\0');
      for (auto& c : s) c = static_cast<char>(random_.bits());
      return s;
    }
  }
}

void RequestMutator::set_field(Message& m, const FieldDescriptor* f, int depth) {
  const auto* r = m.GetReflection();
  if (f->is_repeated()) {
    if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE && depth < 4)
      mutate_message(*r->AddMessage(&m, f), depth + 1);
    return;
  }
  switch (f->cpp_type()) {
    case FieldDescriptor::CPPTYPE_INT32:
      return r->SetInt32(&m, f, static_cast<std::int32_t>(number(f->name())));
    case FieldDescriptor::CPPTYPE_INT64:
      return r->SetInt64(&m, f, static_cast<std::int64_t>(number(f->name())));
    case FieldDescriptor::CPPTYPE_UINT32:
      return r->SetUInt32(&m, f, static_cast<std::uint32_t>(number(f->name())));
    case FieldDescriptor::CPPTYPE_UINT64:
      return r->SetUInt64(&m, f, number(f->name()));
    case FieldDescriptor::CPPTYPE_DOUBLE:
      return r->SetDouble(&m, f, random_.one_in(2) ? std::nan("") : -1e300);
    case FieldDescriptor::CPPTYPE_FLOAT:
      return r->SetFloat(&m, f, random_.one_in(2) ? std::nanf("") : -1e30f);
    case FieldDescriptor::CPPTYPE_BOOL:
      return r->SetBool(&m, f, random_.one_in(2));
    case FieldDescriptor::CPPTYPE_ENUM:
      return r->SetEnumValue(&m, f, static_cast<int>(random_.below(12)) - 2);
    case FieldDescriptor::CPPTYPE_STRING: {
      std::string s = text();
      // Proto3 `string` fields must hold UTF-8; serializing anything else
      // would only make the fuzzer log. Byte-level mutations still reach it.
      if (f->type() == FieldDescriptor::TYPE_STRING && !valid_utf8(s)) s = "x";
      return r->SetString(&m, f, std::move(s));
    }
    case FieldDescriptor::CPPTYPE_MESSAGE:
      if (depth < 4) mutate_message(*r->MutableMessage(&m, f), depth + 1);
      return;
  }
}

void RequestMutator::mutate_message(Message& m, int depth) {
  const auto* d = m.GetDescriptor();
  const auto* r = m.GetReflection();
  if (d->field_count() == 0) return;
  // Mostly stay inside the body already set, sometimes switch to another.
  std::vector<const FieldDescriptor*> set;
  r->ListFields(m, &set);
  std::erase_if(set,
                [](const FieldDescriptor* f) { return f->cpp_type() != FieldDescriptor::CPPTYPE_MESSAGE; });
  if (!set.empty() && !random_.one_in(3)) {
    return mutate_message(*r->MutableMessage(&m, set[random_.below(set.size())]), depth + 1);
  }
  const auto* f = d->field(static_cast<int>(random_.below(static_cast<std::uint64_t>(d->field_count()))));
  if (random_.one_in(6)) return r->ClearField(&m, f);
  set_field(m, f, depth);
}

void RequestMutator::append_wire_noise(Bytes& data) {
  static constexpr std::uint64_t kFields[] = {1, 2, 3, 4, 10, 15, 19, 20, 99, 536870911};
  switch (random_.below(3)) {
    case 0: {  // an unknown or mistyped field
      const std::uint64_t wire = random_.below(6);
      varint(data, random_.pick(kFields) << 3 | wire);
      if (wire == 0) varint(data, number(""));
      if (wire == 1) data.append(8, '\x7f');
      if (wire == 2) varint(data, random_.below(4) == 0 ? number("") : random_.below(8));
      if (wire == 5) data.append(4, '\x01');
      return;
    }
    case 1:  // a varint that never ends
      data.append(1 + random_.below(11), '\x80');
      return;
    default:  // a body field whose length runs past the end
      varint(data, 15 << 3 | 2);
      varint(data, 1000 + random_.below(1u << 20));
      return;
  }
}

// Points the request's instance fields at live instances: ids are never
// reused, so a seed's instance 1 is gone after its first destroy.
void RequestMutator::retarget(Message& m) {
  const auto ids = harness_.instance_ids();
  if (ids.empty()) return;
  std::vector<const FieldDescriptor*> set;
  m.GetReflection()->ListFields(m, &set);
  for (const auto* f : set) {
    if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE && !f->is_repeated()) {
      retarget(*m.GetReflection()->MutableMessage(&m, f));
    }
  }
  if (const auto* f = m.GetDescriptor()->FindFieldByName("instance");
      f && f->cpp_type() == FieldDescriptor::CPPTYPE_UINT32 && !f->is_repeated()) {
    m.GetReflection()->SetUInt32(&m, f, static_cast<std::uint32_t>(ids[random_.below(ids.size())]));
  }
}

Bytes RequestMutator::mutate(const Bytes& parent, const Bytes& other) {
  v1::Request request;
  if (random_.one_in(3) || !request.ParseFromString(parent)) {
    Bytes data = parent;
    ByteMutator bytes(random_);
    for (auto n = 1 + random_.below(3); n > 0; --n) bytes.mutate(data, other);
    return data;
  }
  if (random_.one_in(2)) retarget(request);
  for (auto n = random_.below(3); n > 0; --n) mutate_message(request, 0);
  Bytes data = request.SerializeAsString();
  if (random_.one_in(10)) data += other;  // protobuf merges concatenated messages
  if (random_.one_in(10)) append_wire_noise(data);
  return data;
}

}  // namespace phasecast::fuzz
