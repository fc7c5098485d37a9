#include "phasecast/server/recording.h"

#include "phasecast/server/thread_priority.h"
#include "phasecast/server/wire.h"

#include <fcntl.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <map>
#include <mutex>

namespace phasecast::server {
namespace {

std::string errno_text() {
  return std::strerror(errno);
}

// Writes all of `bytes`; returns "" or why not.
std::string write_all(int fd, const std::string& bytes, const std::filesystem::path& path) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return fmt::format("record: writing '{}' failed: {}", path.string(), errno_text());
    done += static_cast<std::size_t>(n);
  }
  return {};
}

}  // namespace

struct RecordingWriter::Shared {
  std::mutex mutex;
  std::condition_variable wake;
  std::deque<std::string> queue;
  std::size_t queued_bytes = 0;  // in the queue or being written
  bool stop = false;             // no more ticks come: drain, fsync, close
  std::string failure;           // set by the writer thread: a write or fsync failed
  // Set by the tick: the size cap or a full queue ended the recording. Unlike
  // a failure it does not stop the writer: what was queued is still written.
  std::string ended;
  int fd = -1;
  std::filesystem::path path;

  // The writer thread: writes each batch as it comes, fdatasyncs at least
  // every sync_every, and on stop drains the queue, fsyncs and closes.
  static void run(const std::shared_ptr<Shared>& s) {
    yield_to_the_tick();  // the recording may lag (its queue absorbs that), the tick may not
    auto last_sync = std::chrono::steady_clock::now();
    bool unsynced = false;
    std::unique_lock lock(s->mutex);
    for (;;) {
      s->wake.wait_for(lock, sync_every, [&] { return s->stop || !s->queue.empty(); });
      std::deque<std::string> batch;
      batch.swap(s->queue);
      const bool stopping = s->stop;
      lock.unlock();
      std::string failure;
      std::size_t bytes = 0;
      for (const auto& b : batch) {
        if (failure.empty()) failure = write_all(s->fd, b, s->path);
        bytes += b.size();
      }
      unsynced = unsynced || bytes > 0;
      const auto now = std::chrono::steady_clock::now();
      if (failure.empty() && (stopping || (unsynced && now - last_sync >= sync_every))) {
        if ((stopping ? ::fsync(s->fd) : ::fdatasync(s->fd)) != 0)
          failure = fmt::format("record: fsync '{}': {}", s->path.string(), errno_text());
        last_sync = now;
        unsynced = false;
      }
      lock.lock();
      s->queued_bytes -= bytes;
      if (!failure.empty() && s->failure.empty()) s->failure = failure;
      if (!s->failure.empty() || (stopping && s->queue.empty())) break;
    }
    ::close(s->fd);
    s->fd = -1;
  }
};

RecordingWriter::RecordingWriter(std::filesystem::path path, const v1::RecordingHeader& header,
                                 std::uint64_t max_bytes)
    : path_(std::move(path)), shared_(std::make_shared<Shared>()), max_bytes_(max_bytes) {
  // O_EXCL: a recording never replaces a file (a package being served, say);
  // O_NOFOLLOW: nor writes through a link planted in the record directory.
  shared_->fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (shared_->fd < 0) {
    throw RecordingError(
        fmt::format("record: cannot create '{}': {}{}", path_.string(), errno_text(),
                    errno == EEXIST ? " (expected a new file name; recordings never replace files)" : ""));
  }
  shared_->path = path_;
  buffer_ = core::recording_prologue(header);
  bytes_ = buffer_.size();
  shared_->queue.push_back(std::move(buffer_));
  shared_->queued_bytes = bytes_;
  buffer_.clear();
  writer_ = std::thread([s = shared_] { Shared::run(s); });
}

RecordingWriter::~RecordingWriter() {
  if (!writer_.joinable()) return;
  bool failed = false;
  {
    std::lock_guard lock(shared_->mutex);
    shared_->stop = true;
    failed = !shared_->failure.empty() || !shared_->ended.empty();
  }
  shared_->wake.notify_one();
  if (failed) {
    writer_.detach();  // it drains what was queued and closes; the tick must not wait for that
  } else {
    writer_.join();
  }
}

void RecordingWriter::append(const v1::RecordEntry& entry) {
  core::append_record(entry, buffer_);
  if (entry.has_frame()) ++tick_frames_;
}

void RecordingWriter::end_tick() {
  {
    std::lock_guard lock(shared_->mutex);
    const bool going = shared_->failure.empty() && shared_->ended.empty();
    if (going && bytes_ + buffer_.size() > max_bytes_) {
      shared_->ended = fmt::format("record: '{}' reached its size cap of {} bytes (see --record-max-bytes)",
                                   path_.string(), max_bytes_);
    } else if (going && shared_->queued_bytes + buffer_.size() > max_queued_bytes) {
      shared_->ended = fmt::format(
          "record: the disk fell behind: {} MiB of '{}' waited to be written (expected at most {} MiB)",
          (shared_->queued_bytes + buffer_.size()) >> 20, path_.string(), max_queued_bytes >> 20);
    }
    if (!shared_->failure.empty() || !shared_->ended.empty()) {
      // What was queued before is still written; this tick and later ones are not.
      shared_->stop = true;
      shared_->wake.notify_one();
      buffer_.clear();
      throw RecordingError(shared_->failure.empty() ? shared_->ended : shared_->failure);
    }
    if (!buffer_.empty()) {
      bytes_ += buffer_.size();
      shared_->queued_bytes += buffer_.size();
      shared_->queue.push_back(std::move(buffer_));
    }
  }
  shared_->wake.notify_one();
  buffer_.clear();
  frames_ += tick_frames_;
  tick_frames_ = 0;
}

void RecordingWriter::close() {
  if (!writer_.joinable()) return;
  {
    std::lock_guard lock(shared_->mutex);
    if (shared_->failure.empty() && shared_->ended.empty() &&
        !buffer_.empty()) {  // entries after the last tick (a destroyed instance)
      bytes_ += buffer_.size();
      shared_->queued_bytes += buffer_.size();
      shared_->queue.push_back(std::move(buffer_));
      frames_ += tick_frames_;
    }
    shared_->stop = true;
  }
  shared_->wake.notify_one();
  writer_.join();
  if (!shared_->failure.empty()) throw RecordingError(shared_->failure);
  if (!shared_->ended.empty()) throw RecordingError(shared_->ended);
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
