#include "phasecast/precompute/simulation/obj_mesh.h"

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace phasecast::precompute {
namespace {

std::string one_line(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
  for (char& c : s) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return s;
}

// tinyobjloader reads a malformed coordinate as 0 without a word, so every
// "v" line is checked first: a typo must not become a vertex at the origin.
void check_vertex_lines(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw ObjError(fmt::format("{}: cannot open OBJ file", path.string()));
  std::string text;
  for (int line = 1; std::getline(in, text); ++line) {
    std::istringstream words(text);
    std::string tag;
    if (!(words >> tag) || tag != "v") continue;
    for (int k = 0; k < 3; ++k) {
      std::string token;
      if (!(words >> token)) throw ObjError(fmt::format("{}:{}: expected 'v x y z'", path.string(), line));
      double value = 0;
      const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
      if (ec != std::errc() || end != token.data() + token.size() || !std::isfinite(value)) {
        throw ObjError(fmt::format("{}:{}: expected a finite number, got '{}'", path.string(), line, token));
      }
    }
  }
}

Eigen::MatrixX3i triangles_of(const tinyobj::ObjReader& reader, Eigen::Index vertex_count,
                              const std::filesystem::path& path) {
  std::vector<int> corners;
  for (const auto& shape : reader.GetShapes()) {
    for (const auto& index : shape.mesh.indices) {
      if (index.vertex_index < 0 || index.vertex_index >= vertex_count) {
        throw ObjError(fmt::format("{}: face refers to vertex {}, expected 1..{}", path.string(),
                                   index.vertex_index + 1, vertex_count));
      }
      corners.push_back(index.vertex_index);
    }
  }
  Eigen::MatrixX3i triangles(static_cast<Eigen::Index>(corners.size() / 3), 3);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    for (int k = 0; k < 3; ++k) triangles(f, k) = corners[static_cast<size_t>(3 * f + k)];
  }
  return triangles;
}

}  // namespace

ObjMesh read_obj(const std::filesystem::path& path) {
  check_vertex_lines(path);
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;  // polygons become fans, as every consumer wants triangles
  config.vertex_color = false;
  config.mtl_search_path = "";  // materials play no part in geometry
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path.string(), config)) {
    throw ObjError(fmt::format("{}: not a readable OBJ file: {}", path.string(), one_line(reader.Error())));
  }
  const auto& v = reader.GetAttrib().vertices;
  ObjMesh mesh;
  mesh.vertices.resize(static_cast<Eigen::Index>(v.size() / 3), 3);
  for (Eigen::Index i = 0; i < mesh.vertices.rows(); ++i) {
    for (int k = 0; k < 3; ++k) mesh.vertices(i, k) = v[static_cast<size_t>(3 * i + k)];
  }
  if (mesh.vertices.rows() == 0) throw ObjError(fmt::format("{}: OBJ file has no vertices", path.string()));
  mesh.triangles = triangles_of(reader, mesh.vertices.rows(), path);
  return mesh;
}

void write_obj(const std::filesystem::path& path, const Eigen::MatrixX3d& vertices,
               const Eigen::MatrixX3i& triangles, const Eigen::MatrixX2i& lines) {
  std::ofstream out(path);
  if (!out) throw ObjError(fmt::format("{}: cannot create OBJ file", path.string()));
  for (Eigen::Index i = 0; i < vertices.rows(); ++i) {
    out << fmt::format("v {:.9g} {:.9g} {:.9g}\n", vertices(i, 0), vertices(i, 1), vertices(i, 2));
  }
  for (Eigen::Index i = 0; i < triangles.rows(); ++i) {
    out << fmt::format("f {} {} {}\n", triangles(i, 0) + 1, triangles(i, 1) + 1, triangles(i, 2) + 1);
  }
  for (Eigen::Index i = 0; i < lines.rows(); ++i)
    out << fmt::format("l {} {}\n", lines(i, 0) + 1, lines(i, 1) + 1);
  out.close();
  if (!out) throw ObjError(fmt::format("{}: write failed", path.string()));
}

}  // namespace phasecast::precompute
