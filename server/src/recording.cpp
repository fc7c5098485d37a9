#include "phasecast/server/recording.h"

#include "phasecast/server/wire.h"

#include <fcntl.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <map>

namespace phasecast::server {
namespace {

std::string errno_text() {
  return std::strerror(errno);
}

}  // namespace

RecordingWriter::RecordingWriter(std::filesystem::path path, const v1::RecordingHeader& header)
    : path_(std::move(path)), last_sync_(std::chrono::steady_clock::now()) {
  fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0)
    throw RecordingError(fmt::format("record: cannot create '{}': {}", path_.string(), errno_text()));
  buffer_ = core::recording_prologue(header);
  flush_buffer();
}

RecordingWriter::~RecordingWriter() {
  try {
    close();
  } catch (const RecordingError&) {
    // A destructor cannot report; close() is called explicitly where it matters.
  }
}

void RecordingWriter::append(const v1::RecordEntry& entry) {
  core::append_record(entry, buffer_);
  if (entry.has_frame()) ++frames_;
}

void RecordingWriter::flush_buffer() {
  std::size_t done = 0;
  while (done < buffer_.size()) {
    const ssize_t n = ::write(fd_, buffer_.data() + done, buffer_.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0)
      throw RecordingError(fmt::format("record: writing '{}' failed: {}", path_.string(), errno_text()));
    done += static_cast<std::size_t>(n);
  }
  buffer_.clear();
}

void RecordingWriter::end_tick(std::chrono::steady_clock::time_point now) {
  if (fd_ < 0) return;
  flush_buffer();
  if (now - last_sync_ >= sync_every) {
    ::fdatasync(fd_);
    last_sync_ = now;
  }
}

void RecordingWriter::close() {
  if (fd_ < 0) return;
  std::string failure;
  try {
    flush_buffer();
  } catch (const RecordingError& e) {
    failure = e.what();
  }
  if (::fsync(fd_) != 0 && failure.empty())
    failure = fmt::format("record: fsync '{}': {}", path_.string(), errno_text());
  ::close(fd_);
  fd_ = -1;
  if (!failure.empty()) throw RecordingError(failure);
}

namespace {

// Names the first field in which two frames differ.
std::string first_difference(const v1::Frame& a, const v1::Frame& b) {
  auto floats = [](const auto& x, const auto& y, const char* name) -> std::string {
    if (x.size() != y.size()) return fmt::format("{} has {} values (recorded {})", name, x.size(), y.size());
    for (int i = 0; i < x.size(); ++i) {
      if (std::memcmp(&x[i], &y[i], sizeof(float)) != 0) {
        return fmt::format("{}[{}] = {} (recorded {})", name, i, x[i], y[i]);
      }
    }
    return {};
  };
  for (const auto& d : {floats(a.q_u(), b.q_u(), "q_u"), floats(a.q_a(), b.q_a(), "q_a"),
                        floats(a.support(), b.support(), "support")}) {
    if (!d.empty()) return d;
  }
  if (a.palette_index() != b.palette_index() || a.irf() != b.irf() || a.irf_t() != b.irf_t()) {
    return fmt::format("palette entry/IRF/step {}/{}/{} (recorded {}/{}/{})", a.palette_index(), a.irf(),
                       a.irf_t(), b.palette_index(), b.irf(), b.irf_t());
  }
  return "seq, time or scene";
}

void check_header(const SynthesisEngine& engine, const v1::RecordingHeader& h) {
  if (h.format_version() != kRecordingFormatVersion) {
    throw RecordingError(fmt::format("replay-check: recording format version {} (expected {})",
                                     h.format_version(), kRecordingFormatVersion));
  }
  for (const auto& rs : h.scenes()) {
    const auto& scene = engine.scenes()[static_cast<std::size_t>(engine.scene_index(rs.scene()))];
    if (scene.content_hash != rs.content_hash()) {
      throw RecordingError(
          fmt::format("replay-check: scene '{}' was recorded from {} with hash {:016x}, but {} has hash "
                      "{:016x} (expected the "
                      "same package)",
                      rs.scene(), rs.package(), rs.content_hash(), scene.package, scene.content_hash));
    }
  }
}

}  // namespace

ReplayReport replay_check(SynthesisEngine& engine, const std::vector<v1::RecordEntry>& entries) {
  ReplayReport report;
  std::map<std::uint32_t, SynthesizedFrame> produced;  // this tick's frames not yet compared
  v1::Frame mine;
  try {
    for (std::size_t i = 0; i < entries.size(); ++i) {
      const auto& e = entries[i];
      if (e.has_header()) {
        if (i != 0) throw RecordingError(fmt::format("replay-check: record {} is a second header", i));
        check_header(engine, e.header());
      } else if (e.has_created()) {
        const auto& c = e.created();
        engine.restore_instance(c.instance(), c.scene(), c.frame(),
                                from_snapshot(c.state(), fmt::format("record {}", i)));
        ++report.instances;
      } else if (e.has_destroyed()) {
        engine.destroy_instance(e.destroyed().instance());
      } else if (e.has_impulse()) {
        const auto& imp = e.impulse();
        const int d =
            imp.has_name() ? engine.palette_index(imp.instance(), imp.name()) : static_cast<int>(imp.index());
        engine.schedule_impulse(imp.instance(), d, imp.at_frame());
        ++report.impulses;
      } else if (e.has_frame()) {
        const auto& rec = e.frame();
        if (!produced.count(rec.instance())) {
          if (engine.instance(rec.instance()).frame != rec.frame()) {
            throw RecordingError(
                fmt::format("replay-check: record {}: frame {} of instance {} out of order (the "
                            "replay is at frame {})",
                            i, rec.frame(), rec.instance(), engine.instance(rec.instance()).frame));
          }
          produced.clear();
          TickResult made = engine.tick();
          for (auto& f : made.frames) produced[f.instance] = std::move(f);
        }
        const auto& inst = engine.instance(rec.instance());
        to_frame_message(engine.scenes()[static_cast<std::size_t>(inst.scene)], produced.at(rec.instance()),
                         mine);
        produced.erase(rec.instance());
        if (mine.SerializeAsString() != rec.SerializeAsString()) {
          throw RecordingError(fmt::format("replay-check: frame {} of instance {} differs: {}", rec.frame(),
                                           rec.instance(), first_difference(mine, rec)));
        }
        ++report.frames;
      }
    }
  } catch (const EngineError& err) {
    throw RecordingError(fmt::format("replay-check: {}", err.what()));
  }
  return report;
}

}  // namespace phasecast::server
