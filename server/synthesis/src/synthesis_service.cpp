#include "phasecast/server/synthesis_service.h"

#include "phasecast/core/basis.h"
#include "phasecast/core/hash.h"
#include "phasecast/core/proto_oneof.h"
#include "phasecast/server/wire.h"

#include <fmt/chrono.h>
#include <fmt/format.h>

#include <algorithm>
#include <ctime>
#include <system_error>

namespace phasecast::server {
namespace {

// A refused request: the reply's error line, prefixed with the request kind.
class RequestError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The request's kind for error lines ("impulse: ..."); "request" when it has none.
std::string kind_of(const v1::Request& r) {
  const auto kind = core::oneof_case(r, "body");
  return kind.empty() ? "request" : kind;
}

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  return fmt::format("{:%Y-%m-%dT%H:%M:%SZ}", tm);
}

// Client-named recordings are plain *.phcrec names inside the server's
// record directory: a network client must not choose where the server
// writes, nor name a file that is anything but a recording.
void check_record_name(const std::string& name) {
  const std::string_view ext = ".phcrec";
  const bool plain = name.size() > ext.size() && name.ends_with(ext) && name[0] != '.' &&
                     name.find('/') == std::string::npos && name.find('\0') == std::string::npos;
  if (!plain) {
    throw RequestError(
        fmt::format("path '{}' (expected a plain file name ending in .phcrec; recordings go to the server's "
                    "--record-dir)",
                    name));
  }
}

// The length of the valid UTF-8 prefix of `s` (RFC 3629: no overlongs, no
// surrogates, nothing above U+10FFFF).
std::size_t utf8_valid_prefix(std::string_view s) {
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    const int n = c < 0x80 ? 0 : (c >> 5) == 0x6 ? 1 : (c >> 4) == 0xE ? 2 : (c >> 3) == 0x1E ? 3 : -1;
    if (n < 0 || i + static_cast<std::size_t>(n) >= s.size() + (n == 0 ? 1 : 0)) return i;
    std::uint32_t cp = n == 0 ? c : c & (0x3F >> n);
    for (int k = 1; k <= n; ++k) {
      const auto cc = static_cast<unsigned char>(s[i + static_cast<std::size_t>(k)]);
      if ((cc >> 6) != 0x2) return i;
      cp = (cp << 6) | (cc & 0x3F);
    }
    const std::uint32_t min_cp[] = {0, 0x80, 0x800, 0x10000};
    if (cp < min_cp[n] || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return i;
    i += static_cast<std::size_t>(n) + 1;
  }
  return i;
}

// Names and paths travel as bytes (proto/phasecast.proto) so that libprotobuf
// does not log every malformed one; they must still be UTF-8, and without
// control characters, which would break (a newline) or cut (a NUL) the
// one-line error that echoes them.
void check_text(const char* field, const std::string& value) {
  const auto ok = utf8_valid_prefix(value);
  if (ok != value.size()) {
    throw RequestError(
        fmt::format("{} is not valid UTF-8 (byte {} of {}; expected UTF-8 text)", field, ok, value.size()));
  }
  const auto control = std::find_if(value.begin(), value.end(),
                                    [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; });
  if (control != value.end()) {
    throw RequestError(fmt::format("{} has a control character 0x{:02x} at byte {} (expected printable text)",
                                   field, static_cast<unsigned char>(*control), control - value.begin()));
  }
}

// A request over one of the --max-* limits.
class LimitError : public RequestError {
 public:
  using RequestError::RequestError;
};

}  // namespace

SynthesisService::SynthesisService(double rate_hz) : rate_hz_(rate_hz) {}

SynthesisService::~SynthesisService() = default;

void SynthesisService::load_package(const std::filesystem::path& package,
                                    std::optional<double> blend_lambda) {
  auto data = std::make_shared<const core::ScenePackage>(core::read_package(package));
  engine_.add_scene(std::move(data), package.filename().string(), core::file_content_hash(package),
                    blend_lambda);
}

v1::Reply SynthesisService::handle(std::string_view bytes, const std::string& client) {
  v1::Request request;
  if (!request.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
    count_bad_message();
    v1::Reply reply;
    reply.set_ok(false);
    reply.set_error(fmt::format("request: {} bytes do not parse as a phasecast.v1.Request", bytes.size()));
    return reply;
  }
  return handle(request, client);
}

v1::Reply SynthesisService::handle(const v1::Request& request, const std::string& client) {
  v1::Reply reply;
  reply.set_id(request.id());
  std::unique_lock lock(mutex_, std::defer_lock);
  try {
    {
      std::lock_guard guard(mutex_);
      ++stats_.requests;
      check_rate(client);
    }
    // Packages never change once serving: a basis chunk needs no lock.
    if (!request.has_basis()) lock.lock();
    std::vector<InstanceRow> rows;
    answer(request, client, reply, rows);
    auto closing = std::move(closing_);
    if (lock.owns_lock()) lock.unlock();
    // Listing 45 000 instances takes milliseconds: the tick does not wait for it.
    if (request.has_stats()) write_instances(rows, reply.mutable_stats()->mutable_instances());
    // With no instances the reply's result stays unset, as it always was.
    if (request.has_list_instances() && !rows.empty())
      write_instances(rows, reply.mutable_instances()->mutable_instances());
    if (closing) closing->close();  // record_stop's last write and fsync, while the tick goes on
    reply.set_ok(true);             // before its size is taken
    // Any large reply (a basis chunk, the stats or instance list of many
    // instances) waits in the client's queue until read: bounded like one.
    if (const auto bytes = reply.ByteSizeLong(); bytes > kRepliesAlwaysSent)
      check_pending_replies(client, bytes);
  } catch (const std::exception& e) {  // EngineError, RequestError, RecordingError
    if (!lock.owns_lock()) lock.lock();
    ++stats_.bad_requests;
    if (dynamic_cast<const LimitError*>(&e)) ++stats_.limited_requests;
    reply.Clear();
    reply.set_id(request.id());
    reply.set_ok(false);
    reply.set_error(fmt::format("{}: {}", kind_of(request), e.what()));
  }
  return reply;
}

void SynthesisService::count_bad_message() {
  std::lock_guard lock(mutex_);
  ++stats_.requests;
  ++stats_.bad_requests;
}

void SynthesisService::count_tick(double seconds, bool late) {
  std::lock_guard lock(mutex_);
  if (late) ++stats_.late_ticks;
  stats_.max_tick_seconds = std::max(stats_.max_tick_seconds, seconds);
}

ServiceStats SynthesisService::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

bool SynthesisService::recording() const {
  std::lock_guard lock(mutex_);
  return recorder_ != nullptr;
}

std::string SynthesisService::recording_error() const {
  std::lock_guard lock(mutex_);
  return recording_error_;
}

// A token bucket per client holding one second of requests; idle clients'
// buckets are forgotten so that many short connections cannot grow the map.
void SynthesisService::check_rate(const std::string& client) {
  if (client.empty()) return;
  const auto now = std::chrono::steady_clock::now();
  const double rate = limits_.max_request_rate;
  if (buckets_.size() > 4096) {
    std::erase_if(buckets_, [&](const auto& kv) { return now - kv.second.last > std::chrono::seconds(2); });
  }
  auto [it, fresh] = buckets_.try_emplace(client, RateBucket{rate, now});
  auto& b = it->second;
  b.tokens = std::min(rate, b.tokens + rate * std::chrono::duration<double>(now - b.last).count());
  b.last = now;
  if (b.tokens < 1) {
    throw LimitError(fmt::format(
        "more than {:g} requests/s from this client (expected at most --max-request-rate {:g})", rate, rate));
  }
  b.tokens -= 1;
}

void SynthesisService::answer(const v1::Request& r, const std::string& client, v1::Reply& reply,
                              std::vector<InstanceRow>& rows) {
  switch (r.body_case()) {
    case v1::Request::kImpulse:
      return impulse(r.impulse(), *reply.mutable_impulse());
    case v1::Request::kListScenes:
      return list_scenes(*reply.mutable_scenes());
    case v1::Request::kListInstances:
      return list_instances(rows);
    case v1::Request::kCreateInstance:
      return create_instance(r.create_instance(), client, *reply.mutable_created());
    case v1::Request::kDestroyInstance:
      return destroy_instance(r.destroy_instance(), *reply.mutable_destroyed());
    case v1::Request::kBasis:
      return basis(r.basis(), *reply.mutable_basis());
    case v1::Request::kRecordStart:
      return record_start(r.record_start(), *reply.mutable_record());
    case v1::Request::kRecordStop:
      return record_stop(*reply.mutable_record());
    case v1::Request::kStats:
      return report_stats(*reply.mutable_stats(), rows);
    case v1::Request::BODY_NOT_SET:
      break;
  }
  throw RequestError(fmt::format(
      "request {} has no body this server knows (expected one of impulse, list_scenes, list_instances, "
      "create_instance, destroy_instance, basis, record_start, record_stop, stats)",
      r.id()));
}

void SynthesisService::impulse(const v1::Impulse& r, v1::ImpulseAccepted& out) {
  const auto& inst = engine_.instance(r.instance());
  int d = 0;
  switch (r.entry_case()) {
    case v1::Impulse::kName:
      check_text("palette entry name", r.name());
      d = engine_.palette_index(r.instance(), r.name());
      break;
    case v1::Impulse::kIndex:
      d = static_cast<int>(std::min<std::uint32_t>(r.index(), 1u << 30));
      break;
    case v1::Impulse::ENTRY_NOT_SET:
      throw RequestError(fmt::format("instance {} ({}): no palette entry given (expected name or index)",
                                     r.instance(),
                                     engine_.scenes()[static_cast<std::size_t>(inst.scene)].name));
  }
  const std::optional<std::uint64_t> at = r.has_at_frame() ? std::optional(r.at_frame()) : std::nullopt;
  // An impulse far in the future would hold a queue slot forever.
  const auto horizon = static_cast<std::uint64_t>(limits_.impulse_horizon_s * rate_hz_);
  if (at && *at > inst.frame && *at - inst.frame > horizon) {
    throw LimitError(fmt::format(
        "instance {}: at_frame {} is {} frames ahead (expected at most {} frames, {:g} s at {:g} Hz; see "
        "--impulse-horizon)",
        r.instance(), *at, *at - inst.frame, horizon, limits_.impulse_horizon_s, rate_hz_));
  }
  out.set_instance(r.instance());
  out.set_palette_index(static_cast<std::uint32_t>(d));
  out.set_at_frame(engine_.schedule_impulse(r.instance(), d, at));
}

namespace {

// The package's view besides the camera, only when it says anything.
void describe_view(const core::PackageAttributes& a, v1::SceneInfo& info) {
  if (a.floor && !a.floor_height && a.light.empty() && !a.exposure) return;
  auto& v = *info.mutable_view();
  v.set_no_floor(!a.floor);
  if (a.floor_height) v.set_floor_height(*a.floor_height);
  v.set_light(a.light);
  if (a.exposure) v.set_exposure(*a.exposure);
}

void describe_fidelity(const core::PlaybackFidelity& f, v1::Fidelity& out) {
  const auto count = [](std::int32_t n) { return static_cast<std::uint32_t>(std::max(n, 0)); };
  out.set_schedules(count(f.schedules));
  out.set_items(count(f.items));
  out.set_seed(f.seed);
  out.set_median_nrmse(f.median_nrmse);
  out.set_p90_nrmse(f.p90_nrmse);
  out.set_moving(count(f.moving));
  out.set_moving_within(count(f.moving_within));
  out.set_switches(count(f.switches));
  out.set_switches_within(count(f.switches_within));
  if (f.target_median_nrmse) {
    out.set_adaptive(true);
    out.set_target_median_nrmse(*f.target_median_nrmse);
    out.set_sampled_irfs(count(f.sampled_irfs));
    out.set_rounds(count(f.rounds));
    out.set_target_met(f.target_met);
  }
}

}  // namespace

void SynthesisService::list_scenes(v1::SceneList& out) const {
  out.set_pub_endpoint(pub_endpoint_);
  for (const auto& s : engine_.scenes()) {
    const auto& p = *s.data;
    auto& info = *out.add_scenes();
    info.set_name(s.name);
    info.set_package(s.package);
    info.set_content_hash(s.content_hash);
    info.set_points(static_cast<std::uint32_t>(p.mesh.points()));
    info.set_triangles(static_cast<std::uint32_t>(p.mesh.triangle_count()));
    info.set_rank_u(static_cast<std::uint32_t>(p.rank_u()));
    info.set_rank_a(static_cast<std::uint32_t>(p.rank_a()));
    info.set_state_nodes(static_cast<std::uint32_t>(p.portrait.nodes()));
    info.set_dt(p.attributes.dt);
    if (p.attributes.camera)
      info.mutable_camera()->Assign(p.attributes.camera->begin(), p.attributes.camera->end());
    describe_view(p.attributes, info);
    if (p.fidelity) describe_fidelity(*p.fidelity, *info.mutable_fidelity());
    const auto& pal = p.palette;
    for (int d = 0; d < pal.size(); ++d) {
      const auto i = static_cast<std::size_t>(d);
      auto& e = *info.add_palette();
      e.set_name(pal.names[i]);
      e.set_index(static_cast<std::uint32_t>(d));
      e.mutable_alpha_impulse()->Assign(pal.alpha_impulse.row(d).data(),
                                        pal.alpha_impulse.row(d).data() + pal.alpha_impulse.cols());
      e.mutable_alpha_forcing()->Assign(pal.alpha_forcing.row(d).data(),
                                        pal.alpha_forcing.row(d).data() + pal.alpha_forcing.cols());
      e.set_on_end(pal.on_end[i]);
      const auto& k = pal.kinematics[i];
      auto& km = *e.mutable_kinematics();
      km.mutable_axis()->Assign(k.axis.begin(), k.axis.end());
      km.mutable_pivot()->Assign(k.pivot.begin(), k.pivot.end());
      km.set_rotational(k.rotational);
      km.set_rate(k.rate);
      km.set_range_min(k.range_min);
      km.set_range_max(k.range_max);
      km.set_pulse_tau(k.pulse_tau);
      if (pal.allowed(-1, d)) info.add_allowed_from_rest(static_cast<std::uint32_t>(d));
      for (int next = 0; next < pal.size(); ++next) {
        if (pal.allowed(d, next)) e.add_allowed_after(static_cast<std::uint32_t>(next));
      }
      e.set_group(static_cast<std::uint32_t>(pal.group[i]));
      e.set_max_in_a_row(static_cast<std::uint32_t>(pal.max_in_a_row[i]));
    }
    for (const auto& part : core::basis_parts(p)) {
      auto& bi = *info.add_parts();
      bi.set_part(static_cast<v1::BasisPart>(part.id));
      bi.set_dtype(part.dtype);
      for (const auto n : part.shape) bi.add_shape(n);
      bi.set_total_bytes(part.bytes.size());
    }
  }
}

// Rows only: handle() writes them into the reply after the lock is released.
void SynthesisService::list_instances(std::vector<InstanceRow>& rows) const {
  rows.reserve(engine_.instances().size());
  for (const auto& [id, inst] : engine_.instances()) rows.push_back(instance_row(id));
}

void SynthesisService::create_instance(const v1::CreateInstance& r, const std::string& client,
                                       v1::InstanceInfo& out) {
  check_text("scene name", r.scene());
  if (engine_.instances().size() >= limits_.max_instances) {
    throw LimitError(fmt::format("{} instances exist (expected at most {}; see --max-instances)",
                                 engine_.instances().size(), limits_.max_instances));
  }
  const auto mine = client.empty() ? 0 : instances_of_[client];
  if (!client.empty() && mine >= limits_.max_instances_per_client) {
    throw LimitError(
        fmt::format("this client created {} instances (expected at most {}; see --max-instances-per-client)",
                    mine, limits_.max_instances_per_client));
  }
  const auto id = engine_.create_instance(r.scene());
  if (!client.empty()) {
    owner_[id] = client;
    ++instances_of_[client];
  }
  record_created(id);
  instance_info(id, out);
}

// The reply describes the instance as it was just before it went.
void SynthesisService::destroy_instance(const v1::DestroyInstance& r, v1::InstanceInfo& out) {
  instance_info(r.instance(), out);  // throws EngineError for unknown instances
  engine_.destroy_instance(r.instance());
  if (const auto it = owner_.find(r.instance()); it != owner_.end()) {
    if (--instances_of_[it->second] == 0) instances_of_.erase(it->second);
    owner_.erase(it);
  }
  record_destroyed(out);
}

void SynthesisService::basis(const v1::BasisRequest& r, v1::BasisChunk& out) const {
  check_text("scene name", r.scene());
  const auto& s = engine_.scenes()[static_cast<std::size_t>(engine_.scene_index(r.scene()))];
  const auto parts = core::basis_parts(*s.data);
  const auto it = std::find_if(parts.begin(), parts.end(), [&](const core::BasisPartView& v) {
    return static_cast<int>(v.id) == r.part();
  });
  if (it == parts.end()) {
    std::string names;
    for (const auto& v : parts)
      names += (names.empty() ? "" : ", ") + v1::BasisPart_Name(static_cast<int>(v.id));
    throw RequestError(fmt::format("scene '{}' has no basis part {} (expected one of {})", s.name,
                                   static_cast<int>(r.part()), names));
  }
  const std::uint64_t total = it->bytes.size();
  if (r.offset() > total) {
    throw RequestError(fmt::format("offset {} is beyond the {} bytes of {} of scene '{}' (expected 0..{})",
                                   r.offset(), total, v1::BasisPart_Name(r.part()), s.name, total));
  }
  const std::uint64_t cap = r.max_bytes() == 0 ? kDefaultChunkBytes : std::min(r.max_bytes(), kMaxChunkBytes);
  const std::uint64_t n = std::min(cap, total - r.offset());
  out.set_scene(s.name);
  out.set_part(r.part());
  out.set_offset(r.offset());
  out.set_total_bytes(total);
  out.set_data(reinterpret_cast<const char*>(it->bytes.data()) + r.offset(), n);
  out.set_content_hash(s.content_hash);
  auto& info = *out.mutable_info();
  info.set_part(r.part());
  info.set_dtype(it->dtype);
  for (const auto d : it->shape) info.add_shape(d);
  info.set_total_bytes(total);
}

// Replies wait in ZeroMQ's per-connection queues until the client reads
// them; these bound what one client and all of them together can hold.
void SynthesisService::check_pending_replies(const std::string& client, std::uint64_t reply_bytes) const {
  const PendingReplyBytes pending = pending_reply_bytes_(client);
  const auto check = [&](std::uint64_t waiting, std::uint64_t bound, const char* readers, const char* scope,
                         const char* option) {
    if (waiting + reply_bytes <= bound) return;
    throw LimitError(
        fmt::format("{} bytes of replies are waiting for {} to read them and this reply has {} bytes "
                    "(expected at most {}{}; "
                    "see {})",
                    waiting, readers, reply_bytes, bound, scope, option));
  };
  check(pending.client, limits_.max_pending_reply_bytes_per_client, "this client", "",
        "--max-pending-reply-bytes-per-client");
  check(pending.all, limits_.max_pending_reply_bytes, "clients", " in all", "--max-pending-reply-bytes");
}

void SynthesisService::record_start(const v1::RecordStart& r, v1::RecordStatus& out) {
  check_text("path", r.path());
  check_record_name(r.path());
  std::error_code ec;
  std::filesystem::create_directories(record_dir_, ec);  // the default recordings/ appears on first use
  if (ec) {
    throw RecordingError(fmt::format("cannot create the record directory '{}': {} (see --record-dir)",
                                     record_dir_.string(), ec.message()));
  }
  start_recording_locked(record_dir_ / r.path());
  out.set_recording(true);
  out.set_path(recorder_->path().string());
}

// Runs under the lock; the final write and fsync happen in handle()'s caller
// after the lock is gone (the recorder is closed by stop_recording() there).
void SynthesisService::record_stop(v1::RecordStatus& out) {
  if (!recorder_) throw RequestError("not recording (expected a record_start first)");
  closing_ = take_recorder(out);
}

void SynthesisService::report_stats(v1::Stats& out, std::vector<InstanceRow>& rows) const {
  out.set_ticks(stats_.ticks);
  out.set_frames_published(stats_.frames_published);
  out.set_batches_published(stats_.batches_published);
  out.set_late_ticks(stats_.late_ticks);
  out.set_rate_hz(rate_hz_);
  out.set_requests(stats_.requests);
  out.set_bad_requests(stats_.bad_requests);
  out.set_impulses_applied(stats_.impulses_applied);
  out.set_impulses_refused(stats_.impulses_refused);
  out.set_limited_requests(stats_.limited_requests);
  out.set_recording(recorder_ != nullptr);
  out.set_recording_bytes(recorder_ ? recorder_->bytes_queued() : 0);
  out.set_max_tick_seconds(stats_.max_tick_seconds);
  out.set_recording_error(recording_error_);
  out.set_pending_reply_bytes(pending_reply_bytes_({}).all);
  list_instances(rows);
}

SynthesisService::InstanceRow SynthesisService::instance_row(std::uint32_t id) const {
  const auto& inst = engine_.instance(id);
  return {id,
          &engine_.scenes()[static_cast<std::size_t>(inst.scene)].name,
          inst.frame,
          inst.state.palette_index,
          inst.state.irf,
          inst.state.irf_t,
          engine_.allowed_entries(id)};
}

void SynthesisService::write_instance(const InstanceRow& row, v1::InstanceInfo& out) {
  out.set_instance(row.id);
  out.set_scene(*row.scene);
  out.set_frame(row.frame);
  out.set_palette_index(row.palette_index);
  out.set_irf(row.irf);
  out.set_irf_t(row.irf_t);
  out.set_topic(instance_topic(row.id));
  for (const int d : row.allowed) out.add_allowed_now(static_cast<std::uint32_t>(d));
}

void SynthesisService::write_instances(const std::vector<InstanceRow>& rows,
                                       google::protobuf::RepeatedPtrField<v1::InstanceInfo>* out) {
  out->Reserve(static_cast<int>(rows.size()));
  for (const auto& row : rows) write_instance(row, *out->Add());
}

void SynthesisService::instance_info(std::uint32_t id, v1::InstanceInfo& out) const {
  write_instance(instance_row(id), out);
}

void SynthesisService::record_created(std::uint32_t id) {
  if (!recorder_) return;
  const auto& inst = engine_.instance(id);
  v1::RecordEntry e;
  auto& c = *e.mutable_created();
  c.set_instance(id);
  c.set_scene(engine_.scenes()[static_cast<std::size_t>(inst.scene)].name);
  c.set_frame(inst.frame);
  to_snapshot(inst.state, *c.mutable_state());
  recorder_->append(e);
}

void SynthesisService::record_destroyed(const v1::InstanceInfo& info) {
  if (!recorder_) return;
  v1::RecordEntry e;
  auto& d = *e.mutable_destroyed();
  d.set_instance(info.instance());
  d.set_scene(info.scene());
  d.set_frame(info.frame());
  recorder_->append(e);
}

void SynthesisService::record_impulses(const std::vector<AppliedImpulse>& applied) {
  if (!recorder_) return;
  for (const auto& a : applied) {
    v1::RecordEntry e;
    auto& imp = *e.mutable_impulse();
    imp.set_instance(a.instance);
    imp.set_index(static_cast<std::uint32_t>(a.palette_index));
    imp.set_at_frame(a.frame);
    recorder_->append(e);
  }
}

void SynthesisService::start_recording(const std::filesystem::path& path) {
  std::lock_guard lock(mutex_);
  start_recording_locked(path);
}

void SynthesisService::start_recording_locked(const std::filesystem::path& path) {
  if (recorder_) {
    throw RecordingError(
        fmt::format("already recording to '{}' (expected record_stop first)", recorder_->path().string()));
  }
  v1::RecordingHeader h;
  h.set_format_version(kRecordingFormatVersion);
  h.set_rate_hz(rate_hz_);
  h.set_created_utc(utc_now());
  for (const auto& s : engine_.scenes()) {
    auto& rs = *h.add_scenes();
    rs.set_scene(s.name);
    rs.set_package(s.package);
    rs.set_content_hash(s.content_hash);
  }
  recorder_ = std::make_unique<RecordingWriter>(path, h, limits_.record_max_bytes);
  for (const auto& [id, inst] : engine_.instances()) record_created(id);
}

std::unique_ptr<RecordingWriter> SynthesisService::take_recorder(v1::RecordStatus& status) {
  status.set_path(recorder_->path().string());
  status.set_frames_written(recorder_->frames_written());
  return std::move(recorder_);
}

v1::RecordStatus SynthesisService::stop_recording() {
  v1::RecordStatus s;
  std::unique_ptr<RecordingWriter> recorder;
  {
    std::lock_guard lock(mutex_);
    if (!recorder_) return s;
    recorder = take_recorder(s);
  }
  recorder->close();  // the last write and fsync, while the tick goes on
  return s;
}

const std::vector<PublishedFrame>& SynthesisService::tick() {
  std::lock_guard lock(mutex_);
  try {
    tick_and_record();
  } catch (const RecordingError& e) {
    // A full disk must not stop the stream: the recording ends, serving goes on.
    recording_error_ = e.what();
    recorder_.reset();  // never waits: a failed writer's thread winds down on its own
  }
  return published_;
}

void SynthesisService::tick_and_record() {
  engine_.tick(tick_result_);
  const TickResult& r = tick_result_;
  ++stats_.ticks;
  stats_.impulses_applied += r.applied.size();
  stats_.impulses_refused += r.refused.size();
  record_impulses(r.applied);
  published_count_ = 0;
  open_batches_.assign(engine_.scenes().size(), OpenBatch{});
  batches_.resize(engine_.scenes().size());
  v1::RecordEntry entry;
  for (const auto& f : r.frames) {
    const auto& scene = engine_.scenes()[static_cast<std::size_t>(f.scene)];
    if (recorder_ || interest_.wants_instance(f.instance)) {
      to_frame_message(scene, f, frame_);
      if (interest_.wants_instance(f.instance)) {
        publish(instance_topic(f.instance), frame_);
        ++stats_.frames_published;
      }
      if (recorder_) {
        *entry.mutable_frame() = frame_;
        recorder_->append(entry);
      }
    }
    add_to_batch(f);
  }
  for (std::size_t s = 0; s < open_batches_.size(); ++s) close_batch(s);
  published_.resize(published_count_);
  if (recorder_) recorder_->end_tick();  // queues the tick for the writer thread; throws if it failed
}

void SynthesisService::publish(std::string topic, const google::protobuf::Message& message) {
  if (published_.size() <= published_count_) published_.resize(published_count_ + 1);
  auto& out = published_[published_count_++];
  out.topic = std::move(topic);
  message.SerializeToString(&out.payload);
}

// Frames arrive in id order, so a scene's blocks come one after the other:
// a frame of a new block closes its scene's open batch.
void SynthesisService::add_to_batch(const SynthesizedFrame& f) {
  const auto s = static_cast<std::size_t>(f.scene);
  const std::uint32_t block = batch_block(f.instance);
  OpenBatch& open = open_batches_[s];
  if (open.block != block) {
    close_batch(s);
    const auto& scene = engine_.scenes()[s];
    open = {block, interest_.wants(scene_batch_topic(scene.name, block))};
    if (open.wanted) begin_frame_batch(scene, block, stats_.ticks - 1, batches_[s]);
  }
  if (open.wanted) append_to_frame_batch(f, batches_[s]);
}

void SynthesisService::close_batch(std::size_t s) {
  OpenBatch& open = open_batches_[s];
  if (open.block && open.wanted) {
    const auto& batch = batches_[s];
    publish(scene_batch_topic(batch.scene(), batch.block()), batch);
    ++stats_.batches_published;
  }
  open = {};
}

void SynthesisService::set_subscriptions(std::set<std::string> prefixes) {
  std::lock_guard lock(mutex_);
  interest_.set(std::move(prefixes));
}

}  // namespace phasecast::server
