#include "phasecast/client/frame_sources.h"

#include <fmt/format.h>

#include <fstream>
#include <iterator>

namespace phasecast::client {
namespace {

constexpr std::string_view kRecordingMagic = "PHCREC1\n";

// Protobuf base-128 varint at `pos`; false when the data end inside it.
bool read_varint(const std::string& data, std::size_t& pos, std::uint64_t& value) {
  value = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (pos >= data.size()) return false;
    const auto byte = static_cast<std::uint8_t>(data[pos++]);
    value |= static_cast<std::uint64_t>(byte & 0x7f) << shift;
    if (!(byte & 0x80)) return true;
  }
  return false;
}

}  // namespace

std::vector<FrameState> portrait_frames(const core::ScenePackage& p, int irf) {
  const auto& pp = p.portrait;
  if (irf < 0 || irf >= pp.irf_count()) {
    throw std::invalid_argument(
        fmt::format("--play-irf {} is out of range (expected 0..{}: the package has {} IRFs)", irf,
                    pp.irf_count() - 1, pp.irf_count()));
  }
  const auto i = static_cast<std::size_t>(irf);
  std::vector<FrameState> frames;
  for (int t = 0; t < pp.irf_length[i]; ++t) {
    const int node = pp.irf_start[i] + t;
    FrameState f;
    f.frame = static_cast<std::uint64_t>(t);
    f.q_u.assign(pp.q_u.row(node).data(), pp.q_u.row(node).data() + pp.q_u.cols());
    f.q_a.assign(pp.q_a.row(node).data(), pp.q_a.row(node).data() + pp.q_a.cols());
    if (pp.support.rows() > 0) {
      f.support.assign(pp.support.row(node).data(), pp.support.row(node).data() + pp.support.cols());
    }
    frames.push_back(std::move(f));
  }
  return frames;
}

FrameState frame_state(const v1::Frame& frame) {
  FrameState f;
  f.frame = frame.frame();
  f.q_u.assign(frame.q_u().begin(), frame.q_u().end());
  f.q_a.assign(frame.q_a().begin(), frame.q_a().end());
  f.support.assign(frame.support().begin(), frame.support().end());
  return f;
}

Recording read_recording(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw RecordingError(fmt::format("recording {}: cannot open the file", path.string()));
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (data.compare(0, kRecordingMagic.size(), kRecordingMagic) != 0) {
    throw RecordingError(fmt::format(
        "recording {}: not a Phasecast recording (expected the magic \"PHCREC1\\n\")", path.string()));
  }
  Recording rec;
  std::size_t pos = kRecordingMagic.size();
  bool first = true;
  while (pos < data.size()) {
    std::uint64_t size = 0;
    const std::size_t start = pos;
    if (!read_varint(data, pos, size) || size > data.size() - pos) {
      rec.truncated = true;  // a crash while writing: drop the partial record
      break;
    }
    v1::RecordEntry entry;
    if (!entry.ParseFromArray(data.data() + pos, static_cast<int>(size))) {
      throw RecordingError(fmt::format("recording {}: the record at byte {} does not parse as a RecordEntry",
                                       path.string(), start));
    }
    pos += size;
    if (first) {
      if (!entry.has_header()) {
        throw RecordingError(
            fmt::format("recording {}: the first record is not a header (expected a "
                        "RecordingHeader)",
                        path.string()));
      }
      if (entry.header().format_version() != 1) {
        throw RecordingError(fmt::format("recording {}: format version {} is not supported (expected 1)",
                                         path.string(), entry.header().format_version()));
      }
      rec.header = entry.header();
      first = false;
      continue;
    }
    rec.entries.push_back(std::move(entry));
  }
  if (first)
    throw RecordingError(
        fmt::format("recording {}: no header record (expected a RecordingHeader)", path.string()));
  return rec;
}

std::vector<FrameState> recorded_frames(const Recording& rec, std::optional<std::uint32_t> instance,
                                        const std::string& source) {
  std::vector<FrameState> frames;
  for (const auto& e : rec.entries) {
    if (!e.has_frame()) continue;
    if (!instance) instance = e.frame().instance();
    if (e.frame().instance() == *instance) frames.push_back(frame_state(e.frame()));
  }
  if (frames.empty()) {
    throw RecordingError(instance ? fmt::format("recording {}: no frames of instance {}", source, *instance)
                                  : fmt::format("recording {}: no frames", source));
  }
  return frames;
}

}  // namespace phasecast::client
