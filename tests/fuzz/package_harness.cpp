#include "package_harness.h"

#include "phasecast/core/basis.h"
#include "phasecast/server/synthesis_engine.h"

#include <fmt/format.h>
#include <hdf5.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <typeinfo>

namespace phasecast::fuzz {

// ---- the reader under test --------------------------------------------------------

PackageVerdict PackageHarness::run(std::string_view bytes) {
  write_file(path_, bytes);
  PackageVerdict v;
  const std::string prefix = path_.string() + ": ";
  try {
    const core::ScenePackage package = core::read_package(path_);
    v.kind = "accepted";
    core::validate_package(package, path_.string());
    v.violation = serve(package);
  } catch (const core::PackageError& e) {
    const std::string line = e.what();
    if (!line.starts_with(prefix) || line.find('\n') != std::string::npos) {
      v.violation = fmt::format("PackageError '{}' (expected one line starting with '{}')", line, prefix);
    }
    v.kind =
        "refused " + kind_of_line(std::string_view(line).substr(std::min(prefix.size(), line.size())), 90);
  } catch (const std::exception& e) {
    v.violation =
        fmt::format("read_package threw {}: {} (expected core::PackageError)", typeid(e).name(), e.what());
  } catch (...) {
    v.violation = "read_package threw something that is no std::exception (expected core::PackageError)";
  }
  // A server reads packages once, but the reader must not leak handles either.
  if (const ssize_t open = H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL); open != 0 && v.violation.empty()) {
    v.violation = fmt::format("{} HDF5 objects left open after reading (expected none)", open);
  }
  return v;
}

namespace {

std::string check_basis_parts(const core::ScenePackage& package) {
  const core::BasisSizes sizes = core::basis_sizes(package);
  for (const auto& spec : core::basis_part_specs()) {
    if (spec.needs_appearance && !package.appearance) continue;
    std::uint64_t n = spec.element_bytes;
    for (const auto d : spec.shape(sizes)) n *= d;
    if (spec.bytes(package).size() != n) {
      return fmt::format("basis part {} has {} bytes (expected {})", spec.name, spec.bytes(package).size(),
                         n);
    }
  }
  return "";
}

}  // namespace

// What a server does with a package it loaded: every palette entry played
// for a few frames. A package the reader accepts must survive it.
std::string PackageHarness::serve(const core::ScenePackage& package) const {
  try {
    server::SynthesisEngine engine;
    engine.add_scene(std::make_shared<const core::ScenePackage>(package), "fuzz.h5", 0);
    const auto id = engine.create_instance(package.attributes.scene);
    server::TickResult out;
    for (int d = 0; d < package.palette.size(); ++d) {
      try {
        engine.schedule_impulse(id, d);
      } catch (const server::EngineError&) {
        // the palette's rules may refuse this entry now: that is an answer
      }
      for (int t = 0; t < 8; ++t) engine.tick(out);
    }
    return check_basis_parts(package);
  } catch (const std::exception& e) {
    return fmt::format("serving an accepted package threw {}: {}", typeid(e).name(), e.what());
  }
}

// ---- HDF5 metadata blocks ---------------------------------------------------------

namespace {

std::uint32_t rot(std::uint32_t x, int k) {
  return (x << k) | (x >> (32 - k));
}

void mix(std::uint32_t& a, std::uint32_t& b, std::uint32_t& c) {
  a -= c, a ^= rot(c, 4), c += b;
  b -= a, b ^= rot(a, 6), a += c;
  c -= b, c ^= rot(b, 8), b += a;
  a -= c, a ^= rot(c, 16), c += b;
  b -= a, b ^= rot(a, 19), a += c;
  c -= b, c ^= rot(b, 4), b += a;
}

void final_mix(std::uint32_t& a, std::uint32_t& b, std::uint32_t& c) {
  c ^= b, c -= rot(b, 14);
  a ^= c, a -= rot(c, 11);
  b ^= a, b -= rot(a, 25);
  c ^= b, c -= rot(b, 16);
  a ^= c, a -= rot(c, 4);
  b ^= a, b -= rot(a, 14);
  c ^= b, c -= rot(b, 24);
}

std::uint64_t little_endian(const Bytes& f, std::size_t at, std::size_t width) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < width && at + i < f.size(); ++i)
    v |= std::uint64_t{static_cast<unsigned char>(f[at + i])} << (8 * i);
  return v;
}

bool verifies(const Bytes& f, std::size_t begin, std::size_t end) {
  return end >= begin && end + 4 <= f.size() &&
         lookup3(f.data() + begin, end - begin) == static_cast<std::uint32_t>(little_endian(f, end, 4));
}

constexpr std::size_t kOffsetBytes = 8;  // "size of offsets" and "size of lengths" of our files
constexpr int kContinuationMessage = 0x10;

// Header messages in [at, end): bodies into `block`, continuation chunks
// (address, length) into `chunks`.
void walk_messages(const Bytes& f, std::size_t at, std::size_t end, bool creation_order, MetadataBlock& block,
                   std::vector<std::pair<std::uint64_t, std::uint64_t>>& chunks) {
  const std::size_t header = creation_order ? 6 : 4;
  while (at + header <= end) {
    const int type = static_cast<unsigned char>(f[at]);
    const std::size_t body = at + header;
    const std::size_t size = little_endian(f, at + 1, 2);
    if (body + size > end) return;
    block.messages.push_back({type, body, body + size});
    if (type == kContinuationMessage && size == 2 * kOffsetBytes) {
      chunks.emplace_back(little_endian(f, body, kOffsetBytes),
                          little_endian(f, body + kOffsetBytes, kOffsetBytes));
    }
    at = body + size;
  }
}

// The version 2 object header at `at` and its continuation chunks.
void add_object_header(const Bytes& f, std::size_t at, std::vector<MetadataBlock>& out) {
  if (at + 7 > f.size() || f[at + 4] != 2) return;
  const auto flags = static_cast<unsigned char>(f[at + 5]);
  std::size_t q = at + 6 + ((flags & 0x20) ? 16 : 0) + ((flags & 0x10) ? 4 : 0);
  const std::size_t width = std::size_t{1} << (flags & 3);
  const std::size_t size = little_endian(f, q, width);
  q += width;
  if (size > f.size() || !verifies(f, at, q + size)) return;
  MetadataBlock block{at, q + size, {}};
  std::vector<std::pair<std::uint64_t, std::uint64_t>> chunks;
  walk_messages(f, q, q + size, (flags & 0x04) != 0, block, chunks);
  out.push_back(block);
  for (const auto& [address, length] : chunks) {
    if (length < 8 || address > f.size() || length > f.size() - address) continue;
    if (f.compare(address, 4, "OCHK") != 0 || !verifies(f, address, address + length - 4)) continue;
    MetadataBlock chunk{address, address + length - 4, {}};
    std::vector<std::pair<std::uint64_t, std::uint64_t>>
        more;  // their chunks are found from their own headers
    walk_messages(f, address + 4, address + length - 4, (flags & 0x04) != 0, chunk, more);
    out.push_back(chunk);
  }
}

}  // namespace

// Bob Jenkins' lookup3 hashlittle() with initval 0, byte-wise as HDF5's
// H5_checksum_lookup3() reads it.
std::uint32_t lookup3(const char* data, std::size_t size) {
  const auto* k = reinterpret_cast<const unsigned char*>(data);
  std::uint32_t a = 0xdeadbeef + static_cast<std::uint32_t>(size);
  std::uint32_t b = a, c = a;
  const auto word = [&k](std::size_t i, std::size_t n) {
    std::uint32_t w = 0;
    for (std::size_t j = 0; j < n; ++j) w |= std::uint32_t{k[i + j]} << (8 * j);
    return w;
  };
  while (size > 12) {
    a += word(0, 4), b += word(4, 4), c += word(8, 4);
    mix(a, b, c);
    size -= 12;
    k += 12;
  }
  if (size == 0) return c;
  a += word(0, std::min<std::size_t>(size, 4));
  if (size > 4) b += word(4, std::min<std::size_t>(size - 4, 4));
  if (size > 8) c += word(8, size - 8);
  final_mix(a, b, c);
  return c;
}

void store_checksum(Bytes& f, const MetadataBlock& b) {
  const std::uint32_t sum = lookup3(f.data() + b.begin, b.end - b.begin);
  for (std::size_t i = 0; i < 4; ++i) f[b.end + i] = static_cast<char>((sum >> (8 * i)) & 0xff);
}

std::vector<MetadataBlock> metadata_blocks(const Bytes& file) {
  std::vector<MetadataBlock> out;
  static const Bytes kSignature("\x89HDF\r\n\x1a\n", 8);
  if (file.compare(0, 8, kSignature) == 0 && file.size() > 12 && (file[8] == 2 || file[8] == 3)) {
    const std::size_t end = 12 + 4 * static_cast<std::size_t>(static_cast<unsigned char>(file[9]));
    if (verifies(file, 0, end)) out.push_back({0, end, {}});
  }
  for (std::size_t at = file.find("OHDR"); at != Bytes::npos; at = file.find("OHDR", at + 4)) {
    add_object_header(file, at, out);
  }
  return out;
}

// ---- mutations --------------------------------------------------------------------

bool PackageMutator::mutate_metadata(Bytes& data) {
  const auto blocks = metadata_blocks(data);
  if (blocks.empty()) return false;
  const auto& b = blocks[random_.below(blocks.size())];
  if (!b.messages.empty() && !random_.one_in(4)) {
    const auto& m = b.messages[random_.below(b.messages.size())];
    bytes_.mutate_in_place(data, m.begin, m.end);
  } else {
    bytes_.mutate_in_place(data, b.begin, b.end);
  }
  store_checksum(data, b);
  return true;
}

Bytes PackageMutator::mutate(const Bytes& parent, const Bytes& other) {
  Bytes data = parent;
  for (auto n = 1 + random_.below(random_.one_in(4) ? 4 : 1); n > 0; --n) {
    const auto choice = random_.below(20);
    if (choice < 11 && mutate_metadata(data)) continue;
    if (choice < 17) {
      bytes_.mutate_in_place(data, 0, data.size());
    } else {
      bytes_.mutate(data, other);
    }
  }
  return data;
}

}  // namespace phasecast::fuzz
