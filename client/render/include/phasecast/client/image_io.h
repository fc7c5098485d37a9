#pragma once
// Files the client writes: PNG frames (stb_image_write), vertex dumps as
// NumPy .npy or CSV, and the image comparisons golden-image tests use.

#include "phasecast/client/low_rank_renderer.h"

#include <filesystem>
#include <string>

namespace phasecast::client {

// Throws std::runtime_error naming the path when it cannot be written.
void write_png(const Image& image, const std::filesystem::path& path);
// Reads any PNG as RGBA8; throws std::runtime_error naming the path.
Image read_png(const std::filesystem::path& path);

// "frame_000123.png": named by the server's frame number so two renderers of
// one instance can be compared file by file. Frame numbers start again when a
// server restarts; the frames of the n-th restart (`session` n >= 1) are
// "restart01_frame_000123.png", ..., so that no file replaces an earlier one.
std::string frame_file_name(std::uint64_t frame, unsigned session = 0);

// Peak signal-to-noise ratio over RGB in dB (infinity for identical images)
// and the largest channel difference (0..255). Throws std::invalid_argument
// when the sizes differ.
double psnr(const Image& a, const Image& b);
int max_channel_difference(const Image& a, const Image& b);

// S x 6 table: x, y, z (world) and r, g, b (linear radiance) per point. The
// format follows the extension: ".npy" (float32, shape (S, 6)) or ".csv"
// (header x,y,z,r,g,b). Throws std::invalid_argument for other extensions.
void write_vertex_dump(const VertexDump& dump, const std::filesystem::path& path);
// The same check of the extension, before any rendering starts.
void check_vertex_dump_path(const std::filesystem::path& path);

}  // namespace phasecast::client
