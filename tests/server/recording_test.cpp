// Recordings through the service (no sockets): the format, replay bit for bit
// (also for sessions recorded mid-way), and the reader's rejection paths
// (core::read_recording_file, which the client's --replay shares).

#include "phasecast/server/recording.h"
#include "error_of.h"
#include "phasecast/core/hash.h"
#include "phasecast/core/recording.h"
#include "phasecast/server/synthesis_service.h"
#include "run_tool.h"
#include "synthetic_package.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <sys/resource.h>
#include <cmath>
#include <csignal>
#include <fstream>
#include <functional>
#include <iterator>
#include <thread>

namespace phasecast::server {
namespace {

using phasecast::testing::error_of;

using Clock = std::chrono::steady_clock;

struct Fixture {
  std::filesystem::path dir, pkg;
  explicit Fixture(const std::string& name)
      : dir(testing::scratch_dir("server_rec_" + name)), pkg(dir / "plate.h5") {
    core::write_package(testing::make_plate_package(), pkg);
  }
};

v1::Request impulse(std::uint32_t instance, const std::string& name) {
  v1::Request r;
  r.mutable_impulse()->set_instance(instance);
  r.mutable_impulse()->set_name(name);
  return r;
}

// A session: two instances, impulses, an instance created and one destroyed
// while recording; recording starts after `lead` ticks.
std::filesystem::path record_session(const Fixture& f, int lead) {
  SynthesisService s(60);
  s.load_package(f.pkg);
  s.engine().create_instance("plate");
  s.engine().create_instance("plate");
  EXPECT_TRUE(s.handle(impulse(1, "open")).ok());
  for (int i = 0; i < lead; ++i) s.tick();
  const auto path = f.dir / "session.phcrec";
  s.start_recording(path);
  EXPECT_TRUE(s.handle(impulse(2, "open")).ok());
  for (int i = 0; i < 30; ++i) s.tick();
  v1::Request create;
  create.mutable_create_instance()->set_scene("plate");
  EXPECT_TRUE(s.handle(create).ok());
  EXPECT_TRUE(s.handle(impulse(3, "open")).ok());
  auto later = impulse(2, "stop");
  later.mutable_impulse()->set_at_frame(lead + 50);
  EXPECT_TRUE(s.handle(later).ok());
  for (int i = 0; i < 40; ++i) s.tick();
  v1::Request destroy;
  destroy.mutable_destroy_instance()->set_instance(1);
  EXPECT_TRUE(s.handle(destroy).ok());
  for (int i = 0; i < 10; ++i) s.tick();
  EXPECT_EQ(s.stop_recording().frames_written(), 30u * 2 + 40u * 3 + 10u * 2);
  return path;
}

std::vector<v1::RecordEntry> read_entries(const std::filesystem::path& rec) {
  return core::read_recording_file(rec).entries;
}

ReplayReport replay(const Fixture& f, const std::filesystem::path& rec) {
  SynthesisService s(60);
  s.load_package(f.pkg);
  return replay_check(s.engine(), read_entries(rec));
}

TEST(Recording, FileStartsWithMagicAndHeaderNamingThePackage) {
  const Fixture f("header");
  const auto rec = record_session(f, 0);
  std::ifstream in(rec, std::ios::binary);
  std::string magic(8, '\0');
  in.read(magic.data(), 8);
  EXPECT_EQ(magic, "PHCREC1\n");
  const auto entries = read_entries(rec);
  const auto& h = entries.front().header();
  EXPECT_EQ(h.format_version(), 1u);
  ASSERT_EQ(h.scenes_size(), 1);
  EXPECT_EQ(h.scenes(0).package(), "plate.h5");
  EXPECT_EQ(h.scenes(0).content_hash(), core::file_content_hash(f.pkg));
  EXPECT_DOUBLE_EQ(h.rate_hz(), 60);
  // Applied impulses are written before the frame they land in.
  for (std::size_t i = 0; i + 1 < entries.size(); ++i) {
    if (!entries[i].has_impulse()) continue;
    const auto& imp = entries[i].impulse();
    for (std::size_t j = i + 1; j < entries.size(); ++j) {
      if (entries[j].has_frame() && entries[j].frame().instance() == imp.instance()) {
        EXPECT_EQ(entries[j].frame().frame(), imp.at_frame());
        EXPECT_EQ(entries[j].frame().palette_index(), static_cast<int>(imp.index()));
        break;
      }
    }
  }
}

TEST(Recording, SessionReplaysBitForBit) {
  const Fixture f("replay");
  const auto r = replay(f, record_session(f, 0));
  EXPECT_EQ(r.frames, 200u);
  EXPECT_EQ(r.instances, 3u);
  EXPECT_EQ(r.impulses, 4u);  // the open queued before recording lands inside it
}

TEST(Recording, RecordingStartedMidSessionReplaysFromTheSnapshots) {
  const Fixture f("midway");
  const auto r = replay(f, record_session(f, 17));  // instance 1 is mid-IRF when recording starts
  EXPECT_EQ(r.frames, 200u);
}

TEST(Recording, ReplayReportsTheFirstDifferingFrame) {
  const Fixture f("tamper");
  const auto rec = record_session(f, 0);
  auto entries = read_entries(rec);
  for (auto& e : entries) {
    if (e.has_frame() && e.frame().frame() == 12 && e.frame().instance() == 2) {
      e.mutable_frame()->set_q_u(1, std::nextafter(e.frame().q_u(1), 1.0f));
    }
  }
  SynthesisService s(60);
  s.load_package(f.pkg);
  EXPECT_EQ(error_of<RecordingError>([&] {
              replay_check(s.engine(), entries);
            }).rfind("replay-check: frame 12 of instance 2 differs: q_u[1] = ", 0),
            0u);
}

TEST(Recording, TruncatedFinalRecordEndsTheListCleanly) {
  const Fixture f("truncated");
  const auto rec = record_session(f, 0);
  const auto full = core::read_recording_file(rec);
  EXPECT_FALSE(full.truncated);
  std::filesystem::resize_file(rec, std::filesystem::file_size(rec) - 5);
  const auto cut = core::read_recording_file(rec);
  EXPECT_TRUE(cut.truncated);
  EXPECT_EQ(cut.entries.size(), full.entries.size() - 1);
  SynthesisService s(60);
  s.load_package(f.pkg);
  EXPECT_NO_THROW(replay_check(s.engine(), cut.entries));
}

// Writes the magic and then `records` as they are.
void write_raw(const std::filesystem::path& path, const std::string& records) {
  std::ofstream out(path, std::ios::binary);
  out << "PHCREC1\n" << records;
}

std::string delimited(const v1::RecordEntry& e) {
  std::string out;
  core::append_record(e, out);
  return out;
}

TEST(Recording, ReaderRejectsWhatIsNotARecording) {
  const Fixture f("reject");
  auto read = [](const std::filesystem::path& p) {
    return error_of<RecordingError>([&] { core::read_recording_file(p); });
  };
  const auto missing = f.dir / "missing.phcrec";
  EXPECT_EQ(read(missing), "recording '" + missing.string() + "': cannot open: No such file or directory");
  const auto junk = f.dir / "junk.phcrec";
  std::ofstream(junk) << "PHCREC0\nxxxx";
  EXPECT_EQ(read(junk), "recording '" + junk.string() +
                            "': not a Phasecast recording (expected the magic \"PHCREC1\\n\")");
  const auto empty = f.dir / "empty.phcrec";
  write_raw(empty, "");
  EXPECT_EQ(read(empty),
            "recording '" + empty.string() + "': expected a RecordingHeader as the first record");
  const auto no_header = f.dir / "noheader.phcrec";
  v1::RecordEntry frame;
  frame.mutable_frame()->set_instance(1);
  write_raw(no_header, delimited(frame));
  EXPECT_EQ(read(no_header),
            "recording '" + no_header.string() + "': expected a RecordingHeader as the first record");
  const auto future = f.dir / "future.phcrec";
  v1::RecordEntry header;
  header.mutable_header()->set_format_version(2);
  write_raw(future, delimited(header));
  EXPECT_EQ(read(future),
            "recording '" + future.string() + "': format version 2 is not supported (expected 1)");
  const auto corrupt = f.dir / "corrupt.phcrec";
  write_raw(corrupt, "\x03\xff\xff\xff");
  EXPECT_EQ(read(corrupt),
            "recording '" + corrupt.string() + "': record 0 at byte 8 does not parse as a RecordEntry");
  const auto huge = f.dir / "huge.phcrec";
  header.mutable_header()->set_format_version(1);
  write_raw(huge, delimited(header) + "\x80\x80\x80\x80\x01");  // 2^28 bytes, more than kMaxRecordBytes
  EXPECT_EQ(read(huge), fmt::format("recording '{}': record 1 at byte {} claims 268435456 bytes (expected at "
                                    "most 67108864)",
                                    huge.string(), 8 + delimited(header).size()));
}

TEST(Recording, ReplayRefusesAPackageOfAnotherHash) {
  const Fixture f("hash");
  const auto rec = record_session(f, 0);
  auto entries = read_entries(rec);
  entries.front().mutable_header()->mutable_scenes(0)->set_content_hash(1);
  SynthesisService s(60);
  s.load_package(f.pkg);
  EXPECT_EQ(
      error_of<RecordingError>([&] { replay_check(s.engine(), entries); }),
      fmt::format("replay-check: scene 'plate' was recorded from plate.h5 with hash 0000000000000001, but "
                  "plate.h5 has hash {:016x} (expected the same package)",
                  core::file_content_hash(f.pkg)));
}

TEST(Recording, CannotRecordTwiceOrToAnUnwritablePath) {
  const Fixture f("twice");
  SynthesisService s(60);
  s.load_package(f.pkg);
  s.start_recording(f.dir / "a.phcrec");
  EXPECT_EQ(error_of<RecordingError>([&] { s.start_recording(f.dir / "b.phcrec"); }),
            "already recording to '" + (f.dir / "a.phcrec").string() + "' (expected record_stop first)");
  s.stop_recording();
  EXPECT_EQ(error_of<RecordingError>([&] { s.start_recording(f.dir / "no" / "such" / "dir.phcrec"); }),
            "record: cannot create '" + (f.dir / "no" / "such" / "dir.phcrec").string() +
                "': No such file or directory");
}

TEST(Recording, WriteFailureEndsTheRecordingButNotTheStream) {
  const Fixture f("write_failure");
  SynthesisService s(60);
  s.load_package(f.pkg);
  s.engine().create_instance("plate");
  const auto path = f.dir / "full.phcrec";
  s.start_recording(path);
  // A file size limit makes write(2) fail with EFBIG, as a full disk would.
  rlimit old{};
  getrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, SIG_IGN);
  rlimit small = old;
  small.rlim_cur = 4096;
  setrlimit(RLIMIT_FSIZE, &small);
  // The writer thread meets the failure; a later tick learns of it.
  std::size_t ticks = 0, published = 0;
  for (; ticks < 200 || (s.recording() && ticks < 20000); ++ticks) {
    published += s.tick().size();
    if (ticks >= 200) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  setrlimit(RLIMIT_FSIZE, &old);
  EXPECT_EQ(published, ticks);
  EXPECT_FALSE(s.recording());
  EXPECT_EQ(s.recording_error(), "record: writing '" + path.string() + "' failed: File too large");
  v1::Request stats;
  stats.mutable_stats();
  EXPECT_EQ(s.handle(stats).stats().recording_error(), s.recording_error());
}

// Defect: record("pkg.h5") truncated the package being served. A recording
// is created exclusively and never through a link.
TEST(Recording, NeverReplacesAFileNorFollowsALink) {
  const Fixture f("exclusive");
  SynthesisService s(60);
  s.load_package(f.pkg);
  const auto size = std::filesystem::file_size(f.pkg);
  EXPECT_NE(error_of([&] { s.start_recording(f.pkg); }).find("File exists (expected a new file name"),
            std::string::npos);
  EXPECT_EQ(std::filesystem::file_size(f.pkg), size);
  const auto link = f.dir / "link.phcrec";
  std::filesystem::remove(link);
  std::filesystem::create_symlink(f.pkg, link);
  EXPECT_NE(error_of([&] { s.start_recording(link); }).find("cannot create"), std::string::npos);
  EXPECT_EQ(std::filesystem::file_size(f.pkg), size);
  EXPECT_FALSE(s.recording());
  // Through the command socket: only *.phcrec names, inside the record directory.
  s.set_record_dir(f.dir);
  v1::Request r;
  r.mutable_record_start()->set_path(f.pkg.filename().string());
  EXPECT_NE(s.handle(r).error().find("expected a plain file name ending in .phcrec"), std::string::npos);
  r.mutable_record_start()->set_path("link.phcrec");
  EXPECT_NE(s.handle(r).error().find("cannot create"), std::string::npos);
  EXPECT_EQ(std::filesystem::file_size(f.pkg), size);
}

// A recording ends at its size cap with a reason; what it holds is whole
// ticks that read back, and the stream goes on.
TEST(Recording, SizeCapEndsTheRecordingWithWholeTicks) {
  const Fixture f("size_cap");
  SynthesisService s(60);
  s.load_package(f.pkg);
  ServiceLimits limits;
  limits.record_max_bytes = 20000;
  s.set_limits(limits);
  s.engine().create_instance("plate");
  const auto path = f.dir / "capped.phcrec";
  std::filesystem::remove(path);
  s.start_recording(path);
  std::size_t published = 0;
  for (int i = 0; i < 1000; ++i) published += s.tick().size();
  EXPECT_EQ(published, 1000u);
  EXPECT_FALSE(s.recording());
  EXPECT_EQ(s.recording_error(),
            "record: '" + path.string() + "' reached its size cap of 20000 bytes (see --record-max-bytes)");
  // The writer drains what was queued before the cap on its own thread. It
  // is done when no further tick would have fitted: the file is within one
  // entry of the cap (a partial file is at least one whole tick short).
  const auto drained = [&] {
    try {
      const auto r = core::read_recording_file(path);
      std::string largest;
      for (const auto& e : r.entries) {  // one frame a tick: one instance, no impulses
        if (!e.has_frame()) continue;
        std::string one;
        core::append_record(e, one);
        if (one.size() > largest.size()) largest = one;
      }
      return std::filesystem::file_size(path) + largest.size() > 20000u;
    } catch (const std::exception&) {
      return false;  // mid-write: a torn last record
    }
  };
  for (int i = 0; i < 2000 && !drained(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_TRUE(drained()) << "ticks queued before the cap were not written";
  EXPECT_LE(std::filesystem::file_size(path), 20000u);
  const auto read = core::read_recording_file(path);
  std::size_t frames = 0;
  for (const auto& e : read.entries) frames += e.has_frame() ? 1 : 0;
  EXPECT_GT(frames, 50u);
  EXPECT_LT(frames, 1000u);
}

}  // namespace
}  // namespace phasecast::server
