#include "phasecast/core/recording.h"

#include <fmt/format.h>
#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <string_view>

namespace phasecast::core {

void append_record(const v1::RecordEntry& entry, std::string& out) {
  google::protobuf::io::StringOutputStream stream(&out);  // appends
  google::protobuf::io::CodedOutputStream coded(&stream);
  coded.WriteVarint32(static_cast<std::uint32_t>(entry.ByteSizeLong()));
  entry.SerializeWithCachedSizes(&coded);
}

std::string recording_prologue(const v1::RecordingHeader& header) {
  std::string out(kRecordingMagic, kRecordingMagicSize);
  v1::RecordEntry e;
  *e.mutable_header() = header;
  append_record(e, out);
  return out;
}

namespace {

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw RecordingError(fmt::format("recording '{}': cannot open: {}", path.string(), std::strerror(errno)));
  }
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void check_magic(std::string_view data, const std::filesystem::path& path) {
  if (data.substr(0, kRecordingMagicSize) != std::string_view(kRecordingMagic, kRecordingMagicSize)) {
    throw RecordingError(fmt::format(
        "recording '{}': not a Phasecast recording (expected the magic \"PHCREC1\\n\")", path.string()));
  }
}

// The protobuf base-128 varint at `pos`; nullopt when the data end inside it.
// One longer than 10 bytes reads as the largest value, so it is rejected as
// too long rather than mistaken for a truncated end.
std::optional<std::uint64_t> read_varint(std::string_view data, std::size_t& pos) {
  std::uint64_t value = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (pos >= data.size()) return std::nullopt;
    const auto byte = static_cast<std::uint8_t>(data[pos++]);
    value |= static_cast<std::uint64_t>(byte & 0x7f) << shift;
    if (!(byte & 0x80)) return value;
  }
  return std::numeric_limits<std::uint64_t>::max();
}

enum class Next { record, end, truncated };

// Reads record `index`, which starts at `pos`, into `entry` and moves `pos`
// past it. A crash while writing leaves at most one partial record, at the
// end: that is `truncated`, not an error.
Next read_record(std::string_view data, std::size_t& pos, std::size_t index,
                 const std::filesystem::path& path, v1::RecordEntry& entry) {
  if (pos == data.size()) return Next::end;
  const std::size_t start = pos;
  const auto size = read_varint(data, pos);
  if (!size) return Next::truncated;
  if (*size > kMaxRecordBytes) {
    throw RecordingError(
        fmt::format("recording '{}': record {} at byte {} claims {} bytes (expected at most {})",
                    path.string(), index, start, *size, kMaxRecordBytes));
  }
  if (*size > data.size() - pos) return Next::truncated;
  if (!entry.ParseFromArray(data.data() + pos, static_cast<int>(*size))) {
    throw RecordingError(fmt::format("recording '{}': record {} at byte {} does not parse as a RecordEntry",
                                     path.string(), index, start));
  }
  pos += *size;
  return Next::record;
}

RecordingError no_header(const std::filesystem::path& path) {
  return RecordingError(
      fmt::format("recording '{}': expected a RecordingHeader as the first record", path.string()));
}

// Checked as soon as it is read, so a file of another kind fails on its first
// record rather than somewhere in its body.
void check_header(const v1::RecordEntry& first, const std::filesystem::path& path) {
  if (!first.has_header()) throw no_header(path);
  const auto version = first.header().format_version();
  if (version != kRecordingFormatVersion) {
    throw RecordingError(fmt::format("recording '{}': format version {} is not supported (expected {})",
                                     path.string(), version, kRecordingFormatVersion));
  }
}

}  // namespace

Recording read_recording_file(const std::filesystem::path& path) {
  const std::string data = file_bytes(path);
  check_magic(data, path);
  Recording rec;
  std::size_t pos = kRecordingMagicSize;
  for (;;) {
    v1::RecordEntry entry;
    const Next next = read_record(data, pos, rec.entries.size(), path, entry);
    if (next != Next::record) {
      rec.truncated = next == Next::truncated;
      break;
    }
    if (rec.entries.empty()) check_header(entry, path);
    rec.entries.push_back(std::move(entry));
  }
  if (rec.entries.empty()) throw no_header(path);
  return rec;
}

}  // namespace phasecast::core
