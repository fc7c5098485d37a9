#include "phasecast/client/image_io.h"

#include <fmt/format.h>
#include <stb_image.h>
#include <stb_image_write.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <stdexcept>

namespace phasecast::client {
namespace {

void expect_same_size(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height) {
    throw std::invalid_argument(fmt::format("image sizes differ: {}x{} vs {}x{} (expected equal sizes)",
                                            a.width, a.height, b.width, b.height));
  }
}

void write_npy(const VertexDump& d, const std::filesystem::path& path, std::size_t points) {
  // NPY v1.0: magic, header length, a Python dict padded so data start at a multiple of 64.
  std::string header = fmt::format("{{'descr': '<f4', 'fortran_order': False, 'shape': ({}, 6), }}", points);
  const std::size_t preamble = 10;
  header.append(64 - (preamble + header.size() + 1) % 64, ' ');
  header += '\n';
  std::ofstream out(path, std::ios::binary);
  out.write("\x93NUMPY\x01\x00", 8);
  const auto length = static_cast<std::uint16_t>(header.size());
  const char length_bytes[2] = {static_cast<char>(length & 0xff), static_cast<char>(length >> 8)};
  out.write(length_bytes, 2);
  out.write(header.data(), static_cast<std::streamsize>(header.size()));
  for (std::size_t v = 0; v < points; ++v) {
    out.write(reinterpret_cast<const char*>(&d.positions[3 * v]), 3 * sizeof(float));
    out.write(reinterpret_cast<const char*>(&d.radiance[3 * v]), 3 * sizeof(float));
  }
  if (!out) throw std::runtime_error(fmt::format("cannot write vertex dump {}", path.string()));
}

void write_csv(const VertexDump& d, const std::filesystem::path& path, std::size_t points) {
  std::ofstream out(path);
  out << "x,y,z,r,g,b\n";
  for (std::size_t v = 0; v < points; ++v) {
    // 9 significant digits round-trip float32 exactly.
    out << fmt::format("{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}\n", d.positions[3 * v],
                       d.positions[3 * v + 1], d.positions[3 * v + 2], d.radiance[3 * v],
                       d.radiance[3 * v + 1], d.radiance[3 * v + 2]);
  }
  if (!out) throw std::runtime_error(fmt::format("cannot write vertex dump {}", path.string()));
}

}  // namespace

void write_png(const Image& image, const std::filesystem::path& path) {
  if (!stbi_write_png(path.c_str(), image.width, image.height, 4, image.rgba.data(), 4 * image.width)) {
    throw std::runtime_error(fmt::format("cannot write PNG {}", path.string()));
  }
}

Image read_png(const std::filesystem::path& path) {
  int w = 0, h = 0, channels = 0;
  stbi_uc* data = stbi_load(path.c_str(), &w, &h, &channels, 4);
  if (!data) {
    throw std::runtime_error(fmt::format("cannot read PNG {}: {}", path.string(), stbi_failure_reason()));
  }
  Image image{w, h, std::vector<std::uint8_t>(data, data + 4 * static_cast<std::size_t>(w) * h)};
  stbi_image_free(data);
  return image;
}

std::string frame_file_name(std::uint64_t frame, unsigned session) {
  if (session == 0) return fmt::format("frame_{:06d}.png", frame);
  return fmt::format("restart{:02d}_frame_{:06d}.png", session, frame);
}

double psnr(const Image& a, const Image& b) {
  expect_same_size(a, b);
  double squared = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < a.rgba.size(); ++i) {
    if (i % 4 == 3) continue;  // alpha is always opaque
    const double d = double(a.rgba[i]) - double(b.rgba[i]);
    squared += d * d;
    ++count;
  }
  if (squared == 0) return std::numeric_limits<double>::infinity();
  return 10 * std::log10(255.0 * 255.0 / (squared / static_cast<double>(count)));
}

int max_channel_difference(const Image& a, const Image& b) {
  expect_same_size(a, b);
  int worst = 0;
  for (std::size_t i = 0; i < a.rgba.size(); ++i)
    worst = std::max(worst, std::abs(int(a.rgba[i]) - int(b.rgba[i])));
  return worst;
}

void write_vertex_dump(const VertexDump& d, const std::filesystem::path& path) {
  const std::size_t points = d.positions.size() / 3;
  const auto extension = path.extension().string();
  if (extension == ".npy") {
    write_npy(d, path, points);
  } else if (extension == ".csv") {
    write_csv(d, path, points);
  } else {
    check_vertex_dump_path(path);
  }
}

void check_vertex_dump_path(const std::filesystem::path& path) {
  const auto extension = path.extension().string();
  if (extension != ".npy" && extension != ".csv") {
    throw std::invalid_argument(fmt::format(
        "--dump-vertices file '{}' has an unknown format (expected a .npy or .csv name)", path.string()));
  }
}

}  // namespace phasecast::client
