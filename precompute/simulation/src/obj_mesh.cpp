#include "phasecast/precompute/simulation/obj_mesh.h"

#include <fmt/format.h>

#include <array>
#include <charconv>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace phasecast::precompute {
namespace {

double parse_number(const std::string& token, const std::filesystem::path& path, int line) {
  double value = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
  if (ec != std::errc() || end != token.data() + token.size() || !std::isfinite(value)) {
    throw ObjError(fmt::format("{}:{}: expected a finite number, got '{}'", path.string(), line, token));
  }
  return value;
}

int parse_index(const std::string& token, int vertex_count, const std::filesystem::path& path, int line) {
  const std::string head = token.substr(0, token.find('/'));
  int value = 0;
  const auto [end, ec] = std::from_chars(head.data(), head.data() + head.size(), value);
  if (ec != std::errc() || end != head.data() + head.size() || value == 0) {
    throw ObjError(fmt::format("{}:{}: expected a vertex index, got '{}'", path.string(), line, token));
  }
  const int index = value > 0 ? value - 1 : vertex_count + value;
  if (index < 0 || index >= vertex_count) {
    throw ObjError(
        fmt::format("{}:{}: vertex index {} out of range [1, {}]", path.string(), line, value, vertex_count));
  }
  return index;
}

}  // namespace

ObjMesh read_obj(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw ObjError(fmt::format("{}: cannot open OBJ file", path.string()));
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;
  std::string text;
  for (int line = 1; std::getline(in, text); ++line) {
    std::istringstream words(text);
    std::string tag;
    words >> tag;
    if (tag == "v") {
      std::array<std::string, 3> t;
      if (!(words >> t[0] >> t[1] >> t[2])) {
        throw ObjError(fmt::format("{}:{}: expected 'v x y z'", path.string(), line));
      }
      vertices.emplace_back(parse_number(t[0], path, line), parse_number(t[1], path, line),
                            parse_number(t[2], path, line));
    } else if (tag == "f") {
      std::vector<int> corners;
      for (std::string t; words >> t;)
        corners.push_back(parse_index(t, static_cast<int>(vertices.size()), path, line));
      if (corners.size() < 3) {
        throw ObjError(fmt::format("{}:{}: face has {} corners, expected at least 3", path.string(), line,
                                   corners.size()));
      }
      for (size_t k = 1; k + 1 < corners.size(); ++k)
        triangles.push_back({corners[0], corners[k], corners[k + 1]});
    }
  }
  ObjMesh mesh;
  mesh.vertices.resize(static_cast<Eigen::Index>(vertices.size()), 3);
  for (size_t i = 0; i < vertices.size(); ++i) mesh.vertices.row(static_cast<Eigen::Index>(i)) = vertices[i];
  mesh.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (size_t i = 0; i < triangles.size(); ++i) {
    for (int k = 0; k < 3; ++k)
      mesh.triangles(static_cast<Eigen::Index>(i), k) = triangles[i][static_cast<size_t>(k)];
  }
  if (mesh.vertices.rows() == 0) throw ObjError(fmt::format("{}: OBJ file has no vertices", path.string()));
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
